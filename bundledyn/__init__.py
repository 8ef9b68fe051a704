"""bundledyn: differentiable dynamics on principal SE(3) bundles (Chevallier's equations) in JAX."""

import importlib.metadata

from . import checks, identify, lie, stress
from ._dynamics import (
    BundleGeometry,
    bundle_geometry,
    coadjoint_term,
    curvature_term,
    driven_shape_acceleration,
    driven_shape_force,
    frame_transport_term,
    inertia_covariant_derivative,
    kinetic_covariant_derivative,
    levi_civita_term,
    locked_acceleration,
    reference_accelerations,
    shape_acceleration,
)
from ._effects import (
    AbstractCentralGravity,
    AbstractEffect,
    AbstractPotential,
    BodywiseGravityGradient,
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
from ._identify_file import IdentificationFile
from ._modes import (
    AbstractMode,
    AbstractWindowChart,
    FloatingBase,
    Free,
    FreeShapeMode,
    Prescribed,
    PrescribedBase,
    PrescribedBaseMode,
    PrescribedShapeMode,
    RigidBodyMode,
)
from ._paths import models, scenes
from ._precision import enable_x64
from ._scene import Scene
from ._scene_file import SceneFile, SceneFileError, load_scene, load_system
from ._simulate import project_to_se3, simulate
from ._solids import AbstractSolid, Box, Capsule, Ellipsoid
from ._solver._adjoint import StoredStepsAdjoint
from ._solver._base import AbstractLieGroupSolver, AbstractStageReplaySolver
from ._solver._lie_euler import LieEuler
from ._solver._rkmk import RKMK4, RKMK54, RKMK87, AbstractRKMK
from ._solver._tableau import LieButcherTableau
from ._solver._variational import VariationalMidpoint
from ._state import State
from ._systems._affine_body import AffineBody
from ._systems._base import AbstractInertialSystem, AbstractSystem
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
from ._systems._link import Link
from ._systems._metric_jet import AbstractMetricJet, DenseMetricJet
from ._systems._mujoco_import import FixedTendon, ModelParts, parts_from_mjcf, parts_from_urdf
from ._systems._mujoco_state import state_from_mujoco, state_to_mujoco
from ._systems._multibody import AbstractMultibody, Multibody, Resectioned
from ._systems._rigid_body import RigidBody, spatial_inertia
from ._term import AbstractBodyTerm, AbstractSceneTerm, SceneTerm
from ._trajectory import Diagnostics, Trajectory
from ._xla_flags import CPU_XLA_FLAGS, use_cpu_xla_flags

__version__ = importlib.metadata.version("bundledyn")

__all__ = [
    "AbstractBodyTerm",
    "AbstractCentralGravity",
    "AbstractEffect",
    "AbstractFrame",
    "AbstractInertialSystem",
    "AbstractJoint",
    "AbstractLieGroupSolver",
    "AbstractStageReplaySolver",
    "AbstractMetricJet",
    "AbstractMode",
    "AbstractMultibody",
    "AbstractPotential",
    "AbstractRKMK",
    "AbstractSceneTerm",
    "AbstractSolid",
    "AbstractSystem",
    "AbstractWindowChart",
    "AffineBody",
    "BodywiseGravityGradient",
    "Boosted",
    "Box",
    "BundleGeometry",
    "CPU_XLA_FLAGS",
    "Capsule",
    "Composite",
    "DenseMetricJet",
    "Diagnostics",
    "Ellipsoid",
    "ExternalWrench",
    "Fixed",
    "FixedTendon",
    "FloatingBase",
    "Free",
    "FreeFalling",
    "FreeShapeMode",
    "GenericSystem",
    "Gravity",
    "GravityGradient",
    "IdentificationFile",
    "Kinematics",
    "LieButcherTableau",
    "LieEuler",
    "Link",
    "ModelParts",
    "MovingFrame",
    "Multibody",
    "Prescribed",
    "PrescribedBase",
    "PrescribedBaseMode",
    "PrescribedShapeMode",
    "Prismatic",
    "RKMK4",
    "RKMK54",
    "RKMK87",
    "Resectioned",
    "Revolute",
    "RigidBody",
    "RigidBodyMode",
    "Scene",
    "SceneFile",
    "SceneFileError",
    "SceneTerm",
    "ShapeDamper",
    "ShapeForce",
    "ShapePotential",
    "ShapeSpring",
    "Spherical",
    "State",
    "StoredStepsAdjoint",
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
    "driven_shape_acceleration",
    "driven_shape_force",
    "enable_x64",
    "frame_transport_term",
    "horizontal_lift",
    "identify",
    "inertia_covariant_derivative",
    "kinetic_covariant_derivative",
    "kinetic_energy",
    "levi_civita_term",
    "lie",
    "load_scene",
    "load_system",
    "locked_acceleration",
    "locked_inertia",
    "locked_velocity",
    "mass_and_centre",
    "metric",
    "models",
    "parts_from_mjcf",
    "parts_from_urdf",
    "project_to_se3",
    "reference_accelerations",
    "scenes",
    "shape_acceleration",
    "shape_metric",
    "simulate",
    "spatial_inertia",
    "square_loop_holonomy",
    "state_from_mujoco",
    "state_to_mujoco",
    "stress",
    "use_cpu_xla_flags",
]
