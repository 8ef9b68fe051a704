r"""A base that follows a given motion: only the shape equation, driven by it, is integrated."""

import jax.numpy as jnp

from .._effects import Kinematics
from .._geometry import locked_velocity
from .._state import State
from .._systems._ball_chart import ball_columns, recharted_shape
from ._base import AbstractMode, SceneParts
from ._charts import DrivenChart, balls_of
from ._floating import checked_shape
from ._motions import Free, PrescribedBase

__all__ = ["PrescribedBaseMode", "select"]


class PrescribedBaseMode(AbstractMode):
    r"""A prescribed base $g(t)$ and a free shape: $x = [q, \dot q]$, and the field is
    $(\dot q, \ddot q)$ of the shape equation driven by the base (`driven_shape_acceleration`);
    $g$ is carried along.

    **Arguments:**

    - `motion`: the base's `PrescribedBase` motion.
    """

    motion: PrescribedBase

    @property
    def shape(self):
        return Free()

    @property
    def base(self):
        return self.motion

    def check(self, system, frame):
        if system.shape_dim == 0:
            raise ValueError(
                "`PrescribedBase` integrates the shape equation: it needs a free shape with "
                "d > 0 (with a prescribed shape too, nothing would be left to integrate)."
            )
        if frame is not None:
            raise ValueError("give a `PrescribedBase`'s motion in the Galilean frame (frame=None).")

    def pack(self, scene: SceneParts, t, g, q, U, qdot):
        return g, jnp.concatenate([q, qdot])

    def _shape(self, scene: SceneParts, y):
        d = scene.system.shape_dim
        x = y[1]
        return x[:d], x[d:]

    def unpack(self, scene: SceneParts, t, y):
        q, qdot = self._shape(scene, y)
        g, xi, _ = self.motion.at(t)
        return g, q, locked_velocity(scene.system, q, xi, qdot), qdot

    def encode(self, scene: SceneParts, t, state: State):
        q, qdot = checked_shape(scene, state)
        g = self.motion.at(jnp.asarray(t, dtype=state.g.dtype))[0]
        return g, jnp.concatenate([q, qdot])

    def decode(self, scene: SceneParts, t, y):
        q, qdot = self._shape(scene, y)
        g, xi, _ = self.motion.at(t)
        return State(g, q, xi, qdot), locked_velocity(scene.system, q, xi, qdot)

    def body_field(self, scene: SceneParts, t, y):
        q, qdot = self._shape(scene, y)
        g, xi, xi_dot = self.motion.at(t)
        qddot = scene.algorithm.driven(scene, t, g, q, xi, xi_dot, qdot)
        return xi, jnp.concatenate([qdot, qddot])

    def kinematics(self, scene: SceneParts, t, y):
        q, qdot = self._shape(scene, y)
        g, xi, _ = self.motion.at(t)
        return Kinematics(t, g, q, xi, qdot)

    def recharted(self, scene: SceneParts, t, y):
        if ball_columns(scene.system).size == 0:
            return y
        q, qdot = recharted_shape(scene.system, *self._shape(scene, y))
        return y[0], jnp.concatenate([q, qdot])

    def constraint_residual(self, scene: SceneParts, state: State):
        return state.xi[:0]

    def window_chart(self, scene: SceneParts):
        return DrivenChart(scene.system.shape_dim, balls_of(scene.system))


def select(system, shape, base) -> PrescribedBaseMode | None:
    """This mode for a prescribed base (any shape: a prescribed one is refused by `check`)."""
    if isinstance(base, PrescribedBase):
        if not isinstance(shape, Free):
            raise ValueError(
                "`PrescribedBase` integrates the shape equation: it needs a free shape with "
                "d > 0 (with a prescribed shape too, nothing would be left to integrate)."
            )
        return PrescribedBaseMode(base)
    return None
