r"""Parameter identification: fit bodies' inertial parameters to measured motion.

Each body's ten inertial parameters are its 4×4 pseudo-inertia (`pseudo_inertia`), and
its log-Cholesky coordinates (`log_cholesky_from_pseudo_inertia`) make every real
10-vector a physical body (Rucker & Wensing 2022).
"""

from ._systems._pseudo_inertia import (
    inertial_from_pseudo_inertia,
    log_cholesky_from_pseudo_inertia,
    pseudo_inertia,
    pseudo_inertia_from_log_cholesky,
)

__all__ = [
    "inertial_from_pseudo_inertia",
    "log_cholesky_from_pseudo_inertia",
    "pseudo_inertia",
    "pseudo_inertia_from_log_cholesky",
]
