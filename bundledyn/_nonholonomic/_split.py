r"""Maggi's equations split into nonholonomic and holonomic terms, $A_\alpha + Q_\alpha = \Phi_\alpha$ (91)."""

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._constraints import as_time, constrained_velocities
from ._system import AbstractNonholonomicSystem


def nonholonomic_terms(
    system: AbstractNonholonomicSystem, q: Float[Array, " n"], e: Float[Array, " nu"], t
) -> Float[Array, " nu"]:
    r"""The nonholonomic terms $A_\alpha$ (89) of Maggi's equations (seed 001, §58).

    $$ A_\alpha = \sum_{h=1}^n \frac{\partial T}{\partial\dot q_h}\Big\{\sum_{j=1}^n
       \frac{\partial\dot q_h}{\partial q_j}\frac{\partial\dot q_j}{\partial e_\alpha}
       - \frac{d}{dt}\frac{\partial\dot q_h}{\partial e_\alpha}\Big\} \qquad (89) $$

    with $\dot q(q, e, t)$ from (77), $\partial\dot q_j/\partial e_\alpha = \eta_{j\alpha}$ and
    $\frac{d}{dt}\eta_{h\alpha}$ along the motion; equivalently
    $A_\alpha = \sum_h \frac{\partial T}{\partial\dot q_h}\varphi_{h\alpha}$ (93) with
    $\varphi_{h\alpha} = \eta_{h|0\alpha} + \sum_\beta\eta_{h|\beta\alpha}e_\beta$ (87) from the
    bilinear covariants (84). They depend on $(q, e, t)$ only, vanish identically when the
    constraints are holonomic and the characteristics holonomic (§58), and, for
    constraints that do not depend on time, do no work: $\sum_\alpha A_\alpha e_\alpha = 0$
    ((94), §59: they are gyroscopic). Both derivatives are forward-mode products of (77), from one linearization of it.

    **Arguments:**

    - `system`: an `AbstractNonholonomicSystem`.
    - `q`: the coordinates, shape `(n,)`; `e`: the characteristics, shape `(nu,)`.
    - `t`: the time.

    **Returns:**

    $A$, shape `(nu,)`.
    """
    t = as_time(t, q)

    def coefficients_and_velocities(q, t):
        eta, eta0 = system.constraints.parametric_form(q, t)
        return eta, eta @ e + eta0

    (eta, qdot), linear = jax.linearize(coefficients_and_velocities, q, t)
    momenta = jax.grad(system.kinetic_energy, argnums=1)(q, qdot, t)
    # sum_j (d qdot_h / d q_j) eta_{j alpha}: the velocities' derivative along each column
    along_columns = jax.vmap(lambda c: linear(c, jnp.zeros_like(t))[1], in_axes=1, out_axes=1)(eta)
    eta_rate = linear(qdot, jnp.ones_like(t))[0]  # d eta / dt along the motion
    return momenta @ (along_columns - eta_rate)


def holonomic_terms(
    system: AbstractNonholonomicSystem,
    q: Float[Array, " n"],
    e: Float[Array, " nu"],
    edot: Float[Array, " nu"],
    t,
) -> Float[Array, " nu"]:
    r"""The holonomic terms $Q_\alpha$ (90) of Maggi's equations (seed 001, §58).

    $$ Q_\alpha = \frac{d}{dt}\frac{\partial T^*}{\partial e_\alpha}
       - \sum_{h=1}^n\frac{\partial\dot q_h}{\partial e_\alpha}\frac{\partial T^*}{\partial q_h}
       \qquad (90) $$

    with $T^*(q, e, t) = T(q, \eta e + \eta_0, t)$ the kinetic energy in the characteristics
    (§58) and $\frac{d}{dt}$ along $(\dot q, \dot e, 1)$, one forward-mode derivative. For
    holonomic constraints and characteristics $e = \dot r$ they are Lagrange's binomials in
    the independent coordinates $r$ (§58). With `nonholonomic_terms`, Maggi's equations
    read $A_\alpha + Q_\alpha = \Phi_\alpha$ (91), and $A_\alpha + Q_\alpha =
    \sum_h\eta_{h\alpha}\tau_h$ for any $\dot e$ (88).

    **Arguments:**

    - `system`: an `AbstractNonholonomicSystem`.
    - `q`: the coordinates, shape `(n,)`.
    - `e`, `edot`: the characteristics and their rates, shape `(nu,)`.
    - `t`: the time.

    **Returns:**

    $Q$, shape `(nu,)`; affine in `edot`.
    """
    t = as_time(t, q)
    constraints = system.constraints

    def reduced_energy(q, e, t):  # T*(q, e, t)
        return system.kinetic_energy(q, constrained_velocities(constraints, q, e, t), t)

    eta, eta0 = constraints.parametric_form(q, t)
    qdot = eta @ e + eta0
    _, rate = jax.jvp(
        jax.grad(reduced_energy, argnums=1), (q, e, t), (qdot, edot, jnp.ones_like(t))
    )
    return rate - eta.T @ jax.grad(reduced_energy, argnums=0)(q, e, t)
