r"""Wheels of a multibody tree rolling without slipping on a plane: Maggi's equations (82) on SE(3) × shape space.

Bodies of a floating tree, its wheels $k$, touch a fixed plane at points $p_k$ of their
surfaces (section frame) and roll on it: those material points are at rest. With the
tree's velocities $v = (\xi, \dot q)$ (the section's body twist and the shape velocity),
body $k$'s twist in the section frame is $\hat J_k v$ (`velocity_jacobians`), and its
contact point's velocity is

$$ u_k = C_k v, \qquad C_k = \begin{pmatrix} -\tilde p_k & I \end{pmatrix}\hat J_k, $$

three Pfaffian rows (76) per wheel, $C v = 0$. The kinematic characteristics $e$ are the
components of $v$ named `independent`; the rows solve for the others, $C_d v_d = -C_e e$
(with one wheel, by default, $e = (\omega, \dot q)$: $\hat J_k$ passes the section's twist
through unchanged, so its linear velocity enters $u_k$ with the identity and is always
solved for). The parametric form (77) is $v = H e$, and Maggi's equations (82)
with the metric $G(q)$ of the tree are Gauss's principle in these variables: the
characteristics' rates make the constrained acceleration $\dot v = He' + \dot He$ the
$G$-projection of the unconstrained one $a$ (the reference form of the equations of
motion, with the scene's forces),

$$ \dot e = (H^T G H)^{-1} H^T G\,(a - \dot H e). $$

$p_k$ and $H$ depend on the section's orientation through the plane's normal seen from it,
$n = R^T n_{\rm world}$, turning as $\dot n = n\times\omega$, and on $q$; $\dot H e$ is a
JVP along both. The normal rows of the constraints are holonomic (the wheels touch the
plane). The first wheel's is kept by coordinate partitioning, as for a single body
(`RollingMode`): the pose's offset along the normal is placed so that its contact point
lies on the plane. The others' are carried in their differentiated form, kept by the
integrator to its tolerance, and reported by `constraint_residual`.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .. import lie
from .._dynamics import reference_accelerations
from .._effects import Kinematics
from .._geometry import locked_velocity
from .._linalg import matmul
from .._nonholonomic._constraints import rank_checked
from .._nonholonomic._contact import AbstractContactSurface, unit_axis
from .._state import State
from .._systems._multibody import AbstractMultibody
from .._validation import check_shape
from ._base import AbstractFreeMotionMode, SceneParts
from ._floating import body_twist, checked_shape
from ._plane_contact import consistency

__all__ = ["RollingWheelMode", "Wheel"]

# As `PfaffianConstraints`' default: a block whose smallest singular value is below this
# fraction of the rows' largest cannot be solved for to useful accuracy.
_RANK_TOLERANCE = 1e-8
_PARTITION_SINGULAR = (
    "the wheels' rolling constraints do not determine the velocities left out of "
    "`RollingWheelMode.independent` here: choose other independent velocities."
)
_RANK_LOST = (
    "the wheels' rolling constraints lost rank here (two contacts constrain the same "
    "motion, e.g. a wheel lying flat): the state is singular for this mode."
)


class Wheel(eqx.Module):
    r"""A body of a tree that rolls: its name (`Multibody.names`) or index, and its surface.

    **Arguments:**

    - `body`: the body's name or index.
    - `surface`: its `AbstractContactSurface` in the body's own frame (`DiscContact`,
      `TorusContact`, `SphereContact`, `EllipsoidContact`).
    """

    body: str | int = eqx.field(static=True)
    surface: AbstractContactSurface

    def __check_init__(self):
        if not isinstance(self.body, (str, int)):
            raise ValueError(
                f"`Wheel.body` must be a body's name or index; got {type(self.body).__name__}."
            )
        if not isinstance(self.surface, AbstractContactSurface):
            raise ValueError(
                "`Wheel.surface` must be an AbstractContactSurface, e.g. "
                f"`bd.DiscContact(radius)`; got {type(self.surface).__name__}."
            )

    def index(self, system: AbstractMultibody) -> int:
        """The body's index among `system`'s bodies (static)."""
        if isinstance(self.body, int):
            if not 0 <= self.body < system.num_bodies:
                raise ValueError(
                    f"`Wheel.body` is {self.body}, but the tree has {system.num_bodies} bodies."
                )
            return self.body
        if self.body not in system.names:
            raise ValueError(
                f"`Wheel.body` is {self.body!r}, which is not one of the tree's bodies "
                f"{system.names}."
            )
        return system.names.index(self.body)


class RollingWheelMode(AbstractFreeMotionMode):
    r"""Wheels of a floating multibody tree roll without slipping on a fixed plane (seed 001, (76), (77), (82)).

    The integration state is $y = (g, x)$: the section's pose on SE(3) (stepped by the
    Lie-group solvers) and $x = (q, e)$, the shape and the kinematic characteristics; the
    other velocities follow from the rolling constraints. The plane's reaction is ideal
    and does no work, so the energy of a scene with conservative effects is conserved.

    ```python
    tree = bd.Multibody.from_mjcf(bd.models / "unicycle.xml")
    mode = bd.RollingWheelMode([bd.Wheel("wheel", bd.DiscContact(0.2))])
    scene = bd.Scene(tree, [bd.Gravity(9.81)], mode=mode)
    state = mode.state(tree, g0, q0, jnp.concatenate([omega0, qdot0]))
    ```

    **Arguments:**

    - `wheels`: the rolling bodies, a sequence of `Wheel`; the first one's contact is
      placed on the plane by the pose, the others' kept by the integrator.
    - `independent`: the characteristics $e$, as indices into $v = (\omega, v, \dot q)$
      (the section's body angular and linear velocities, then the shape velocity); static.
      Their number is $6 + d - 3w$ for $w$ wheels, and the rows must solve for the other
      velocities along the motion. Default, with one wheel: $e = (\omega, \dot q)$.
    - `normal`: the plane's upward normal in the world frame; default $(0, 0, 1)$.
    - `offset`: the plane is $\{x : n\cdot x = \text{offset}\}$; default 0.
    """

    wheels: tuple[Wheel, ...]
    independent: tuple[int, ...] | None = eqx.field(static=True)
    normal: Float[Array, "3"]
    offset: Float[Array, ""]

    def __init__(self, wheels, *, independent=None, normal=(0.0, 0.0, 1.0), offset=0.0):
        self.wheels = tuple(wheels)
        self.independent = None if independent is None else tuple(int(i) for i in independent)
        self.normal = unit_axis("RollingWheelMode", normal, "normal")
        self.offset = jnp.asarray(offset, dtype=float)

    def __check_init__(self):
        if not self.wheels or not all(isinstance(w, Wheel) for w in self.wheels):
            raise ValueError(
                "`RollingWheelMode.wheels` must be a non-empty sequence of `bd.Wheel(body, "
                "surface)`."
            )
        if self.independent is None and len(self.wheels) > 1:
            raise ValueError(
                "`RollingWheelMode` with several wheels needs `independent`: the indices, into "
                "(omega, v, qdot), of the velocities the rolling constraints leave free."
            )
        check_shape("RollingWheelMode.offset", self.offset, ())

    def characteristics(self, d: int) -> tuple[int, ...]:
        r"""The characteristics' indices into $(\omega, v, \dot q)$ for a shape of `d` (static)."""
        return (0, 1, 2, *range(6, 6 + d)) if self.independent is None else self.independent

    def _split(self, d: int):
        """The indices of the characteristics and of the velocities solved for (static)."""
        independent = self.characteristics(d)
        dependent = tuple(i for i in range(6 + d) if i not in independent)
        return independent, dependent

    def check(self, system, frame):
        if not (isinstance(system, AbstractMultibody) and system.shape_dim > 0):
            raise ValueError(
                "`RollingWheelMode` rolls wheels of a multibody tree with shape coordinates "
                f"(`bd.Multibody`); got {type(system).__name__}. A single rolling body is "
                "`bd.RollingMode`."
            )
        for wheel in self.wheels:
            wheel.index(system)
        d = system.shape_dim
        independent, dependent = self._split(d)
        wanted = 6 + d - 3 * len(self.wheels)
        if len(set(independent)) != wanted or not all(0 <= i < 6 + d for i in independent):
            raise ValueError(
                f"`RollingWheelMode.independent` must name {wanted} different velocities among "
                f"the {6 + d} of (omega, v, qdot) ({len(self.wheels)} wheels leave "
                f"{wanted} free); got {independent}."
            )
        if frame is not None:
            raise ValueError(
                "`RollingWheelMode` rolls on a plane at rest in the Galilean frame: give the "
                "scene no `frame`."
            )

    def _contact_rows(self, system, n, q):
        r"""$C(n, q)$ `(3w, 6 + d)` and the contact points $p_k$ `(w, 3)` (section frame)."""
        r, Jhat = system.velocity_jacobians(q)
        rows, points = [], []
        for wheel in self.wheels:
            k = wheel.index(system)
            R_k = r[k, :3, :3]
            p = matmul(R_k, wheel.surface.contact_point(matmul(R_k.T, n))) + r[k, :3, 3]
            moment = jnp.concatenate([-lie.so3_hat(p), jnp.eye(3, dtype=p.dtype)], axis=1)
            rows.append(matmul(moment, Jhat[k]))
            points.append(p)
        return jnp.concatenate(rows), jnp.stack(points)

    def _basis(self, system, n, q):
        r"""$H$ `(6 + d, m)`: the identity on the characteristics, $-C_d^{-1}C_e$ on the others."""
        C, _ = self._contact_rows(system, n, q)
        independent, dependent = self._split(system.shape_dim)
        ind, dep = jnp.asarray(independent), jnp.asarray(dependent)
        m = len(independent)
        C = rank_checked(
            C, C[:, dep], _RANK_TOLERANCE, _PARTITION_SINGULAR, whole=C, whole_message=_RANK_LOST
        )
        solved = jnp.linalg.solve(C[:, dep], -C[:, ind])
        return (
            jnp.zeros((C.shape[1], m), C.dtype)
            .at[ind]
            .set(jnp.eye(m, dtype=C.dtype))
            .at[dep]
            .set(solved)
        )

    def _velocities(self, system, n, q, e):
        r"""$v = H e$: the section's twist and the shape velocity of the characteristics."""
        return matmul(self._basis(system, n, q), e)

    def _section_normal(self, g):
        return matmul(g[:3, :3].T, self.normal)

    def _heights(self, g, points):
        placed = matmul(points, g[:3, :3].T) + g[None, :3, 3]
        return matmul(placed, self.normal) - self.offset

    def placed(self, system, g, q) -> Float[Array, "4 4"]:
        r"""The pose `g` moved along the plane's normal until the first wheel's contact point
        lies on the plane (the holonomic constraint, solved for the offset along the normal)."""
        _, points = self._contact_rows(system, self._section_normal(g), q)
        gap = self._heights(g, points[:1])[0]
        return g.at[:3, 3].set(g[:3, 3] - gap * self.normal)

    def state(self, system, g, q, e) -> State:
        r"""The `State` of the tree at pose `g` (placed on the plane) and shape `q`, with the
        characteristics `e`, the other velocities those that keep the wheels rolling.

        **Arguments:**

        - `system`: the tree.
        - `g`: the section's pose `(4, 4)` (its offset along the plane's normal is replaced).
        - `q`: the shape `(d,)`, with every wheel but the first on the plane.
        - `e`: the characteristics, the components `independent` of $(\omega, v, \dot q)$;
          with one wheel and the default, $(\omega, \dot q)$.
        """
        q = jnp.asarray(q, dtype=float)
        g = self.placed(system, jnp.asarray(g, dtype=float), q)
        v = self._velocities(system, self._section_normal(g), q, jnp.asarray(e, dtype=float))
        return State(g, q, v[:6], v[6:])

    def _characteristics(self, scene: SceneParts, xi, qdot):
        independent, _ = self._split(scene.system.shape_dim)
        return jnp.concatenate([xi, qdot])[jnp.asarray(independent)]

    def pack(self, scene: SceneParts, t, g, q, U, qdot):
        xi = body_twist(scene, q, U, qdot)
        return g, jnp.concatenate([q, self._characteristics(scene, xi, qdot)])

    def _parts(self, scene: SceneParts, y):
        g, x = y
        d = scene.system.shape_dim
        q, e = x[:d], x[d:]
        g = self.placed(scene.system, g, q)
        v = self._velocities(scene.system, self._section_normal(g), q, e)
        return g, q, e, v[:6], v[6:]

    def unpack(self, scene: SceneParts, t, y):
        g, q, _, xi, qdot = self._parts(scene, y)
        return g, q, locked_velocity(scene.system, q, xi, qdot), qdot

    def encode(self, scene: SceneParts, t, state: State):
        q, qdot = checked_shape(scene, state)
        U = locked_velocity(scene.system, q, state.xi, qdot)
        y = self.pack(scene, t, state.g, q, U, qdot)
        g, _, _, xi, _ = self._parts(scene, y)
        scale = jnp.linalg.norm(state.xi) + jnp.linalg.norm(state.g[:3, 3]) + 1.0
        off = (
            jnp.linalg.norm(xi - state.xi)
            + jnp.linalg.norm(g[:3, 3] - state.g[:3, 3])
            + jnp.linalg.norm(self.constraint_residual(scene, state))
        )
        g0 = eqx.error_if(
            state.g,
            off > consistency(off.dtype) * scale,
            "the state does not keep the wheels rolling: their contact points must lie on "
            "the plane and be at rest; build it with the mode's `state(system, g, q, e)`.",
        )
        return g0, y[1]

    def decode(self, scene: SceneParts, t, y):
        g, q, _, xi, qdot = self._parts(scene, y)
        return State(g, q, xi, qdot), locked_velocity(scene.system, q, xi, qdot)

    def body_field(self, scene: SceneParts, t, y):
        system = scene.system
        g, q, e, xi, qdot = self._parts(scene, y)
        n = self._section_normal(g)
        basis = lambda n, q: self._basis(system, n, q)
        H, H_dot = jax.jvp(basis, (n, q), (jnp.cross(n, xi[:3]), qdot))
        F, Q = scene.forces(Kinematics(t, g, q, xi, qdot))
        free = jnp.concatenate(reference_accelerations(system, q, xi, qdot, F, Q))
        G = system.metric(q)
        HG = matmul(H.T, G)
        e_dot = jnp.linalg.solve(matmul(HG, H), matmul(HG, free - matmul(H_dot, e)))
        return xi, jnp.concatenate([qdot, e_dot])

    def kinematics(self, scene: SceneParts, t, y):
        g, q, _, xi, qdot = self._parts(scene, y)
        return Kinematics(t, g, q, xi, qdot)

    def recharted(self, scene: SceneParts, t, y):
        return y

    def constraint_residual(self, scene: SceneParts, state: State):
        r"""The wheels' contact points' velocities $u = Cv$ (section frame, 3 rows each) and
        their heights above the plane (1 row each)."""
        g = state.g
        C, points = self._contact_rows(scene.system, self._section_normal(g), state.q)
        u = matmul(C, jnp.concatenate([state.xi, state.qdot]))
        return jnp.concatenate([u, self._heights(g, points)])

    def window_chart(self, scene: SceneParts):
        raise ValueError(
            "identification does not fit scenes with rolling wheels (`RollingWheelMode`): "
            "its window states would have to keep the rolling constraints."
        )
