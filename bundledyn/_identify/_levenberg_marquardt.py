r"""Levenberg–Marquardt with equality constraints, on residuals whose exact Jacobian the caller computes.

optimistix's least-squares solvers build the Jacobian themselves, one JVP of the whole
residual function per decision variable, and take no constraints; the multiple-shooting
problem's Jacobian is block sparse (each window's states touch only that window),
`ShootingProblem` computes it with each window's own tangents only, and its continuity
conditions $c(z) = 0$ are constraints. Each step here solves the linearized constraints
exactly, $C\delta = -c$ (Bock's multiple shooting: $\delta = \delta_p + N y$ with $N$ a
basis of the null space of $C$ from a QR factorization), and takes a Levenberg–Marquardt
step in $y$ on the data residuals: Marquardt's scaled damping
$\lambda\,\mathrm{diag}(A^TA)$, $A = JN$, a step from the stacked least-squares problem (never
the normal equations), the gain ratio of actual to predicted reduction of the merit
$\tfrac12\|r\|^2 + \tfrac12\|c\|^2$, Nielsen's update of $\lambda$, and stopping on small
steps or reductions. Without constraints it is plain Levenberg–Marquardt.
"""

from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["LevenbergMarquardtResult", "levenberg_marquardt"]


class LevenbergMarquardtResult(NamedTuple):
    """The solution of `levenberg_marquardt`.

    **Fields:** `z` (the solution); `residuals`, `jacobian`, `defects` and
    `constraint_jacobian` there; `costs` (the merit ½‖r‖² + ½‖c‖² at each accepted
    iterate, the first at the start); `evaluations` (of $(r, J, c, C)$); `steps`
    (accepted); `converged` (a stopping test was met before `max_steps`).
    """

    z: jax.Array
    residuals: jax.Array
    jacobian: jax.Array
    defects: jax.Array
    constraint_jacobian: jax.Array
    costs: list
    evaluations: int
    steps: int
    converged: bool


def null_space(C):
    r"""$(Q_1, R_1, N)$: $C^T = Q_1R_1$ and an orthonormal basis $N$ of the null space of $C$."""
    m = C.shape[0]
    Q, R = jnp.linalg.qr(C.T, mode="complete")
    return Q[:, :m], R[:m], Q[:, m:]


@jax.jit
def _step(r, J, c, C, damping):
    """The constrained damped Gauss–Newton step and the merit reduction it predicts."""
    if C.shape[0]:
        Q1, R1, N = null_space(C)
        delta_p = -Q1 @ jax.scipy.linalg.solve_triangular(R1.T, c, lower=True)
    else:
        N, delta_p = jnp.eye(J.shape[1], dtype=J.dtype), jnp.zeros(J.shape[1], J.dtype)
    A, b = J @ N, r + J @ delta_p
    scale = jnp.sqrt(jnp.maximum(jnp.sum(A * A, axis=0), jnp.finfo(A.dtype).tiny))
    stacked = jnp.concatenate([A, jnp.sqrt(damping) * jnp.diag(scale)])
    y = jnp.linalg.lstsq(stacked, jnp.concatenate([-b, jnp.zeros_like(scale)]))[0]
    model = b + A @ y
    predicted = 0.5 * (r @ r + c @ c - model @ model)
    return delta_p + N @ y, predicted


def levenberg_marquardt(
    evaluate: Callable,
    z0,
    *,
    max_steps: int = 100,
    xtol: float = 1e-10,
    ftol: float = 1e-10,
    callback: Callable | None = None,
) -> LevenbergMarquardtResult:
    """Minimize ½‖r(z)‖² subject to c(z) = 0 with the caller's exact Jacobians.

    **Arguments:**

    - `evaluate`: `z -> (r, J, c, C)`: the residuals and their Jacobian, the constraints
      $c(z) = 0$ and theirs (compiled by the caller; `c` may be empty).
    - `z0`: the starting point.
    - `max_steps`: the most evaluations after the first.
    - `xtol`: stop when a step is below `xtol (‖z‖ + xtol)`.
    - `ftol`: stop when an accepted step reduces the cost by less than `ftol` of it.
    - `callback`: called as `callback(step, z, cost, damping)` after every accepted step.

    **Returns:**

    A `LevenbergMarquardtResult`.
    """
    z = jnp.asarray(z0)
    r, J, c, C = evaluate(z)
    cost = 0.5 * float(r @ r + c @ c)
    costs, evaluations, steps = [cost], 1, 0
    damping, growth, converged = 1e-3, 2.0, False
    while evaluations <= max_steps:
        delta, predicted = _step(r, J, c, C, damping)
        if not np.isfinite(float(predicted)):
            break
        r_new, J_new, c_new, C_new = evaluate(z + delta)
        evaluations += 1
        cost_new = 0.5 * float(r_new @ r_new + c_new @ c_new)
        gain = (cost - cost_new) / max(float(predicted), np.finfo(float).tiny)
        small_step = float(jnp.linalg.norm(delta)) <= xtol * (float(jnp.linalg.norm(z)) + xtol)
        if np.isfinite(cost_new) and gain > 1e-4:
            reduction = cost - cost_new
            z, r, J, c, C, cost = z + delta, r_new, J_new, c_new, C_new, cost_new
            costs.append(cost)
            steps += 1
            damping *= max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3)
            growth = 2.0
            if callback is not None:
                callback(steps, z, cost, damping)
            if reduction <= ftol * cost or small_step:
                converged = True
                break
        else:
            if small_step:
                converged = True
                break
            damping *= growth
            growth *= 2.0
    return LevenbergMarquardtResult(z, r, J, c, C, costs, evaluations, steps, converged)
