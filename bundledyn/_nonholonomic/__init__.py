r"""Nonholonomic systems in Lagrangian coordinates (seed 001, §54–§60).

A system given by its kinetic energy $T(q, \dot q, t)$, its active forces and kinematic
constraints, either as Pfaffian rows (76) or in the parametric form (77); Maggi's equations
(82) and Appell's (§60) assembled by autodiff and solved for the rates of the kinematic
characteristics; the split of Maggi's equations into nonholonomic and holonomic terms
((84)–(93)); a diffrax term on $(q, e)$; the Chaplygin sleigh, the vertical rolling disc and the Whipple bicycle; the surfaces a rigid body rolls on a plane
with (`RollingMode`).
"""

from ._appell import (
    acceleration_energy,
    appell_accelerations,
    appell_body_rates,
    body_acceleration_energy,
)
from ._bicycle import Placement, WhippleBicycle
from ._body_motion import BodyMotion
from ._constraints import (
    AbstractKinematicConstraints,
    constrained_accelerations,
    constrained_velocities,
    kinematic_characteristics,
)
from ._contact import (
    AbstractContactSurface,
    DiscContact,
    EllipsoidContact,
    PointContact,
    SphereContact,
    TorusContact,
    contact_twist,
)
from ._covariants import bilinear_covariants
from ._equations import AbstractNonholonomicEquations, AppellEquations, MaggiEquations
from ._holonomic import HolonomicConstraints
from ._linearize import linearization, stability_boundary
from ._maggi import (
    characteristic_forces,
    lagrange_binomials,
    maggi_accelerations,
    maggi_body_rates,
    maggi_equations,
)
from ._mjcf_contact import contact_surface_from_mjcf
from ._parametric import ParametricConstraints
from ._pfaffian import PfaffianConstraints
from ._rolling_disc import RollingDisc
from ._sleigh import ChaplyginSleigh
from ._split import holonomic_terms, nonholonomic_terms
from ._system import AbstractNonholonomicSystem, NonholonomicSystem, mechanical_energy
from ._term import NonholonomicTerm

__all__ = [
    "AbstractContactSurface",
    "AbstractKinematicConstraints",
    "AbstractNonholonomicEquations",
    "AbstractNonholonomicSystem",
    "BodyMotion",
    "AppellEquations",
    "ChaplyginSleigh",
    "DiscContact",
    "EllipsoidContact",
    "HolonomicConstraints",
    "PointContact",
    "MaggiEquations",
    "NonholonomicSystem",
    "NonholonomicTerm",
    "ParametricConstraints",
    "PfaffianConstraints",
    "RollingDisc",
    "SphereContact",
    "TorusContact",
    "WhippleBicycle",
    "Placement",
    "acceleration_energy",
    "appell_accelerations",
    "appell_body_rates",
    "body_acceleration_energy",
    "bilinear_covariants",
    "characteristic_forces",
    "constrained_accelerations",
    "constrained_velocities",
    "contact_surface_from_mjcf",
    "contact_twist",
    "holonomic_terms",
    "kinematic_characteristics",
    "lagrange_binomials",
    "linearization",
    "maggi_accelerations",
    "maggi_body_rates",
    "maggi_equations",
    "mechanical_energy",
    "nonholonomic_terms",
    "stability_boundary",
]
