r"""Parameter identification: fit inertial parameters to measured motion, and say what the data determine.

A researcher has measured the motion of a floating system (a satellite with an arm, a
thrown object, a robot in flight) and wants its masses, centres of mass, inertias and joint
constants:

```python
import bundledyn as bd
from bundledyn import identify

parameters = identify.Parameters(bd.Scene(nominal_system))          # what is fitted
data = identify.Measurements.from_mujoco(system, ts, qpos, qvel, noise=identify.Noise(...))
torques = identify.Inputs(ts, joint_forces=tau)                     # known inputs
result = identify.fit(parameters, data, inputs=torques, gauge=identify.MeasuredInputs())
print(result.report())          # base parameters with 95 % intervals, what is undetermined
```

Each body's ten inertial parameters are its 4×4 pseudo-inertia (`pseudo_inertia`), fitted
through its log-Cholesky coordinates (`log_cholesky_from_pseudo_inertia`), so that every
iterate is a physical body (Rucker & Wensing 2022). The fit starts from the equation error
of momentum and energy (`warm_start`), refines the output error by multiple shooting
(`Windows`) with exact forward-mode Jacobians and Levenberg–Marquardt, and reports the
identifiability of the solution: what the data determine (the base parameters: the
combinations of each body's standard parameters that no blind direction moves), with
standard errors, and the combinations they cannot (the mass scale without a `gauge`, mass a joint carries alike on
its two bodies, directions the motion did not excite), in physical terms.
"""

from ._identify._base_parameters import (
    BaseParameter,
    standard_parameter_names,
    standard_parameters,
)
from ._identify._data import Inputs, Measurements, Noise, body_frame_velocity_noise
from ._identify._fit import FitResult, fit
from ._identify._gauge import AbstractGauge, KnownBodies, KnownMass, MeasuredInputs
from ._identify._identifiability import Estimate, Identifiability
from ._identify._parameters import Parameters
from ._identify._regressor import warm_start
from ._identify._shooting import Windows
from ._systems._pseudo_inertia import (
    inertial_from_pseudo_inertia,
    log_cholesky_from_pseudo_inertia,
    pseudo_inertia,
    pseudo_inertia_from_log_cholesky,
)

__all__ = [
    "AbstractGauge",
    "BaseParameter",
    "Estimate",
    "FitResult",
    "Identifiability",
    "Inputs",
    "KnownBodies",
    "KnownMass",
    "Measurements",
    "MeasuredInputs",
    "Noise",
    "Parameters",
    "Windows",
    "body_frame_velocity_noise",
    "fit",
    "inertial_from_pseudo_inertia",
    "log_cholesky_from_pseudo_inertia",
    "pseudo_inertia",
    "pseudo_inertia_from_log_cholesky",
    "standard_parameter_names",
    "standard_parameters",
    "warm_start",
]
