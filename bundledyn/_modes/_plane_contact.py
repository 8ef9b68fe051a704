r"""A rigid body touching a fixed plane at one point: the parametric form (77) of its
contact and Maggi's equations (82) on SE(3), shared by rolling and skating.

The material point at the contact $c$ (body frame) may slide only along the directions
$S$ (a `(3, s)` matrix of orthonormal columns tangent to the plane): none for rolling, the
blade's direction for a skate. Its velocity $v + \omega\times c$ is then $S\sigma$, so the
kinematic characteristics are $e = (\omega, \sigma)$ and the body twist is

$$ \xi = H e, \qquad H = \begin{pmatrix} I & 0 \\ \tilde c & S \end{pmatrix}. $$

Maggi's equations (82) with the body twist as the quasi-velocities whose kinetic terms
(2.7) gives, $H^T\big(I_r\dot\xi + \operatorname{ad}^*_\xi I_r\xi - F\big) = 0$ with
$\dot\xi = \dot H e + H\dot e$, are solved for the characteristics' rates:

$$ \dot e = (H^T I_r H)^{-1} H^T\big(F - \operatorname{ad}^*_\xi I_r\xi - I_r\dot H e\big) $$

(`maggi_body_rates`), or Appell's equations from the energy of the material points'
accelerations (`appell_body_rates`), as the mode's `equations` say.

$c$ and $S$ depend on the orientation through the plane's normal seen from the body,
$n = R^T n_{\rm world}$, which turns as $\dot n = n\times\omega$; $\dot H e$ is a JVP
along it. The normal row of the constraints is holonomic (the body touches the plane); it
is kept by coordinate partitioning: the pose's offset along the plane's normal is not read
from the integrated pose but placed so that the contact point lies on the plane, so the
residual of that constraint is zero to rounding at every saved state.
"""

import abc

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .. import lie
from .._dynamics import bundle_geometry
from .._effects import Kinematics
from .._linalg import matmul
from .._nonholonomic._body_motion import BodyMotion
from .._nonholonomic._contact import AbstractContactSurface
from .._nonholonomic._equations import AbstractNonholonomicEquations
from .._state import State
from .._validation import check_shape, precision_floor
from ._base import AbstractFreeMotionMode, SceneParts
from ._floating import checked_shape

__all__ = ["AbstractPlaneContactMode", "check_contact", "consistency"]


def consistency(dtype) -> float:
    """How far a given state may be from the contact constraints, relative to its scale,
    before `encode` refuses it: far above rounding (1e-8, or 1000 rounding errors of `dtype`
    where that is larger: float32 builds a state consistent to about 1e-6), far below any
    physically different state."""
    return precision_floor(dtype, 1e-8, 1000.0)


def check_contact(owner: str, surface, offset, equations) -> None:
    """Refuse, with a `ValueError`, a contact surface that is not an `AbstractContactSurface`,
    a plane offset that is not a scalar, or equations that are not an
    `AbstractNonholonomicEquations`."""
    if not isinstance(surface, AbstractContactSurface):
        raise ValueError(
            f"`{owner}.surface` must be an AbstractContactSurface, e.g. "
            f"`bd.SphereContact(radius)`; got {type(surface).__name__}."
        )
    check_shape(f"{owner}.offset", offset, ())
    if not isinstance(equations, AbstractNonholonomicEquations):
        raise ValueError(
            f"`{owner}.equations` must be `bd.MaggiEquations()` or `bd.AppellEquations()` (an "
            f"AbstractNonholonomicEquations); got {type(equations).__name__}."
        )


