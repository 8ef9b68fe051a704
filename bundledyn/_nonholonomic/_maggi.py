r"""Maggi's equations (82) of seed 001, assembled by autodiff from the kinetic energy."""

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .. import lie
from .._linalg import spd_solve
from ._body_motion import BodyMotion
from ._constraints import as_time, motion
from ._system import AbstractNonholonomicSystem


def lagrange_binomials(
    system: AbstractNonholonomicSystem,
    q: Float[Array, " n"],
    qdot: Float[Array, " n"],
    qddot: Float[Array, " n"],
    t,
) -> Float[Array, " n"]:
    r"""Lagrange's binomials $\tau_h = \frac{d}{dt}\frac{\partial T}{\partial\dot q_h} - \frac{\partial T}{\partial q_h}$ (38), (42).

    $\frac{d}{dt}\partial T/\partial\dot q$ is one forward-mode derivative of
    $\partial T/\partial\dot q$ along $(\dot q, \ddot q, 1)$ in $(q, \dot q, t)$; no derivative
    is written by hand. They hold whether or not the $\dot q$ obey the constraints (§55).

    **Arguments:**

    - `system`: an `AbstractNonholonomicSystem`.
    - `q`, `qdot`, `qddot`: coordinates, velocities, accelerations, shape `(n,)`.
    - `t`: the time.

    **Returns:**

    $\tau$, shape `(n,)`.
    """
    t = as_time(t, q)
    momenta = jax.grad(system.kinetic_energy, argnums=1)
    _, rate = jax.jvp(momenta, (q, qdot, t), (qdot, qddot, jnp.ones_like(t)))
    return rate - jax.grad(system.kinetic_energy, argnums=0)(q, qdot, t)


def characteristic_forces(
    system: AbstractNonholonomicSystem, q: Float[Array, " n"], e: Float[Array, " nu"], t
) -> Float[Array, " nu"]:
    r"""The active forces along the characteristics, $\Phi_\alpha = \sum_h \eta_{h\alpha} Q_h$ (81).

    They are the coefficients of $\delta\varepsilon_\alpha$ in the virtual work
    $\delta L = \sum_\alpha \Phi_\alpha\,\delta\varepsilon_\alpha$ (§55), the right-hand sides of
    Maggi's (82) and Appell's equations.

    **Arguments:**

    - `system`: an `AbstractNonholonomicSystem`.
    - `q`: the coordinates, shape `(n,)`; `e`: the characteristics, shape `(nu,)`.
    - `t`: the time.

    **Returns:**

    $\Phi$, shape `(nu,)`.
    """
    t = as_time(t, q)
    eta, eta0 = system.constraints.parametric_form(q, t)
    return eta.T @ system.generalized_forces(q, eta @ e + eta0, t)


def maggi_equations(
    system: AbstractNonholonomicSystem,
    q: Float[Array, " n"],
    e: Float[Array, " nu"],
    edot: Float[Array, " nu"],
    t,
) -> Float[Array, " nu"]:
    r"""The residual of Maggi's equations (82), $\sum_h \eta_{h\alpha}\,\tau_h - \Phi_\alpha$.

    $\tau_h$ are Lagrange's binomials (42) at $\dot q = \eta e + \eta_0$ (77) and
    $\ddot q = \frac{d}{dt}(\eta e + \eta_0)$, which is linear in $\dot e$
    (`constrained_accelerations`); $\Phi_\alpha$ as (81). Zero on the motions
    of the system.

    **Arguments:**

    - `system`: an `AbstractNonholonomicSystem`.
    - `q`: the coordinates, shape `(n,)`.
    - `e`, `edot`: the characteristics and their rates, shape `(nu,)`.
    - `t`: the time.

    **Returns:**

    The residual, shape `(nu,)`; affine in `edot`.
    """
    t = as_time(t, q)
    eta, qdot, drift = motion(system.constraints, q, e, t)
    binomials = lagrange_binomials(system, q, qdot, eta @ edot + drift, t)
    return eta.T @ (binomials - system.generalized_forces(q, qdot, t))


def maggi_accelerations(
    system: AbstractNonholonomicSystem, q: Float[Array, " n"], e: Float[Array, " nu"], t
) -> Float[Array, " nu"]:
    r"""The rates $\dot e$ that solve Maggi's equations (82) at $(q, e, t)$.

    The residual (`maggi_equations`) is affine in $\dot e$ (§55: the $\dot e$ enter
    linearly), $r(\dot e) = r(0) + \eta^T M \eta\,\dot e$ with $M = \partial^2T/\partial\dot q^2$;
    it is linearized once at $\dot e = 0$ and its $\nu\times\nu$ matrix $\eta^TM\eta$ (positive
    definite for a positive definite $T$ and independent columns of $\eta$) read off the
    linear map, then $\dot e = -(\eta^TM\eta)^{-1}\,r(0)$ by Cholesky.

    **Arguments:**

    - `system`: an `AbstractNonholonomicSystem`.
    - `q`: the coordinates, shape `(n,)`; `e`: the characteristics, shape `(nu,)`.
    - `t`: the time.

    **Returns:**

    $\dot e$, shape `(nu,)`.
    """
    t = as_time(t, q)
    residual, linear = jax.linearize(
        lambda edot: maggi_equations(system, q, e, edot, t), jnp.zeros_like(e)
    )
    matrix = jax.vmap(linear, out_axes=1)(jnp.eye(e.shape[0], dtype=e.dtype))
    return spd_solve(matrix, -residual)


def maggi_body_rates(body: BodyMotion) -> Float[Array, " nu"]:
    r"""Maggi's equations (82) for a rigid body whose body twist is $\xi = He$: the rates $\dot e$.

    With the body twist as the quasi-velocities, whose kinetic terms are those of (2.7) of
    seed 004, $H^T\big(I\dot\xi + \operatorname{ad}^*_\xi I\xi - F\big) = 0$ with
    $\dot\xi = H\dot e + \dot H e$, solved by Cholesky:
    $\dot e = (H^TIH)^{-1}H^T\big(F - \operatorname{ad}^*_\xi I\xi - I\dot He\big)$.

    **Arguments:**

    - `body`: a `BodyMotion` ($H$, $\dot He$, $\xi$, $I$, $F$).

    **Returns:**

    $\dot e$, shape `(nu,)`.
    """
    H, inertia = body.H, body.inertia
    rhs = body.wrench - lie.coad_action(body.xi, inertia @ body.xi) - inertia @ body.H_dot_e
    return spd_solve(H.T @ inertia @ H, H.T @ rhs)
