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
from ._paths import models, scenes
from ._precision import enable_x64
from ._scene import FloatingBase, Free, Prescribed, PrescribedBase, Scene
from ._scene_file import SceneFile, SceneFileError, load_scene, load_system
from ._simulate import project_to_se3, simulate
from ._solids import AbstractSolid, Box, Capsule, Ellipsoid
from ._solver._adjoint import StoredStepsAdjoint
from ._solver._base import AbstractLieGroupSolver
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
from ._term import AbstractBodyTerm, SceneTerm
from ._trajectory import Trajectory
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
    "AbstractMetricJet",
    "AbstractMultibody",
    "AbstractPotential",
    "AbstractRKMK",
    "AbstractSolid",
    "AbstractSystem",
    "AffineBody",
    "BodywiseGravityGradient",
    "Boosted",
    "Box",
    "bundle_geometry",
    "BundleGeometry",
    "Capsule",
    "checks",
    "coadjoint_term",
    "Composite",
    "connection",
    "CPU_XLA_FLAGS",
    "curvature",
    "curvature_by_holonomy",
    "curvature_from_connection",
    "curvature_term",
    "DenseMetricJet",
    "driven_shape_acceleration",
    "driven_shape_force",
    "Ellipsoid",
    "enable_x64",
    "ExternalWrench",
    "Fixed",
    "FixedTendon",
    "FloatingBase",
    "frame_transport_term",
    "Free",
    "FreeFalling",
    "GenericSystem",
    "Gravity",
    "GravityGradient",
    "horizontal_lift",
    "IdentificationFile",
    "identify",
    "inertia_covariant_derivative",
    "Kinematics",
    "kinetic_covariant_derivative",
    "kinetic_energy",
    "levi_civita_term",
    "lie",
    "LieButcherTableau",
    "LieEuler",
    "Link",
    "load_scene",
    "load_system",
    "locked_acceleration",
    "locked_inertia",
    "locked_velocity",
    "mass_and_centre",
    "metric",
    "ModelParts",
    "models",
    "MovingFrame",
    "Multibody",
    "parts_from_mjcf",
    "parts_from_urdf",
    "Prescribed",
    "PrescribedBase",
    "Prismatic",
    "project_to_se3",
    "reference_accelerations",
    "Resectioned",
    "Revolute",
    "RigidBody",
    "RKMK4",
    "RKMK54",
    "RKMK87",
    "Scene",
    "SceneFile",
    "SceneFileError",
    "scenes",
    "SceneTerm",
    "shape_acceleration",
    "shape_metric",
    "ShapeDamper",
    "ShapeForce",
    "ShapePotential",
    "ShapeSpring",
    "simulate",
    "spatial_inertia",
    "Spherical",
    "square_loop_holonomy",
    "State",
    "stress",
    "state_from_mujoco",
    "state_to_mujoco",
    "StoredStepsAdjoint",
    "Trajectory",
    "Universal",
    "use_cpu_xla_flags",
    "VariationalMidpoint",
]
