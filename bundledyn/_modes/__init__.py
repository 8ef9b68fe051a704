r"""Scene modes: a scene's integration layout and field, one final class per kind of scene.

The built-in modes are chosen from `Scene`'s `shape` and `base` arguments by the selections
registered in `SELECTIONS`: a new built-in mode is one file here and one line there.
"""

from ._algorithms import (
    AbstractFieldAlgorithm,
    ArticulatedBodyField,
    DenseField,
    default_algorithm,
)
from ._base import AbstractFreeMotionMode, AbstractMode, SceneParts, frame_shift
from ._centre_of_mass import CentreOfMassMode
from ._charts import AbstractWindowChart, ChannelScales, DrivenChart, FloatingChart
from ._floating import floating_field, galilean_kinematics
from ._free_shape import FreeShapeMode, select as _select_free_shape
from ._motions import FloatingBase, Free, Prescribed, PrescribedBase
from ._plane_contact import AbstractPlaneContactMode
from ._prescribed_base import PrescribedBaseMode, select as _select_prescribed_base
from ._prescribed_shape import PrescribedShapeMode, select as _select_prescribed_shape
from ._rigid_body import RigidBodyMode, select as _select_rigid_body
from ._rolling import RollingMode
from ._rolling_wheel import RollingWheelMode, Wheel
from ._skating import SkatingMode

__all__ = [
    "AbstractFieldAlgorithm",
    "ArticulatedBodyField",
    "DenseField",
    "default_algorithm",
    "AbstractFreeMotionMode",
    "AbstractMode",
    "AbstractPlaneContactMode",
    "AbstractWindowChart",
    "CentreOfMassMode",
    "ChannelScales",
    "DrivenChart",
    "FloatingBase",
    "FloatingChart",
    "Free",
    "FreeShapeMode",
    "Prescribed",
    "PrescribedBase",
    "PrescribedBaseMode",
    "PrescribedShapeMode",
    "RigidBodyMode",
    "RollingMode",
    "RollingWheelMode",
    "SELECTIONS",
    "SceneParts",
    "SkatingMode",
    "Wheel",
    "floating_field",
    "frame_shift",
    "galilean_kinematics",
    "mode_of",
]

# Each takes `(system, shape, base)` and gives its mode, or None if the combination is not its.
SELECTIONS = (
    _select_prescribed_base,
    _select_prescribed_shape,
    _select_free_shape,
    _select_rigid_body,
)


def mode_of(system, shape, base) -> AbstractMode:
    """The built-in mode of `shape` (`Free()` or `Prescribed(q_of_t)`) and `base`
    (`FloatingBase()` or `PrescribedBase(g_of_t)`) for `system`.

    **Raises:**

    `ValueError` if no registered mode integrates that combination.
    """
    for select in SELECTIONS:
        mode = select(system, shape, base)
        if mode is not None:
            return mode
    if not isinstance(shape, Free | Prescribed):
        raise ValueError("`Scene.shape` must be `Free()` or `Prescribed(q_of_t)`.")
    raise ValueError("`Scene.base` must be `FloatingBase()` or `PrescribedBase(g_of_t)`.")
