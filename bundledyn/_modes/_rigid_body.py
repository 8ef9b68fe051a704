r"""A single rigid body ($d = 0$) on a floating base: only (2.7) is integrated."""

from .._state import State
from ._base import AbstractFreeMotionMode, SceneParts
from ._charts import FloatingChart
from ._floating import checked_shape, galilean_kinematics, locked_field
from ._motions import FloatingBase, Free

__all__ = ["RigidBodyMode", "select"]


class RigidBodyMode(AbstractFreeMotionMode):
    r"""A system without shape coordinates: $x = U = \xi$, and the field is $\dot U$ of (2.7)."""

    def check(self, system, frame):
        if system.shape_dim != 0:
            raise ValueError(
                "`RigidBodyMode` is for systems without shape coordinates; use `FreeShapeMode`."
            )

    def pack(self, scene: SceneParts, t, g, q, U, qdot):
        return g, U

    def unpack(self, scene: SceneParts, t, y):
        g, U = y
        empty = U[:0]
        return g, empty, U, empty

    def encode(self, scene: SceneParts, t, state: State):
        q, qdot = checked_shape(scene, state)
        return self.pack(scene, t, state.g, q, state.xi, qdot)

    def decode(self, scene: SceneParts, t, y):
        g, q, U, qdot = self.unpack(scene, t, y)
        return State(g, q, U, qdot), U

    def body_field(self, scene: SceneParts, t, y):
        g, q, U, qdot = self.unpack(scene, t, y)
        return locked_field(scene, t, g, q, U, qdot)

    def kinematics(self, scene: SceneParts, t, y):
        g, q, U, qdot = self.unpack(scene, t, y)
        return galilean_kinematics(scene, t, g, q, U, qdot)

    def recharted(self, scene: SceneParts, t, y):
        return y

    def constraint_residual(self, scene: SceneParts, state: State):
        return state.xi[:0]

    def window_chart(self, scene: SceneParts):
        return FloatingChart(0)


def select(system, shape, base) -> RigidBodyMode | None:
    """This mode for a system without shape coordinates on a floating base."""
    free = isinstance(shape, Free) and isinstance(base, FloatingBase)
    return RigidBodyMode() if free and system.shape_dim == 0 else None
