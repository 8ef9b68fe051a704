r"""A floating base integrated about its centre of mass: steps that do not see a uniform velocity."""

import jax.numpy as jnp

from .._dynamics import bundle_geometry, locked_acceleration, shape_acceleration
from .._effects import Kinematics, mass_and_centre
from .._geometry import locked_velocity
from .._linalg import matmul
from .._state import State
from .._systems._ball_chart import ball_columns, recharted_shape
from ._base import AbstractFreeMotionMode, SceneParts
from ._charts import FloatingChart, balls_of
from ._floating import body_twist, checked_shape

__all__ = ["CentreOfMassMode"]


def _translated(p, g):
    """`g` moved by the translation `p` of the Galilean frame."""
    return g.at[:3, 3].add(p)


def _frame_velocity(R, v_c):
    r"""$\operatorname{Ad}_{g^{-1}}(0, v_c) = (0, R^T v_c)$: the velocity of the frame that
    translates with the centre of mass, seen from the section frame."""
    return jnp.concatenate([jnp.zeros_like(v_c), matmul(R.T, v_c)])


class CentreOfMassMode(AbstractFreeMotionMode):
    r"""A floating base integrated in the frame that translates with the centre of mass.

    By Theorem 2.2 (seed 004) a Galilean-invariant system seen from a frame moving with a
    uniform velocity obeys the same equations, and by Theorem 3.4 a uniformly accelerated
    frame adds a uniform field, which moves the centre of mass alone. So this mode
    integrates the centre of mass's motion in the Galilean frame, $m\dot v_c = R F_v$ (the
    total force), and the rest of the state in the non-rotating frame that carries the
    centre of mass: the pose $g_c = (R, p - c_w)$, the shape, the shape velocity and the
    locked velocity relative to that frame, $U_c = U - (0, R^T v_c)$ (zero linear
    momentum), with

    $$\dot U_c = \dot U(q, U_c, \dot q) - (0, F_v/m),$$

    (2.7) at the relative velocity less the frame's acceleration, and $\ddot q$ of (2.6) at
    the relative velocity; the forces see the true motion. The centre of mass's position
    is integrated as $c_0 = c_w - t\,v_c$ (its Galilean boost's charge over $m$, constant
    for a system without external forces), with $\dot c_0 = -t\,\dot v_c$.

    So a body at orbital speed takes the steps it takes at rest, and no term of
    (2.6)–(2.7) is formed from the large velocity. The default layouts (`FreeShapeMode`,
    `RigidBodyMode`) integrate $U$ in the section frame, where a spinning body's linear
    velocity swings through $\pm|v_c|$ every turn, and the error control and the rounding
    of terms quadratic in $v$ follow it.

    The integration state is $y = (g_c, x)$ with $x = [c_0, v_c, q, U_c, \dot q]$. The mode
    needs a system that meets Theorem 2.2 (every physical one) and a scene seen from the
    Galilean frame (no `frame`); times of the order of the motion's, not since an epoch
    ($c_0$ is extrapolated to $t = 0$). Use it as
    `bd.Scene(system, effects, mode=bd.CentreOfMassMode())`.
    """

    def check(self, system, frame):
        if frame is not None:
            raise ValueError(
                "`CentreOfMassMode` integrates in the Galilean frame: give the scene no "
                "`frame` (the centre of mass's translation is the frame it moves with)."
            )

    def _split(self, scene: SceneParts, y):
        r"""$(g_c, c_0, v_c, q, U_c, \dot q)$ of the integration state."""
        g_c, x = y
        d = scene.system.shape_dim
        return g_c, x[:3], x[3:6], x[6 : 6 + d], x[6 + d : 12 + d], x[12 + d :]

    def _joined(self, g_c, c_0, v_c, q, U_c, qdot):
        return g_c, jnp.concatenate([c_0, v_c, q, U_c, qdot])

    def pack(self, scene: SceneParts, t, g, q, U, qdot):
        # U_c is written with zero linear momentum, v = c × ω (Theorem 2.3's form of I_r),
        # rather than as U less the frame's velocity: a difference of two orbital-size
        # numbers would leave their rounding in it.
        _, c, _ = mass_and_centre(scene.system.metric(q)[:6, :6])
        R, omega = g[:3, :3], U[:3]
        v_c = matmul(R, U[3:] + jnp.cross(omega, c))
        c_w = g[:3, 3] + matmul(R, c)
        U_c = jnp.concatenate([omega, jnp.cross(c, omega)])
        return self._joined(_translated(-c_w, g), c_w - t * v_c, v_c, q, U_c, qdot)

    def unpack(self, scene: SceneParts, t, y):
        g_c, c_0, v_c, q, U_c, qdot = self._split(scene, y)
        g = _translated(c_0 + t * v_c, g_c)
        return g, q, U_c + _frame_velocity(g_c[:3, :3], v_c), qdot

    def encode(self, scene: SceneParts, t, state: State):
        q, qdot = checked_shape(scene, state)
        U = locked_velocity(scene.system, q, state.xi, qdot)
        return self.pack(scene, t, state.g, q, U, qdot)

    def decode(self, scene: SceneParts, t, y):
        g, q, U, qdot = self.unpack(scene, t, y)
        g_c, _, v_c, _, U_c, _ = self._split(scene, y)
        xi = body_twist(scene, q, U_c, qdot) + _frame_velocity(g_c[:3, :3], v_c)
        return State(g, q, xi, qdot), U

    def body_field(self, scene: SceneParts, t, y):
        g_c, c_0, v_c, q, U_c, qdot = self._split(scene, y)
        R = g_c[:3, :3]
        geo = bundle_geometry(scene.system, q, U_c, qdot)
        xi_c = U_c - matmul(geo.A, qdot) if qdot.shape[0] else U_c  # relative to the frame
        kin = Kinematics(
            t, _translated(c_0 + t * v_c, g_c), q, xi_c + _frame_velocity(R, v_c), qdot
        )
        F, Q = scene.forces(kin)
        m = jnp.trace(geo.I_r[3:, 3:]) / 3.0
        acceleration = F[3:] / m  # the centre of mass's, in section axes
        frame = jnp.concatenate([jnp.zeros_like(acceleration), acceleration])
        Udot = locked_acceleration(geo, F) - frame
        qddot = shape_acceleration(geo, F, Q) if qdot.shape[0] else qdot
        v_dot = matmul(R, acceleration)
        return xi_c, jnp.concatenate([-t * v_dot, v_dot, qdot, Udot, qddot])

    def kinematics(self, scene: SceneParts, t, y):
        state, _ = self.decode(scene, t, y)
        return Kinematics(t, state.g, state.q, state.xi, state.qdot)

    def recharted(self, scene: SceneParts, t, y):
        if ball_columns(scene.system).size == 0:
            return y
        g_c, c_0, v_c, q, U_c, qdot = self._split(scene, y)
        q, qdot = recharted_shape(scene.system, q, qdot)
        return self._joined(g_c, c_0, v_c, q, U_c, qdot)

    def constraint_residual(self, scene: SceneParts, state: State):
        return state.xi[:0]

    def window_chart(self, scene: SceneParts):
        return FloatingChart(scene.system.shape_dim, balls_of(scene.system))
