r"""A shape that follows a given motion on a floating base: (2.7) alone is integrated."""

import jax.numpy as jnp

from .._geometry import locked_velocity
from .._state import State
from ._base import AbstractMode, SceneParts
from ._charts import FloatingChart, balls_of
from ._floating import body_twist, galilean_kinematics, locked_field
from ._motions import FloatingBase, Prescribed

__all__ = ["PrescribedShapeMode", "select"]


class PrescribedShapeMode(AbstractMode):
    r"""A prescribed shape $q(t)$ on a floating base: $x = U$, and the field is $\dot U$
    of (2.7) with $q, \dot q$ read off the motion.

    **Arguments:**

    - `motion`: the shape's `Prescribed` motion.
    """

    motion: Prescribed

    @property
    def shape(self):
        return self.motion

    @property
    def base(self):
        return FloatingBase()

    def check(self, system, frame):
        if system.shape_dim == 0:
            raise ValueError("`Prescribed` needs a system with shape coordinates (d > 0).")

    def pack(self, scene: SceneParts, t, g, q, U, qdot):
        return g, U

    def unpack(self, scene: SceneParts, t, y):
        g, U = y
        q, qdot = self.motion.at(t)
        return g, q, U, qdot

    def encode(self, scene: SceneParts, t, state: State):
        q, qdot = self.motion.at(jnp.asarray(t, dtype=state.g.dtype))
        U = locked_velocity(scene.system, q, state.xi, qdot)
        return self.pack(scene, t, state.g, q, U, qdot)

    def decode(self, scene: SceneParts, t, y):
        g, q, U, qdot = self.unpack(scene, t, y)
        return State(g, q, body_twist(scene, q, U, qdot), qdot), U

    def body_field(self, scene: SceneParts, t, y):
        g, q, U, qdot = self.unpack(scene, t, y)
        return locked_field(scene, t, g, q, U, qdot)

    def kinematics(self, scene: SceneParts, t, y):
        g, q, U, qdot = self.unpack(scene, t, y)
        return galilean_kinematics(scene, t, g, q, body_twist(scene, q, U, qdot), qdot)

    def recharted(self, scene: SceneParts, t, y):
        return y  # the shape is given, not integrated

    def constraint_residual(self, scene: SceneParts, state: State):
        return state.xi[:0]

    def window_chart(self, scene: SceneParts):
        return FloatingChart(scene.system.shape_dim, balls_of(scene.system))


def select(system, shape, base) -> PrescribedShapeMode | None:
    """This mode for a prescribed shape on a floating base."""
    if isinstance(shape, Prescribed) and isinstance(base, FloatingBase):
        return PrescribedShapeMode(shape)
    return None
