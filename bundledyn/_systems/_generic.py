"""A system given by a user's kinetic energy, for research metrics."""

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp

from ._base import AbstractSystem, autodiff_metric_jet


class GenericSystem(AbstractSystem):
    r"""A system defined by its kinetic energy $T(q, \dot q, \xi)$, quadratic in the velocities.

    The metric is the Hessian of $T$ in $(\xi, \dot q)$, by autodiff. Make
    `kinetic_energy` an `equinox.Module` (or close over arrays) to differentiate with
    respect to its parameters.

    **Arguments:**

    - `kinetic_energy`: `T(q, qdot, xi) -> scalar` with `q, qdot` of shape `(d,)` and `xi` of
      shape `(6,)` (angular first), invariant under the left action of SE(3).
    - `shape_dim`: $d$ (static).
    """

    kinetic_energy: Callable
    _shape_dim: int = eqx.field(static=True)

    def __init__(self, kinetic_energy, shape_dim):
        if not callable(kinetic_energy):
            raise ValueError("`GenericSystem.kinetic_energy` must be a callable T(q, qdot, xi).")
        if int(shape_dim) < 0:
            raise ValueError(f"`GenericSystem.shape_dim` must be >= 0, got {shape_dim}.")
        self.kinetic_energy = kinetic_energy
        self._shape_dim = int(shape_dim)

    @property
    def shape_dim(self) -> int:
        return self._shape_dim

    def metric(self, q):
        d = self.shape_dim

        def energy(velocity):
            return self.kinetic_energy(q, velocity[6:], velocity[:6])

        return jax.hessian(energy)(jnp.zeros(6 + d, q.dtype))

    def metric_jet(self, q):
        return autodiff_metric_jet(self, q)

    def checked(self) -> "GenericSystem":
        """The system itself: a user's kinetic energy has no parameters of bundledyn's to
        check (that it is positive definite is the function's to ensure)."""
        return self
