r"""A mechanical system with kinematic constraints in Lagrangian coordinates (seed 001, §54–§55)."""

import abc
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._constraints import AbstractKinematicConstraints, as_time


class AbstractNonholonomicSystem(eqx.Module):
    r"""A system in Lagrangian coordinates $q$ with ideal kinematic constraints (seed 001, §54–§55).

    It is known by its kinetic energy $T(q, \dot q, t)$, the generalized forces $Q_h$ of the
    active forces (§55), and its constraints, read in the parametric form (77)
    $\dot q = \eta(q, t)\,e + \eta_0(q, t)$. Its state is $(q, e)$: the configuration and the
    kinematic characteristics. Subclasses give `kinetic_energy`, `potential_energy`,
    `generalized_forces` and `constraints`.
    """

    constraints: eqx.AbstractVar[AbstractKinematicConstraints]

    @abc.abstractmethod
    def kinetic_energy(
        self, q: Float[Array, " n"], qdot: Float[Array, " n"], t
    ) -> Float[Array, ""]:
        r"""The kinetic energy $T(q, \dot q, t)$ (the seed's *живая сила*), a scalar.

        **Arguments:**

        - `q`, `qdot`: coordinates and velocities, shape `(n,)`; `t`: the time.
        """

    @abc.abstractmethod
    def potential_energy(self, q: Float[Array, " n"], t) -> Float[Array, ""]:
        r"""The potential $\Pi(q, t)$ of the conservative part of the active forces, a scalar
        (zero for a system without one); `mechanical_energy` adds it.

        **Arguments:**

        - `q`: the coordinates, shape `(n,)`; `t`: the time.
        """

    @abc.abstractmethod
    def generalized_forces(
        self, q: Float[Array, " n"], qdot: Float[Array, " n"], t
    ) -> Float[Array, " n"]:
        r"""The generalized forces $Q_h = \sum_i F_i\cdot\partial P_i/\partial q_h$ (§55) of all
        active forces, the potential's $-\partial\Pi/\partial q$ included.

        **Arguments:**

        - `q`, `qdot`: coordinates and velocities, shape `(n,)`; `t`: the time.

        **Returns:**

        $Q$, shape `(n,)`.
        """


def mechanical_energy(
    system: AbstractNonholonomicSystem, q: Float[Array, " n"], qdot: Float[Array, " n"], t
) -> Float[Array, ""]:
    r"""The mechanical energy $T + \Pi$ of `system`: conserved when $T$ is a quadratic form in
    $\dot q$, and $T$, the constraints and the potential do not depend on time, and no other
    forces act (§56).

    **Arguments:**

    - `system`: an `AbstractNonholonomicSystem`.
    - `q`, `qdot`: coordinates and velocities, shape `(n,)`; `t`: the time.

    **Returns:**

    $T + \Pi$, a scalar.
    """
    t = as_time(t, q)
    return system.kinetic_energy(q, qdot, t) + system.potential_energy(q, t)


class NonholonomicSystem(AbstractNonholonomicSystem):
    r"""A nonholonomic system given by functions: $T(q, \dot q, t)$, $\Pi(q, t)$, $Q(q, \dot q, t)$.

    The active forces are $Q_h = -\partial\Pi/\partial q_h + Q_h^{\rm other}$, the gradient by
    autodiff; a potential or force not given is absent (nothing of it is compiled).

    ```python
    sleigh_on_a_slope = bd.NonholonomicSystem(
        T=lambda q, qdot, t: 0.5 * m * (qdot[0]**2 + qdot[1]**2) + 0.5 * I * qdot[2]**2,
        constraints=bd.PfaffianConstraints(
            lambda q, t: jnp.array([[-jnp.sin(q[2]), jnp.cos(q[2]), -a]]), independent=(0, 1)),
        Pi=lambda q, t: m * g * jnp.sin(slope) * q[0],
    )
    ```

    **Arguments:**

    - `T`: the kinetic energy `T(q, qdot, t) -> scalar`.
    - `constraints`: an `AbstractKinematicConstraints` (`PfaffianConstraints`,
      `ParametricConstraints`).
    - `Pi`: the potential `Pi(q, t) -> scalar`, or `None`.
    - `Q`: other generalized forces `Q(q, qdot, t) -> (n,)` (dampers, drives), or `None`.

    Make the functions `equinox.Module`s (or close over arrays) to differentiate with
    respect to their parameters.
    """

    T: Callable
    constraints: AbstractKinematicConstraints
    Pi: Callable | None = None
    Q: Callable | None = None

    def __check_init__(self):
        if not callable(self.T):
            raise ValueError("`NonholonomicSystem.T` must be a callable T(q, qdot, t) -> scalar.")
        if not isinstance(self.constraints, AbstractKinematicConstraints):
            raise ValueError(
                "`NonholonomicSystem.constraints` must be an AbstractKinematicConstraints, e.g. "
                "`PfaffianConstraints(b, independent)` or `ParametricConstraints(eta)`; got "
                f"{type(self.constraints).__name__}."
            )
        for name, value, signature in (("Pi", self.Pi, "Pi(q, t)"), ("Q", self.Q, "Q(q, qdot, t)")):
            if value is not None and not callable(value):
                raise ValueError(
                    f"`NonholonomicSystem.{name}` must be a callable {signature}, or None."
                )

    def kinetic_energy(self, q, qdot, t):
        return self.T(q, qdot, as_time(t, q))

    def potential_energy(self, q, t):
        if self.Pi is None:
            return jnp.zeros((), q.dtype)
        return self.Pi(q, as_time(t, q))

    def generalized_forces(self, q, qdot, t):
        t = as_time(t, q)
        forces = jnp.zeros_like(q)
        if self.Pi is not None:
            forces = forces - jax.grad(self.Pi)(q, t)
        if self.Q is not None:
            forces = forces + self.Q(q, qdot, t)
        return forces
