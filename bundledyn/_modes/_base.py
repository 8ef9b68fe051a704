r"""Scene modes: which parts of a system's state are integrated, and how.

A mode owns a scene's integration layout: the integration state $y = (g, x)$ it packs from
the pose, shape, locked velocity $U = \xi + A(q)\dot q$ (seed 004, §2) and shape velocity,
the field it assembles from (2.6)–(2.7) on that layout, the state in the Galilean frame it
decodes, and the coordinates of an identification window's initial state. The term layer
(`SceneTerm`) delegates to it, so a new kind of scene is one new mode (architecture §5).
"""

import abc
from typing import Any, Protocol

import equinox as eqx
import jax

from .. import lie
from .._effects import AbstractEffect, Kinematics
from .._frames import AbstractFrame
from .._linalg import matmul
from .._state import State
from .._systems._base import AbstractSystem
from ._algorithms import AbstractFieldAlgorithm
from ._charts import AbstractWindowChart
from ._motions import FloatingBase, Free, Prescribed, PrescribedBase

__all__ = ["AbstractFreeMotionMode", "AbstractMode", "SceneParts", "frame_shift"]


class SceneParts(Protocol):
    """What a mode reads of its scene: the system, the frame, the effects and their forces,
    and the field's algorithm (`AbstractFieldAlgorithm`)."""

    @property
    def system(self) -> AbstractSystem: ...

    @property
    def frame(self) -> AbstractFrame | None: ...

    @property
    def effects(self) -> list[AbstractEffect]: ...

    @property
    def algorithm(self) -> AbstractFieldAlgorithm: ...

    def forces(self, kin: Kinematics) -> tuple[jax.Array, jax.Array]: ...


def frame_shift(frame: AbstractFrame, t, g):
    r"""$\operatorname{Ad}_{g^{-1}}\vartheta$, $\operatorname{Ad}_{g^{-1}}\dot\vartheta$ and $M$:
    what a frame moving by $M(t)$ with body velocity $\vartheta$ adds to the velocities of
    (2.9)–(2.10) (seed 004).

    **Arguments:**

    - `frame`: the scene's frame; `t`: the time; `g`: the pose in that frame.

    **Returns:**

    `(shift, shift_dot, M)`: the frame's velocity and acceleration seen from the section
    frame, `(6,)` each, and the frame's pose `(4, 4)`.
    """
    M, theta, theta_dot = frame.motion_and_velocity(t)
    Ad_inv = lie.Ad(lie.se3_inv(g))
    return matmul(Ad_inv, theta), matmul(Ad_inv, theta_dot), M


class AbstractMode(eqx.Module):
    r"""How a scene integrates its system: the layout of the integration state and the
    field on it.

    Subclass it (final classes) for a new kind of scene and pass it as `Scene(..., mode=...)`;
    the built-in ones are chosen from `Scene`'s `shape` and `base` arguments. Every method
    takes the scene (`SceneParts`: its system, frame and forces).
    """

    @property
    @abc.abstractmethod
    def shape(self) -> Free | Prescribed:
        """The shape's motion in the user's terms: `Free()` or `Prescribed(q_of_t)`."""

    @property
    @abc.abstractmethod
    def base(self) -> FloatingBase | PrescribedBase:
        """The base's motion in the user's terms: `FloatingBase()` or `PrescribedBase(g_of_t)`."""

    @abc.abstractmethod
    def check(self, system: AbstractSystem, frame: AbstractFrame | None) -> None:
        """Raise `ValueError`, saying what to use instead, if the mode cannot integrate
        `system` seen from `frame`."""

    @abc.abstractmethod
    def pack(self, scene: SceneParts, t, g, q, U, qdot) -> Any:
        r"""The integration state $y = (g, x)$ at time `t` of the pose, shape, locked velocity
        and shape velocity (a part the layout does not integrate is not read)."""

    @abc.abstractmethod
    def unpack(self, scene: SceneParts, t, y) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
        r"""$(g, q, U, \dot q)$ of the integration state `y` at time `t`."""

    @abc.abstractmethod
    def encode(self, scene: SceneParts, t, state: State) -> Any:
        r"""The integration state $y$ of `state` (in the scene's frame) at time `t`."""

    @abc.abstractmethod
    def decode(self, scene: SceneParts, t, y) -> tuple[State, jax.Array]:
        r"""The `State` $(g, q, \xi, \dot q)$ at `y` and the locked velocity $U$ there."""

    @abc.abstractmethod
    def body_field(self, scene: SceneParts, t, y) -> Any:
        r"""The field at `y`, shaped as `y` with the pose's body twist $\xi$ `(6,)` as its
        first leaf (`AbstractBodyTerm.body_vf`)."""

    @abc.abstractmethod
    def kinematics(self, scene: SceneParts, t, y) -> Kinematics:
        """The state at `y` in the Galilean frame (the true pose and velocities)."""

    @abc.abstractmethod
    def recharted(self, scene: SceneParts, t, y) -> Any:
        r"""`y` with every ball joint's rotation vector in $|\varphi| \le \pi$
        (`recharted_shape`), or `y` itself when nothing is recharted."""

    @abc.abstractmethod
    def constraint_residual(self, scene: SceneParts, state: State) -> jax.Array:
        """The residuals of the constraints the mode keeps, at a decoded `state`: zero when
        they hold, shape `(r,)` (`(0,)` for a mode that keeps none)."""

    @abc.abstractmethod
    def window_chart(self, scene: SceneParts) -> AbstractWindowChart:
        """The coordinates of an identification window's initial state."""


class AbstractFreeMotionMode(AbstractMode):
    """A mode whose shape and base the user does not prescribe: `Free()` and `FloatingBase()`."""

    @property
    def shape(self):
        return Free()

    @property
    def base(self):
        return FloatingBase()
