"""bundledyn: differentiable dynamics on principal SE(3) bundles (Chevallier's equations) in JAX."""

import pathlib

from . import checks, lie
from ._dynamics import (
    BundleGeometry,
    bundle_geometry,
    coadjoint_term,
    curvature_term,
    frame_transport_term,
    inertia_covariant_derivative,
    kinetic_covariant_derivative,
    levi_civita_term,
    locked_acceleration,
    reference_accelerations,
    shape_acceleration,
)
from ._effects import (
    AbstractEffect,
    AbstractPotential,
    ExternalWrench,
    Gravity,
    GravityGradient,
    Kinematics,
    ShapeDamper,
    ShapeForce,
    ShapePotential,
    ShapeSpring,
    mass_and_centre,
)
from ._frames import AbstractFrame, Boosted, FreeFalling, MovingFrame
from ._geometry import (
    connection,
    curvature,
    curvature_from_connection,
    kinetic_energy,
    locked_inertia,
    locked_velocity,
    metric,
    shape_metric,
)
from ._holonomy import curvature_by_holonomy, horizontal_lift, square_loop_holonomy
from ._precision import enable_x64
from ._scene import Free, Prescribed, Scene
from ._scene_file import SceneFile, SceneFileError, load_system
from ._simulate import project_to_se3, simulate
from ._solids import AbstractSolid, Box, Capsule, Ellipsoid
from ._solver._lie_euler import LieEuler
from ._solver._rkmk import RKMK4, RKMK54, RKMK87
from ._solver._variational import VariationalMidpoint
from ._state import State
from ._systems._affine_body import AffineBody
from ._systems._base import AbstractSystem
from ._systems._generic import GenericSystem
from ._systems._joints import (
    AbstractJoint,
    Composite,
    Fixed,
    Prismatic,
    Revolute,
    Spherical,
    Universal,
)
from ._systems._multibody import Link, Multibody
from ._systems._rigid_body import RigidBody, spatial_inertia
from ._trajectory import Trajectory
from ._xla_flags import CPU_XLA_FLAGS, use_cpu_xla_flags

__version__ = "0.1.0"

#: Folder of the example models shipped with the package (MJCF and URDF).
models = pathlib.Path(__file__).parent / "models"
#: Folder of the example scene files shipped with the package (TOML, see `SceneFile`).
scenes = pathlib.Path(__file__).parent / "scenes"

__all__ = [
    "AbstractEffect",
    "AbstractFrame",
    "AbstractJoint",
    "AbstractPotential",
    "AbstractSolid",
    "AbstractSystem",
    "CPU_XLA_FLAGS",
    "AffineBody",
    "Boosted",
    "Box",
    "Capsule",
    "BundleGeometry",
    "Composite",
    "Ellipsoid",
    "ExternalWrench",
    "Fixed",
    "Free",
    "FreeFalling",
    "GenericSystem",
    "Gravity",
    "GravityGradient",
    "Kinematics",
    "LieEuler",
    "Link",
    "MovingFrame",
    "Multibody",
    "Prescribed",
    "Prismatic",
    "RKMK4",
    "RKMK54",
    "RKMK87",
    "Revolute",
    "RigidBody",
    "Scene",
    "SceneFile",
    "SceneFileError",
    "ShapeDamper",
    "ShapeForce",
    "ShapePotential",
    "ShapeSpring",
    "Spherical",
    "State",
    "Trajectory",
    "Universal",
    "VariationalMidpoint",
    "bundle_geometry",
    "checks",
    "coadjoint_term",
    "connection",
    "curvature",
    "curvature_by_holonomy",
    "curvature_from_connection",
    "curvature_term",
    "enable_x64",
    "use_cpu_xla_flags",
    "frame_transport_term",
    "horizontal_lift",
    "inertia_covariant_derivative",
    "kinetic_covariant_derivative",
    "kinetic_energy",
    "levi_civita_term",
    "load_system",
    "lie",
    "locked_acceleration",
    "locked_inertia",
    "locked_velocity",
    "mass_and_centre",
    "metric",
    "models",
    "project_to_se3",
    "reference_accelerations",
    "scenes",
    "shape_acceleration",
    "shape_metric",
    "simulate",
    "spatial_inertia",
    "square_loop_holonomy",
]
