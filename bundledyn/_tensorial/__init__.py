r"""Tensorial Lagrange equations (seed 000, §3–§4): scalars, unit vectors and rotation tensors
as generalized coordinates, the equations (44) by autodiff, their diffrax term and the RKMK
methods that keep unit vectors and rotations on their manifolds.
"""

from ._coordinates import TensorCoordinates, TensorVelocities, accelerations_of, projected, rates_of
from ._equations import (
    lagrange_bracket,
    tensorial_accelerations,
    tensorial_equations,
)
from ._gyroscopes import LagrangeGyroscopeChain
from ._solver import (
    AbstractTensorialRKMK,
    TensorialInterpolation,
    TensorialRKMK4,
    TensorialRKMK54,
    TensorialRKMK87,
)
from ._system import AbstractTensorialSystem, TensorialSystem, generalized_forces_at_points
from ._term import TensorialTerm

__all__ = [
    "AbstractTensorialRKMK",
    "AbstractTensorialSystem",
    "LagrangeGyroscopeChain",
    "TensorCoordinates",
    "TensorialInterpolation",
    "TensorialRKMK4",
    "TensorialRKMK54",
    "TensorialRKMK87",
    "TensorialSystem",
    "TensorialTerm",
    "TensorVelocities",
    "accelerations_of",
    "generalized_forces_at_points",
    "lagrange_bracket",
    "projected",
    "rates_of",
    "tensorial_accelerations",
    "tensorial_equations",
]
