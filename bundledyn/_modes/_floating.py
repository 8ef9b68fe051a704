r"""What the modes with a floating base share: the field of (2.6)–(2.7) in the locked
velocity, and the state seen from the Galilean frame."""

from .. import lie
from .._dynamics import bundle_geometry, locked_acceleration
from .._effects import Kinematics
from .._geometry import connection
from .._linalg import matmul
from .._state import State
from ._base import SceneParts, frame_shift

__all__ = [
    "body_twist",
    "checked_shape",
    "floating_field",
    "galilean_kinematics",
    "locked_field",
]


def _seen_from_the_frame(scene: SceneParts, t, g, U, rates):
    r"""`rates(g, U)`'s $(\xi, \dot U, \ldots)$ in the Galilean frame, seen from the
    scene's frame.

    In a moving frame the locked velocity is relative to it: the true one is $U +
    \operatorname{Ad}_{g^{-1}}\vartheta$, and $\dot U$ gains $[\xi, \operatorname{Ad}_{g^{-1}}\vartheta]
    - \operatorname{Ad}_{g^{-1}}\dot\vartheta$ (seed 004, (2.9)–(2.10)).
    """
    if scene.frame is None:
        return rates(g, U)
    shift, shift_dot, M = frame_shift(scene.frame, t, g)
    xi, Udot, *rest = rates(matmul(M, g), U + shift)
    xi = xi - shift
    return xi, Udot + lie.bracket(xi, shift) - shift_dot, *rest


def floating_field(scene: SceneParts, t, g, q, U, qdot):
    r"""The body twist $\xi$ of the pose and the rates $\dot U$ (2.7) and $\ddot q$ (2.6)
    of a free shape on a floating base, by the scene's `algorithm`.

    **Arguments:**

    - `scene`: the scene; `t`: the time.
    - `g`, `q`, `U`, `qdot`: the pose, shape, locked velocity and shape velocity in the
      scene's frame.

    **Returns:**

    `(xi, Udot, qddot)`.
    """

    def rates(g, U):
        return scene.algorithm.floating(scene, t, g, q, U, qdot)

    return _seen_from_the_frame(scene, t, g, U, rates)


def locked_field(scene: SceneParts, t, g, q, U, qdot):
    r"""The body twist $\xi$ of the pose and the rate $\dot U$ (2.7) alone: a rigid body, or
    a shape whose motion is given.

    **Returns:**

    `(xi, Udot)`.
    """

    def rates(g, U):
        geo = bundle_geometry(scene.system, q, U, qdot)
        xi = U - matmul(geo.A, qdot)
        F, _ = scene.forces(Kinematics(t, g, q, xi, qdot))
        return xi, locked_acceleration(geo, F)

    return _seen_from_the_frame(scene, t, g, U, rates)


def body_twist(scene: SceneParts, q, U, qdot):
    r"""$\xi = U - A(q)\dot q$ (seed 004, §2)."""
    system = scene.system
    return U - connection(system, q) @ qdot if system.shape_dim else U


def galilean_kinematics(scene: SceneParts, t, g, q, xi, qdot) -> Kinematics:
    """The state `(g, q, xi, qdot)` in the scene's frame as `Kinematics` in the Galilean frame."""
    if scene.frame is None:
        return Kinematics(t, g, q, xi, qdot)
    shift, _, M = frame_shift(scene.frame, t, g)
    return Kinematics(t, M @ g, q, xi + shift, qdot)


def checked_shape(scene: SceneParts, state: State):
    """`(state.q, state.qdot)`, after checking their length against the system's."""
    d = scene.system.shape_dim
    if state.q.shape != (d,):
        raise ValueError(
            f"`state.q` and `state.qdot` must have shape ({d},) for this system, got "
            f"{state.q.shape}."
        )
    return state.q, state.qdot
