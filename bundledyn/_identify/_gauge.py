r"""The gauge of an identification: what fixes the scale that motion alone cannot.

Multiplying every mass and inertia of a system by the same factor leaves its free motion
unchanged (the equations (2.6)–(2.7) are homogeneous in the metric), so with no measured
force the overall mass scale is not in the data; in uniform gravity in free flight it is not
either (Theorem 3.4: gravity disappears in a falling frame). A fit must say what fixes it:
a known mass, a body whose parameters are known, or measured forces (joint torques,
wrenches), whose work the motion shows.
"""

import abc

import equinox as eqx
import jax
import jax.numpy as jnp

from ._data import Inputs, Level, level
from ._parameters import Parameters

__all__ = ["AbstractGauge", "KnownBodies", "KnownMass", "MeasuredInputs"]

# The standard deviation of a known mass's pseudo-measurement, relative to the mass.
_KNOWN = 1e-9


class AbstractGauge(eqx.Module):
    """What fixes the mass scale of an identification."""

    @abc.abstractmethod
    def check(self, parameters: Parameters, inputs: Inputs | None) -> None:
        """Raise `ValueError` if this gauge cannot fix the scale of this problem."""

    @abc.abstractmethod
    def mass_rows(self, parameters: Parameters, masses) -> jax.Array:
        """The gauge's pseudo-measurement residuals given the free bodies' masses `(k,)`
        (possibly none)."""

    def residuals(self, parameters: Parameters, theta) -> jax.Array:
        r"""The gauge's pseudo-measurement residuals at $\theta$ (possibly none)."""
        return self.mass_rows(parameters, parameters.pseudo_inertias(theta)[:, 3, 3])

    @abc.abstractmethod
    def describe(self, parameters: Parameters) -> str:
        """One line for the report."""


class KnownMass(AbstractGauge):
    """A known mass: the system's total mass, or one body's.

    **Arguments:**

    - `value`: the mass.
    - `body`: the body, by index or name (static); `None` for the total mass.
    """

    value: Level = eqx.field(converter=level)
    body: int | str | None = eqx.field(static=True, default=None)

    def _index(self, parameters):
        names = parameters.body_names
        if isinstance(self.body, str):
            if self.body not in names:
                raise ValueError(f"`KnownMass.body` names {self.body!r}, not a body of {names}.")
            return names.index(self.body)
        return self.body

    def check(self, parameters, inputs):
        if not self.value > 0:
            raise ValueError(f"`KnownMass.value` must be positive, got {self.value}.")
        index = self._index(parameters)
        if index is not None and index not in parameters.bodies:
            raise ValueError(f"body {self.body!r} is not free: its mass is already known.")

    def mass_rows(self, parameters, masses):
        P = parameters.system.pseudo_inertias()
        masses = P[:, 3, 3].at[jnp.array(parameters.bodies)].set(masses)
        index = self._index(parameters)
        mass = jnp.sum(masses) if index is None else masses[index]
        return jnp.atleast_1d((mass - self.value) / (_KNOWN * self.value))

    def describe(self, parameters):
        what = "the total mass" if self.body is None else f"the mass of body {self.body!r}"
        return f"{what} is known: {self.value:g}"


class KnownBodies(AbstractGauge):
    """Bodies whose inertial parameters are known (held at their nominal values): an arm or
    wheel of known make, a calibrated base. Leave them out of `Parameters.bodies`."""

    def check(self, parameters, inputs):
        if len(parameters.bodies) == parameters.system.pseudo_inertias().shape[0]:
            raise ValueError(
                "`KnownBodies` gauge: every body is free in `Parameters`; leave the known "
                "bodies out of `Parameters(bodies=...)`."
            )

    def mass_rows(self, parameters, masses):
        return jnp.zeros((0,), masses.dtype)

    def describe(self, parameters):
        n = parameters.system.pseudo_inertias().shape[0]
        known = [b for b in range(n) if b not in parameters.bodies]
        return f"bodies {known} have known inertial parameters"


class MeasuredInputs(AbstractGauge):
    """Measured forces (joint torques, wrenches): their work fixes the scale."""

    def check(self, parameters, inputs):
        if inputs is None or (inputs.joint_forces is None and inputs.wrenches is None):
            raise ValueError(
                "`MeasuredInputs` gauge without measured inputs: with no force measured the "
                "mass scale is not in the data; give `Inputs`, or use `KnownMass` or "
                "`KnownBodies`."
            )

    def mass_rows(self, parameters, masses):
        return jnp.zeros((0,), masses.dtype)

    def describe(self, parameters):
        return "measured inputs (the work of the known forces) fix the mass scale"
