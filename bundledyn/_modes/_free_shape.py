r"""A floating base with a free shape: the whole of (2.6)–(2.7) is integrated."""

import jax.numpy as jnp

from .._geometry import locked_velocity
from .._state import State
from .._systems._ball_chart import ball_columns, recharted_shape
from ._base import AbstractFreeMotionMode, SceneParts
from ._charts import FloatingChart, balls_of
from ._floating import body_twist, checked_shape, floating_field, galilean_kinematics
from ._motions import FloatingBase, Free

__all__ = ["FreeShapeMode", "select"]


class FreeShapeMode(AbstractFreeMotionMode):
    r"""A floating base and a free shape ($d > 0$): $x = [q, U, \dot q]$, and the field is
    $(\dot q, \dot U, \ddot q)$ of (2.6)–(2.7)."""

    def check(self, system, frame):
        if system.shape_dim == 0:
            raise ValueError("`FreeShapeMode` needs shape coordinates; a rigid body has none.")

    def pack(self, scene: SceneParts, t, g, q, U, qdot):
        return g, jnp.concatenate([q, U, qdot])

    def unpack(self, scene: SceneParts, t, y):
        g, x = y
        d = scene.system.shape_dim
        return g, x[:d], x[d : d + 6], x[d + 6 :]

    def encode(self, scene: SceneParts, t, state: State):
        q, qdot = checked_shape(scene, state)
        return self.pack(
            scene, t, state.g, q, locked_velocity(scene.system, q, state.xi, qdot), qdot
        )

    def decode(self, scene: SceneParts, t, y):
        g, q, U, qdot = self.unpack(scene, t, y)
        return State(g, q, body_twist(scene, q, U, qdot), qdot), U

    def body_field(self, scene: SceneParts, t, y):
        g, q, U, qdot = self.unpack(scene, t, y)
        xi, Udot, qddot = floating_field(scene, t, g, q, U, qdot)
        return xi, jnp.concatenate([qdot, Udot, qddot])

    def kinematics(self, scene: SceneParts, t, y):
        g, q, U, qdot = self.unpack(scene, t, y)
        return galilean_kinematics(scene, t, g, q, body_twist(scene, q, U, qdot), qdot)

    def recharted(self, scene: SceneParts, t, y):
        if ball_columns(scene.system).size == 0:
            return y
        g, q, U, qdot = self.unpack(scene, t, y)
        q, qdot = recharted_shape(scene.system, q, qdot)
        return self.pack(scene, t, g, q, U, qdot)

    def constraint_residual(self, scene: SceneParts, state: State):
        return state.xi[:0]

    def window_chart(self, scene: SceneParts):
        return FloatingChart(scene.system.shape_dim, balls_of(scene.system))


def select(system, shape, base) -> FreeShapeMode | None:
    """This mode for a free shape of a system with shape coordinates on a floating base."""
    free = isinstance(shape, Free) and isinstance(base, FloatingBase)
    return FreeShapeMode() if free and system.shape_dim > 0 else None
