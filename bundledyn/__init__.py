"""bundledyn: differentiable dynamics on principal SE(3) bundles (Chevallier's equations) in JAX."""

from . import lie
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
from ._precision import enable_x64
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

__version__ = "0.1.0"

__all__ = [
    "AbstractJoint",
    "AbstractSystem",
    "AffineBody",
    "Composite",
    "Fixed",
    "GenericSystem",
    "Link",
    "Multibody",
    "Prismatic",
    "Revolute",
    "RigidBody",
    "Spherical",
    "Universal",
    "connection",
    "curvature",
    "curvature_from_connection",
    "enable_x64",
    "kinetic_energy",
    "lie",
    "locked_inertia",
    "locked_velocity",
    "metric",
    "shape_metric",
    "spatial_inertia",
]
