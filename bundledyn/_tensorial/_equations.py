r"""The tensorial Lagrange equations of the second kind (seed 000, (44)), by autodiff."""

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.flatten_util import ravel_pytree
from jaxtyping import Array

from ._coordinates import (
    TensorCoordinates,
    TensorVelocities,
    accelerations_of,
    projected,
    rates_of,
    zeros_like_velocities,
)
from ._system import AbstractTensorialSystem

__all__ = ["lagrange_bracket", "tensorial_accelerations", "tensorial_equations"]


def _time(t, X: TensorCoordinates) -> Array:
    return jnp.asarray(t, dtype=X.rotations.dtype)


def lagrange_bracket(
    system: AbstractTensorialSystem,
    X: TensorCoordinates,
    Xdot: TensorCoordinates,
    Xddot: TensorCoordinates,
    t,
) -> TensorCoordinates:
    r"""The bracket of (44), $\tfrac{d}{dt}\partial T/\partial\dot X_i - \partial T/\partial X_i - Q_i$.

    $\partial T/\partial\dot X$ and $\partial T/\partial X$ are gradients of $T$ with respect
    to the tensors themselves (a $3\times3$ tensor for $Z$, a vector for $e$), and the time
    derivative is one JVP of $\partial T/\partial\dot X$ along $(\dot X, \ddot X, 1)$.

    **Arguments:**

    - `system`: an `AbstractTensorialSystem`.
    - `X`, `Xdot`, `Xddot`: the coordinates and their first and second rates
      (`TensorCoordinates`).
    - `t`: the time.

    **Returns:**

    The bracket, as `TensorCoordinates` of tensors (not yet projected: its parts along the
    constraints $|e| = 1$, $Z^TZ = 1$ are the reactions').
    """
    t = _time(t, X)
    momentum = jax.grad(system.kinetic_energy, argnums=1)
    _, momentum_rate = jax.jvp(momentum, (X, Xdot, t), (Xdot, Xddot, jnp.ones_like(t)))
    slope = jax.grad(system.kinetic_energy, argnums=0)(X, Xdot, t)
    forces = system.generalized_forces(X, Xdot, t)
    return jax.tree.map(lambda a, b, c: a - b - c, momentum_rate, slope, forces)


def tensorial_equations(
    system: AbstractTensorialSystem,
    X: TensorCoordinates,
    V: TensorVelocities,
    A: TensorVelocities,
    t,
) -> TensorVelocities:
    r"""The left sides of the tensorial Lagrange equations (44), $\tilde X_i \wedge_{\nu_i}[\dots]$.

    One scalar equation per scalar, two per unit vector (with the closing one that fixes
    $\dot\Omega\cdot e$) and three per rotation tensor; zero on the motion.

    **Arguments:**

    - `system`: an `AbstractTensorialSystem`.
    - `X`: the coordinates; `V`: their velocities; `A`: the velocities' rates.
    - `t`: the time.

    **Returns:**

    The projected equations, as `TensorVelocities`.
    """
    bracket = lagrange_bracket(system, X, rates_of(X, V), accelerations_of(X, V, A), t)
    return projected(X, bracket, A)


def tensorial_accelerations(
    system: AbstractTensorialSystem, X: TensorCoordinates, V: TensorVelocities, t
) -> TensorVelocities:
    r"""The velocities' rates $(\ddot q, \dot\Omega, \dot\omega)$ that solve (44).

    The equations are affine in the rates: their value at zero rates and their linear part
    (one `jax.linearize`) give a square system of $m + 3n + 3p$ equations, solved densely.
    Where that system is singular or so ill-conditioned that the rates would keep fewer
    than half the digits of the floating-point type (its condition number, rows and
    columns scaled, above $1/\sqrt{\epsilon}$: $6.7\cdot10^7$ in float64), the rates
    raise (`equinox.error_if`) instead of losing their accuracy silently: coordinates near
    a singular point of their parametrization (the vector parameter near a rotation by
    $\pi$, an axis near the reference vector of (42)) or a kinetic energy that does not
    depend on some rate.

    **Arguments:**

    - `system`: an `AbstractTensorialSystem`.
    - `X`: the coordinates; `V`: their velocities; `t`: the time.

    **Returns:**

    The rates, as `TensorVelocities`.
    """
    at_rates = lambda A: tensorial_equations(system, X, V, A, t)
    residual, linear = jax.linearize(at_rates, zeros_like_velocities(X))
    flat, unflatten = ravel_pytree(residual)
    basis = jnp.eye(flat.shape[0], dtype=flat.dtype)
    columns = jax.vmap(lambda column: ravel_pytree(linear(unflatten(column)))[0])(basis)
    matrix = columns.T
    rates = jnp.linalg.solve(matrix, -flat)
    condition = _equilibrated_condition(jax.lax.stop_gradient(matrix))
    limit = 1.0 / jnp.sqrt(jnp.finfo(flat.dtype).eps)
    rates = eqx.error_if(
        rates,
        ~(condition <= limit) | ~jnp.all(jnp.isfinite(rates)),
        "The tensorial Lagrange equations (44) do not determine the accelerations to half "
        "the digits of the floating-point type here: their matrix is singular or nearly so "
        "(condition number, rows and columns scaled, above 1/sqrt(eps)). The coordinates "
        "are near a singular point of their parametrization (a vector parameter near a "
        "rotation by pi, an axis near its reference vector, a universal joint's axes lined "
        "up), or the kinetic energy does not depend on some coordinate's rate.",
    )
    return unflatten(rates)


def _equilibrated_condition(matrix):
    """The 2-norm condition number of `matrix` with its rows, then its columns, scaled to a
    largest entry of one: what is left is the system's own ill-conditioning, not its units
    (an inertia of 1e-6 beside a closing equation of unit coefficient)."""
    rows = matrix / jnp.max(jnp.abs(matrix), axis=1, keepdims=True)
    scaled = rows / jnp.max(jnp.abs(rows), axis=0, keepdims=True)
    return jnp.linalg.cond(scaled)
