r"""A wheel of a multibody tree rolling without slipping on a plane: Maggi's equations (82) on SE(3) × shape space.

One body of a floating tree, the wheel $k$, touches a fixed plane at the point $p$ of its
surface (section frame) and rolls on it: that material point is at rest. With the tree's
velocities $v = (\xi, \dot q)$ (the section's body twist and the shape velocity), body
$k$'s twist in the section frame is $\hat J_k v$ (`velocity_jacobians`), and the contact
point's velocity is

$$ u = C v, \qquad C = \begin{pmatrix} -\tilde p & I \end{pmatrix}\hat J_k, $$

three Pfaffian rows (76). $\hat J_k$ passes the section's twist through unchanged, so the
section's linear velocity enters $u$ with the identity: the constraints solve for it, and
the kinematic characteristics are $e = (\omega, \dot q)$, the section's angular velocity
and the shape velocity. The parametric form (77) is $v = H e$,

$$ H = \begin{pmatrix} I & 0 \\ -C_\omega & -C_q \\ 0 & I \end{pmatrix}, $$

with $C_\omega$, $C_q$ the columns of $C$ on $\omega$ and $\dot q$. Maggi's equations (82)
with the metric $G(q)$ of the tree are Gauss's principle in these variables: the
characteristics' rates make the constrained acceleration $\dot v = He' + \dot He$ the
$G$-projection of the unconstrained one $a$ (the reference form of the equations of
motion, with the scene's forces),

$$ \dot e = (H^T G H)^{-1} H^T G\,(a - \dot H e). $$

$p$ and $H$ depend on the section's orientation through the plane's normal seen from it,
$n = R^T n_{\rm world}$, turning as $\dot n = n\times\omega$, and on $q$; $\dot H e$ is a
JVP along both. The normal row of the constraints is holonomic (the wheel touches the
plane); as for a single body (`RollingMode`) it is kept by coordinate partitioning, the
pose's offset along the normal placed so that the contact point lies on the plane.
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
from .._nonholonomic._contact import AbstractContactSurface, unit_axis
from .._state import State
from .._systems._multibody import AbstractMultibody
from .._validation import check_shape
from ._base import AbstractFreeMotionMode, SceneParts
from ._floating import body_twist, checked_shape
from ._plane_contact import CONSISTENCY

__all__ = ["RollingWheelMode"]


class RollingWheelMode(AbstractFreeMotionMode):
    r"""One body of a floating multibody tree, a wheel, rolls without slipping on a fixed plane (seed 001, (76), (77), (82)).

    The integration state is $y = (g, x)$: the section's pose on SE(3) (stepped by the
    Lie-group solvers) and $x = (q, \omega, \dot q)$, the shape and the kinematic
    characteristics $e = (\omega, \dot q)$; the section's linear velocity follows from the
    rolling constraints. The plane's reaction is ideal and does no work, so the energy of a
    scene with conservative effects is conserved.

    ```python
    tree = bd.Multibody.from_mjcf("unicycle.xml")
    mode = bd.RollingWheelMode(bd.DiscContact(0.3), wheel="wheel")
    scene = bd.Scene(tree, [bd.Gravity(9.81)], mode=mode)
    state = mode.state(tree, g0, q0, omega0, qdot0)  # on the plane, rolling
    ```

    **Arguments:**

    - `surface`: the wheel's `AbstractContactSurface` in the wheel's own frame
      (`DiscContact`, `TorusContact`, `SphereContact`, `EllipsoidContact`).
    - `wheel`: the wheel's body name (`Multibody.names`) or index.
    - `normal`: the plane's upward normal in the world frame; default $(0, 0, 1)$.
    - `offset`: the plane is $\{x : n\cdot x = \text{offset}\}$; default 0.
    """

    surface: AbstractContactSurface
    wheel: str | int = eqx.field(static=True)
    normal: Float[Array, "3"]
    offset: Float[Array, ""]

    def __init__(self, surface, *, wheel, normal=(0.0, 0.0, 1.0), offset=0.0):
        self.surface = surface
        self.wheel = wheel
        self.normal = unit_axis("RollingWheelMode", normal, "normal")
        self.offset = jnp.asarray(offset, dtype=float)

    def __check_init__(self):
        if not isinstance(self.surface, AbstractContactSurface):
            raise ValueError(
                "`RollingWheelMode.surface` must be an AbstractContactSurface, e.g. "
                f"`bd.DiscContact(radius)`; got {type(self.surface).__name__}."
            )
        if not isinstance(self.wheel, (str, int)):
            raise ValueError(
                "`RollingWheelMode.wheel` must be a body's name or index; got "
                f"{type(self.wheel).__name__}."
            )
        check_shape("RollingWheelMode.offset", self.offset, ())

    def wheel_index(self, system: AbstractMultibody) -> int:
        """The wheel's index among `system`'s bodies (static)."""
        if isinstance(self.wheel, int):
            if not 0 <= self.wheel < system.num_bodies:
                raise ValueError(
                    f"`RollingWheelMode.wheel` is {self.wheel}, but the tree has "
                    f"{system.num_bodies} bodies."
                )
            return self.wheel
        if self.wheel not in system.names:
            raise ValueError(
                f"`RollingWheelMode.wheel` is {self.wheel!r}, which is not one of the tree's "
                f"bodies {system.names}."
            )
        return system.names.index(self.wheel)

    def check(self, system, frame):
        if not (isinstance(system, AbstractMultibody) and system.shape_dim > 0):
            raise ValueError(
                "`RollingWheelMode` rolls a wheel of a multibody tree with shape coordinates "
                f"(`bd.Multibody`); got {type(system).__name__}. A single rolling body is "
                "`bd.RollingMode`."
            )
        self.wheel_index(system)
        if frame is not None:
            raise ValueError(
                "`RollingWheelMode` rolls on a plane at rest in the Galilean frame: give the "
                "scene no `frame`."
            )

    def _contact_rows(self, system, n, q):
        r"""$C(n, q)$ `(3, 6 + d)` and the contact point $p$ (section frame)."""
        r, Jhat = system.velocity_jacobians(q)
        k = self.wheel_index(system)
        R_k = r[k, :3, :3]
        p = matmul(R_k, self.surface.contact_point(matmul(R_k.T, n))) + r[k, :3, 3]
        rows = jnp.concatenate([-lie.so3_hat(p), jnp.eye(3, dtype=p.dtype)], axis=1)
        return matmul(rows, Jhat[k]), p

    def _velocities(self, system, n, q, e):
        r"""$v = H e$: the section's twist and the shape velocity of the characteristics."""
        C, _ = self._contact_rows(system, n, q)
        omega, qdot = e[:3], e[3:]
        v = -(matmul(C[:, :3], omega) + matmul(C[:, 6:], qdot))
        return jnp.concatenate([omega, v, qdot])

    def _section_normal(self, g):
        return matmul(g[:3, :3].T, self.normal)

    def placed(self, system, g, q) -> Float[Array, "4 4"]:
        r"""The pose `g` moved along the plane's normal until the wheel's contact point lies
        on the plane (the holonomic constraint, solved for the offset along the normal)."""
        _, p = self._contact_rows(system, self._section_normal(g), q)
        gap = jnp.dot(self.normal, g[:3, 3] + matmul(g[:3, :3], p)) - self.offset
        return g.at[:3, 3].set(g[:3, 3] - gap * self.normal)

    def state(self, system, g, q, omega, qdot) -> State:
        r"""The `State` of the tree at pose `g` (placed on the plane) and shape `q`, with the
        section's angular velocity `omega` and the shape velocity `qdot`, the section's
        linear velocity the one that keeps the wheel rolling.

        **Arguments:**

        - `system`: the tree.
        - `g`: the section's pose `(4, 4)` (its offset along the plane's normal is replaced).
        - `q`, `qdot`: the shape and its velocity, `(d,)` each.
        - `omega`: the section's body angular velocity `(3,)`.
        """
        q = jnp.asarray(q, dtype=float)
        g = self.placed(system, jnp.asarray(g, dtype=float), q)
        e = jnp.concatenate([jnp.asarray(omega, dtype=float), jnp.asarray(qdot, dtype=float)])
        v = self._velocities(system, self._section_normal(g), q, e)
        return State(g, q, v[:6], v[6:])

    def pack(self, scene: SceneParts, g, q, U, qdot):
        xi = body_twist(scene, q, U, qdot)
        return g, jnp.concatenate([q, xi[:3], qdot])

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
        y = self.pack(scene, state.g, q, U, qdot)
        g, _, _, xi, _ = self._parts(scene, y)
        scale = jnp.linalg.norm(state.xi) + jnp.linalg.norm(state.g[:3, 3]) + 1.0
        off = jnp.linalg.norm(xi - state.xi) + jnp.linalg.norm(g[:3, 3] - state.g[:3, 3])
        g0 = eqx.error_if(
            state.g,
            off > CONSISTENCY * scale,
            "the state does not keep the wheel rolling: its contact point must lie on the "
            "plane and be at rest; build it with the mode's `state(system, g, q, omega, "
            "qdot)`.",
        )
        return g0, y[1]

    def decode(self, scene: SceneParts, t, y):
        g, q, _, xi, qdot = self._parts(scene, y)
        return State(g, q, xi, qdot), locked_velocity(scene.system, q, xi, qdot)

    def body_field(self, scene: SceneParts, t, y):
        system = scene.system
        g, q, e, xi, qdot = self._parts(scene, y)
        n = self._section_normal(g)
        H_of = lambda n, q: jax.jacfwd(lambda e: self._velocities(system, n, q, e))(e)
        H, H_dot = jax.jvp(H_of, (n, q), (jnp.cross(n, xi[:3]), qdot))
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
        r"""The wheel's contact point's velocity $u = Cv$ (section frame, 3 rows) and its
        height above the plane (1 row)."""
        g = state.g
        C, p = self._contact_rows(scene.system, self._section_normal(g), state.q)
        u = matmul(C, jnp.concatenate([state.xi, state.qdot]))
        height = jnp.dot(self.normal, g[:3, 3] + matmul(g[:3, :3], p)) - self.offset
        return jnp.concatenate([u, height[None]])

    def window_chart(self, scene: SceneParts):
        raise ValueError(
            "identification does not fit scenes with a rolling wheel (`RollingWheelMode`): "
            "its window states would have to keep the rolling constraints."
        )