class AbstractPlaneContactMode(AbstractFreeMotionMode):
    r"""A rigid body whose surface touches a fixed plane at one point, which may slide only
    along given directions (seed 001, (77), (82)).

    The integration state is $y = (g, e)$: the pose on SE(3) (stepped by the Lie-group
    solvers) and the characteristics $e = (\omega, \sigma)$, the body angular velocity and
    the contact point's speeds along the sliding directions. The plane's reaction is ideal
    and does no work, so the energy of a scene with conservative effects is conserved.

    Subclasses give `sliding_directions`; the plane is `normal`, `offset`; `equations`
    (Maggi's or Appell's) give the characteristics' rates from $H$, $\dot He$ and the
    body's inertia and wrench (`AbstractNonholonomicEquations.body_rates`).
    """

    surface: eqx.AbstractVar[AbstractContactSurface]
    normal: eqx.AbstractVar[Float[Array, "3"]]
    offset: eqx.AbstractVar[Float[Array, ""]]
    equations: eqx.AbstractVar[AbstractNonholonomicEquations]

    @abc.abstractmethod
    def sliding_directions(self, n: Float[Array, "3"]) -> Float[Array, "3 s"]:
        r"""The directions $S(n)$ (body frame, orthonormal columns tangent to the plane) along
        which the contact point may slide, for the plane's normal $n$ seen from the body."""

    def check(self, system, frame):
        name = type(self).__name__
        if system.shape_dim != 0:
            raise ValueError(
                f"`{name}` moves a rigid body on a plane (no shape coordinates); got a system "
                f"with {system.shape_dim}."
            )
        if frame is not None:
            raise ValueError(
                f"`{name}` moves on a plane at rest in the Galilean frame: give the scene no "
                "`frame`."
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

    def _contact_frame(self, n):
        return self.surface.contact_point(n), self.sliding_directions(n)

    def _twist(self, n, e):
        r"""$\xi = H e$: the body twist of the characteristics $e = (\omega, \sigma)$."""
        c, S = self._contact_frame(n)
        omega, sigma = e[:3], e[3:]
        return jnp.concatenate([omega, jnp.cross(c, omega) + matmul(S, sigma)])

    def state(self, g, omega, sliding=None) -> State:
        r"""The `State` of a body at orientation and position `g`, placed on the plane, with
        body angular velocity `omega` and the contact point sliding at `sliding` along the
        mode's directions: the twist $\xi = (\omega,\ c\times\omega + S\sigma)$.

        **Arguments:**

        - `g`: a pose `(4, 4)` (its offset along the plane's normal is replaced).
        - `omega`: the body angular velocity `(3,)`.
        - `sliding`: the speeds $\sigma$ `(s,)` along `sliding_directions`; default zero.
        """
        g = self.placed(jnp.asarray(g, dtype=float))
        omega = jnp.asarray(omega, dtype=float)
        n = matmul(g[:3, :3].T, self.normal)
        s = self.sliding_directions(n).shape[1]
        sliding = jnp.zeros(s, omega.dtype) if sliding is None else jnp.asarray(sliding, float)
        check_shape(f"{type(self).__name__}.state's sliding", sliding, (s,))
        xi = self._twist(n, jnp.concatenate([omega, sliding]))
        return State(g, jnp.zeros(0, xi.dtype), xi, jnp.zeros(0, xi.dtype))

    def pack(self, scene: SceneParts, t, g, q, U, qdot):
        c, S = self._contact_frame(matmul(g[:3, :3].T, self.normal))
        omega = U[:3]
        return g, jnp.concatenate([omega, matmul(S.T, U[3:] - jnp.cross(c, omega))])

    def unpack(self, scene: SceneParts, t, y):
        g, e = y
        g = self.placed(g)
        xi = self._twist(matmul(g[:3, :3].T, self.normal), e)
        empty = e[:0]
        return g, empty, xi, empty

    def encode(self, scene: SceneParts, t, state: State):
        q, qdot = checked_shape(scene, state)
        y = self.pack(scene, t, state.g, q, state.xi, qdot)
        g, _, xi, _ = self.unpack(scene, t, y)
        scale = jnp.linalg.norm(state.xi) + jnp.linalg.norm(state.g[:3, 3]) + 1.0
        off = jnp.linalg.norm(xi - state.xi) + jnp.linalg.norm(g[:3, 3] - state.g[:3, 3])
        g0 = eqx.error_if(
            state.g,
            off > consistency(off.dtype) * scale,
            "the state does not keep the contact: its pose must touch the plane and its "
            "contact point move only along the sliding directions; build it with the mode's "
            "`state(g, omega, sliding)`.",
        )
        return g0, y[1]

    def decode(self, scene: SceneParts, t, y):
        g, q, xi, qdot = self.unpack(scene, t, y)
        return State(g, q, xi, qdot), xi

    def body_field(self, scene: SceneParts, t, y):
        g, q, xi, qdot = self.unpack(scene, t, y)
        e = y[1]
        omega, sigma = e[:3], e[3:]
        n = matmul(g[:3, :3].T, self.normal)
        (c, S), (c_dot, S_dot) = jax.jvp(self._contact_frame, (n,), (jnp.cross(n, omega),))
        s = S.shape[1]
        H = jnp.block(
            [[jnp.eye(3, dtype=c.dtype), jnp.zeros((3, s), c.dtype)], [lie.so3_hat(c), S]]
        )
        H_dot_e = jnp.concatenate(
            [jnp.zeros_like(c), jnp.cross(c_dot, omega) + matmul(S_dot, sigma)]
        )
        inertia = bundle_geometry(scene.system, q, xi, qdot).I_r
        F, _ = scene.forces(Kinematics(t, g, q, xi, qdot))
        return xi, self.equations.body_rates(BodyMotion(H, H_dot_e, xi, inertia, F))

    def kinematics(self, scene: SceneParts, t, y):
        g, q, xi, qdot = self.unpack(scene, t, y)
        return Kinematics(t, g, q, xi, qdot)

    def recharted(self, scene: SceneParts, t, y):
        return y

    def constraint_residual(self, scene: SceneParts, state: State):
        r"""The contact point's velocity $u = v + \omega\times c$ off the sliding directions,
        $u - SS^Tu$ (body frame, 3 rows), and its height above the plane (1 row)."""
        g, xi = state.g, state.xi
        R = g[:3, :3]
        c, S = self._contact_frame(matmul(R.T, self.normal))
        u = xi[3:] + jnp.cross(xi[:3], c)
        height = jnp.dot(self.normal, g[:3, 3] + matmul(R, c)) - self.offset
        return jnp.concatenate([u - matmul(S, matmul(S.T, u)), height[None]])

    def window_chart(self, scene: SceneParts):
        raise ValueError(
            f"identification does not fit scenes on a plane contact (`{type(self).__name__}`): "
            "its window states would have to keep the contact's constraints."
        )
