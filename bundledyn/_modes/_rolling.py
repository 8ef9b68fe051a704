r"""A rigid body rolling without slipping on a plane: Maggi's equations (82) on SE(3).

The rolling constraints in parametric form (77) give the body twist from the angular
velocity, $\xi = H\omega$, $H = (I;\ \tilde c)$ (`contact_twist`). Maggi's equations (82)
with the body twist as the quasi-velocities whose kinetic terms (2.7) gives,
$H^T\big(I_r\dot\xi + \operatorname{ad}^*_\xi I_r\xi - F\big) = 0$ with
$\dot\xi = \dot H\omega + H\dot\omega$, are solved for the characteristics' rates:

$$ \dot\omega = (H^T I_r H)^{-1} H^T\big(F - \operatorname{ad}^*_\xi I_r\xi - I_r\dot H\omega\big). $$

The normal row of the constraints is holonomic (the surface touches the plane); it is kept
by coordinate partitioning: the pose's offset along the plane's normal is not read from the
integrated pose but placed so that the contact point lies on the plane, so the residual of
that constraint is zero to rounding at every saved state.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .. import lie
from .._dynamics import bundle_geometry, coadjoint_term
from .._effects import Kinematics
from .._linalg import matmul, spd_solve
from .._nonholonomic._contact import AbstractContactSurface, contact_twist
from .._state import State
from .._validation import check_shape, concrete
from ._base import AbstractFreeMotionMode, SceneParts
from ._floating import checked_shape

__all__ = ["RollingMode"]

# How far a given state may be from the rolling constraints, relative to its scale, before
# `encode` refuses it: far above rounding, far below any physically different state.
_CONSISTENCY = 1e-8


class RollingMode(AbstractFreeMotionMode):
    r"""A rigid body whose surface rolls without slipping on a fixed plane (seed 001, (77), (82)).

    The integration state is $y = (g, \omega)$: the pose on SE(3) (stepped by the Lie-group
    solvers) and the body angular velocity, the kinematic characteristics; the body twist
    is $\xi = (\omega, c\times\omega)$. Gravity and any other effects act as on a free
    body; the plane's reaction is ideal and does no work, so the energy of a scene with
    conservative effects is conserved.

    ```python
    ball = bd.RigidBody(mass, jnp.zeros(3), inertia)
    scene = bd.Scene(ball, [bd.Gravity(9.81)], mode=bd.RollingMode(bd.SphereContact(0.1)))
    state = scene.mode.state(g0, omega0)  # on the plane, with the rolling twist
    ```

    **Arguments:**

    - `surface`: the body's `AbstractContactSurface` (`SphereContact`, `DiscContact`,
      `TorusContact`, `EllipsoidContact`).
    - `normal`: the plane's upward normal in the world frame; default $(0, 0, 1)$.
    - `offset`: the plane is $\{x : n\cdot x = \text{offset}\}$; default 0.
    """

    surface: AbstractContactSurface
    normal: Float[Array, "3"]
    offset: Float[Array, ""]

    def __init__(self, surface, *, normal=(0.0, 0.0, 1.0), offset=0.0):
        self.surface = surface
        normal = jnp.asarray(normal, dtype=float)
        self.normal = normal / jnp.linalg.norm(normal)
        self.offset = jnp.asarray(offset, dtype=float)

    def __check_init__(self):
        if not isinstance(self.surface, AbstractContactSurface):
            raise ValueError(
                "`RollingMode.surface` must be an AbstractContactSurface, e.g. "
                f"`bd.SphereContact(radius)`; got {type(self.surface).__name__}."
            )
        check_shape("RollingMode.normal", self.normal, (3,))
        check_shape("RollingMode.offset", self.offset, ())
        normal = concrete(self.normal)
        if normal is not None and not np.all(np.isfinite(normal)):
            raise ValueError("`RollingMode.normal` must be a nonzero finite vector.")

    def check(self, system, frame):
        if system.shape_dim != 0:
            raise ValueError(
                "`RollingMode` rolls a rigid body (no shape coordinates); got a system with "
                f"{system.shape_dim}."
            )
        if frame is not None:
            raise ValueError(
                "`RollingMode` rolls on a plane at rest in the Galilean frame: give the scene "
                "no `frame`."
            )

    def contact(self, R: Float[Array, "3 3"]) -> Float[Array, "3"]:
        r"""The contact point $c(R^T n)$ in the body frame at the orientation $R$."""
        return self.surface.contact_point(matmul(R.T, self.normal))

    def placed(self, g: Float[Array, "4 4"]) -> Float[Array, "4 4"]:
        r"""The pose `g` moved along the plane's normal until its contact point lies on
        the plane (the holonomic constraint, solved for the offset along the normal)."""
        R, p = g[:3, :3], g[:3, 3]
        gap = jnp.dot(self.normal, p + matmul(R, self.contact(R))) - self.offset
        return g.at[:3, 3].set(p - gap * self.normal)

    def state(self, g, omega) -> State:
        r"""The `State` of a body at orientation and position `g`, placed on the plane, with
        body angular velocity `omega` and the rolling twist $\xi = (\omega, c\times\omega)$.

        **Arguments:**

        - `g`: a pose `(4, 4)` (its offset along the plane's normal is replaced).
        - `omega`: the body angular velocity `(3,)`.
        """
        g = self.placed(jnp.asarray(g, dtype=float))
        omega = jnp.asarray(omega, dtype=float)
        xi = contact_twist(self.contact(g[:3, :3]), omega)
        return State(g, jnp.zeros(0, xi.dtype), xi, jnp.zeros(0, xi.dtype))

    def pack(self, scene: SceneParts, g, q, U, qdot):
        return g, U[:3]

    def unpack(self, scene: SceneParts, t, y):
        g, omega = y
        g = self.placed(g)
        xi = contact_twist(self.contact(g[:3, :3]), omega)
        empty = omega[:0]
        return g, empty, xi, empty

    def encode(self, scene: SceneParts, t, state: State):
        q, qdot = checked_shape(scene, state)
        y = self.pack(scene, state.g, q, state.xi, qdot)
        g, _, xi, _ = self.unpack(scene, t, y)
        scale = jnp.linalg.norm(state.xi) + jnp.linalg.norm(state.g[:3, 3]) + 1.0
        off = jnp.linalg.norm(xi - state.xi) + jnp.linalg.norm(g[:3, 3] - state.g[:3, 3])
        g0 = eqx.error_if(
            state.g,
            off > _CONSISTENCY * scale,
            "the state is not rolling on the plane: its pose must touch the plane and its "
            "twist be (omega, c x omega); build it with `RollingMode.state(g, omega)`.",
        )
        return g0, y[1]

    def decode(self, scene: SceneParts, t, y):
        g, q, xi, qdot = self.unpack(scene, t, y)
        return State(g, q, xi, qdot), xi

    def body_field(self, scene: SceneParts, t, y):
        g, q, xi, qdot = self.unpack(scene, t, y)
        omega = y[1]
        R = g[:3, :3]
        n = matmul(R.T, self.normal)
        c, c_dot = jax.jvp(self.surface.contact_point, (n,), (jnp.cross(n, omega),))
        H = jnp.concatenate([jnp.eye(3, dtype=c.dtype), lie.so3_hat(c)])
        H_dot_omega = jnp.concatenate([jnp.zeros_like(c), jnp.cross(c_dot, omega)])
        geo = bundle_geometry(scene.system, q, xi, qdot)
        F, _ = scene.forces(Kinematics(t, g, q, xi, qdot))
        rhs = F - coadjoint_term(geo) - matmul(geo.I_r, H_dot_omega)
        omega_dot = spd_solve(H.T @ geo.I_r @ H, matmul(H.T, rhs))
        return xi, omega_dot

    def kinematics(self, scene: SceneParts, t, y):
        g, q, xi, qdot = self.unpack(scene, t, y)
        return Kinematics(t, g, q, xi, qdot)

    def recharted(self, scene: SceneParts, t, y):
        return y

    def constraint_residual(self, scene: SceneParts, state: State):
        r"""The contact point's velocity $v + \omega\times c$ (body frame, 3 rows) and its
        height above the plane (1 row)."""
        g, xi = state.g, state.xi
        c = self.contact(g[:3, :3])
        height = jnp.dot(self.normal, g[:3, 3] + matmul(g[:3, :3], c)) - self.offset
        return jnp.concatenate([xi[3:] + jnp.cross(xi[:3], c), height[None]])

    def window_chart(self, scene: SceneParts):
        raise ValueError(
            "identification does not fit rolling scenes (`RollingMode`): its window states "
            "would have to stay on the rolling constraints."
        )
