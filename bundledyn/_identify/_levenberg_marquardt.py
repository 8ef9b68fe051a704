r"""Levenberg–Marquardt on data residuals and penalized constraints, with the caller's Jacobians.

optimistix's least-squares solvers build the Jacobian themselves, one JVP of the whole
residual function per decision variable; the multiple-shooting problem's Jacobian is block
sparse (each window's states touch only that window), and `ShootingProblem` computes it
with each window's own tangents only. Its continuity conditions $c(z) = 0$ enter as
residuals weighted far above the data (a penalty whose solution coincides with the
constrained one to within the weight's ratio). Each step is Levenberg's: in the variables'
natural units $u$ (a parameter's own size, a state's noise level), the stacked residuals'
Jacobian $A = [J; C]\,\mathrm{diag}(u)$ is factorized $A = W\Sigma V^T$ and
$\delta = -\mathrm{diag}(u)\sum_i v_i \sigma_i/(\sigma_i^2 + \lambda)\, w_i^Tb$ over the
directions the residuals resolve ($\sigma_i >$ `1/resolution`): directions the data do not
determine stay put instead of drifting on rounding-level gradients until a body degenerates
(the identifiability report names them). The gain ratio of actual to predicted reduction
of $\tfrac12\|r\|^2 + \tfrac12\|c\|^2$ drives Nielsen's update of $\lambda$; it stops on
small steps or reductions.

$A$ has many more rows (samples) than columns, and a step needs only $\Sigma$, $V$ and
$W^Tb$: a QR factorization of $[A \mid b]$ gives $R$ and $Q^Tb$ without forming $Q$, and
$R = U\Sigma V^T$ (square) gives $W^Tb = U^TQ^Tb$. This is factorized once per Jacobian;
the trial steps at other dampings reuse it, and so may the next steps (chord steps): with
new residuals $b$, $W^Tb = \Sigma^{-1}V^TA^Tb$ costs a product with $A$, not a Jacobian.
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
    iterate, the first at the start); `evaluations` (of $(r, J, c, C)$, a given `start` not
    counted); `trials` (of the residuals at trial points), `chords` of them chord steps
    (from an earlier Jacobian); `steps` (accepted); `converged` (a stopping test was met
    before `max_steps` trials from new Jacobians).
    """

    z: jax.Array
    residuals: jax.Array
    jacobian: jax.Array
    defects: jax.Array
    constraint_jacobian: jax.Array
    costs: list
    evaluations: int
    trials: int
    chords: int
    steps: int
    converged: bool

    def evaluation(self) -> tuple:
        """`(r, J, c, C)` at `z`, as `evaluate(z)` returns them."""
        return self.residuals, self.jacobian, self.defects, self.constraint_jacobian


class _Factorization(NamedTuple):
    r"""What every damped step from one Jacobian needs: the singular values and right
    singular vectors of $A$, $W^Tb$ and the residuals' squared norm $b\cdot b$."""

    singular: jax.Array
    right: jax.Array
    projected: jax.Array
    norm: jax.Array


@jax.jit
def _factorization(r, J, c, C, units):
    r"""$A = [J; C]\,\mathrm{diag}(u)$ and $b = [r; c]$ factorized for `_step`, through the
    triangle of $[A \mid b]$ (module docstring)."""
    A, b = jnp.concatenate([J, C]) * units[None, :], jnp.concatenate([r, c])
    n = A.shape[1]
    Ab = jnp.concatenate([A, b[:, None]], axis=1)
    # Zero rows, where there are fewer residuals than variables, keep R square.
    Ab = jnp.pad(Ab, ((0, max(0, n + 1 - Ab.shape[0])), (0, 0)))
    triangle = jnp.linalg.qr(Ab, mode="r")
    left, singular, right = jnp.linalg.svd(triangle[:n, :n])
    return _Factorization(singular, right, left.T @ triangle[:n, n], b @ b)


# A step that achieves less than this fraction of the reduction its linear model predicted
# is followed by a new Jacobian, not a chord step: the model has stopped describing the
# residuals over a step's length.
_CHORD_GAIN = 0.5


@jax.jit
def _with_residuals(factorization: _Factorization, r, J, c, C, units) -> _Factorization:
    r"""`factorization`'s $A$ with new residuals $b$: $W^Tb = \Sigma^{-1}V^TA^Tb$ (zero
    along null directions, which no step moves along)."""
    singular, right, _, _ = factorization
    gradient = units * (J.T @ r + C.T @ c)
    safe = jnp.where(singular > 0, singular, 1.0)
    projected = jnp.where(singular > 0, (right @ gradient) / safe, 0.0)
    return _Factorization(singular, right, projected, r @ r + c @ c)


@jax.jit
def _step(factorization: _Factorization, damping, units, resolution):
    """The damped Gauss–Newton step of the stacked residuals, in the natural units and only
    along directions the residuals resolve, and the reduction it predicts."""
    singular, right, projected, _ = factorization
    resolved = singular * resolution > 1.0
    gain = jnp.where(resolved, singular / (singular**2 + damping), 0.0)
    y = -(right.T * gain[None, :]) @ projected
    # b·b - |b + Ay|² with b = W Wᵀb + b⊥ and Ay in the range of W.
    model = projected + singular * (right @ y)
    return units * y, 0.5 * (projected @ projected - model @ model)


def levenberg_marquardt(
    evaluate: Callable,
    residuals: Callable,
    z0,
    *,
    max_steps: int = 100,
    xtol: float = 1e-10,
    ftol: float = 1e-8,
    units=None,
    resolution: float = 10.0,
    callback: Callable | None = None,
    start: tuple | None = None,
    reuse: int = 0,
) -> LevenbergMarquardtResult:
    r"""Minimize ½‖r(z)‖² subject to c(z) = 0 with the caller's exact Jacobians.

    **Arguments:**

    - `evaluate`: `z -> (r, J, c, C)`: the residuals and their Jacobian, the constraints
      $c(z) = 0$ and theirs (compiled by the caller; `c` may be empty).
    - `residuals`: `z -> (r, c)` alone, for trial steps (the Jacobian is evaluated only at
      the steps taken).
    - `z0`: the starting point.
    - `max_steps`: the most trial steps from new Jacobians (chord steps not counted).
    - `xtol`: stop when a step is below `xtol (‖z‖ + xtol)`.
    - `ftol`: stop when an accepted step reduces the cost by less than `ftol` of it.
    - `units`: each variable's natural unit (default 1): the damping is $\lambda\|\delta/u\|^2$.
    - `resolution`: steps move only along directions the residuals determine to better than
      this many natural units (singular values of $[J; C]\,\mathrm{diag}(u)$ above
      `1/resolution`); the others stay where they start.
    - `callback`: called as `callback(step, z, cost, damping)` after every accepted step.
    - `reuse`: after an accepted step, take up to this many more steps with the same
      Jacobian and the new residuals (chord steps, each costing one `residuals` call),
      while each step achieves at least half the reduction it predicts.
    - `start`: `evaluate(z0)` when the caller already has it (e.g. from an earlier solve
      of the same residuals with other weights); it is then not evaluated again.

    **Returns:**

    A `LevenbergMarquardtResult`.
    """
    z = jnp.asarray(z0)
    units = jnp.ones_like(z) if units is None else jnp.asarray(units, z.dtype)
    r, J, c, C = evaluate(z) if start is None else start
    factorization = _factorization(r, J, c, C, units)
    cost = 0.5 * float(factorization.norm)
    costs, evaluations, trials, chords, steps = [cost], int(start is None), 0, 0, 0
    damping, growth, converged = 1e-3, 2.0, False
    fresh, reused = True, 0  # whether `factorization` is of the Jacobian at `z`; chord steps

    def refresh():
        nonlocal r, J, c, C, factorization, evaluations, fresh, reused
        r, J, c, C = evaluate(z)
        factorization = _factorization(r, J, c, C, units)
        evaluations, fresh, reused = evaluations + 1, True, 0

    while trials - chords < max_steps:
        delta, predicted = _step(factorization, damping, units, resolution)
        if not np.isfinite(float(predicted)):
            break
        r_new, c_new = residuals(z + delta)
        trials, chords = trials + 1, chords + (not fresh)
        cost_new = 0.5 * float(r_new @ r_new + c_new @ c_new)
        gain = (cost - cost_new) / max(float(predicted), np.finfo(float).tiny)
        small_step = float(jnp.linalg.norm(delta)) <= xtol * (float(jnp.linalg.norm(z)) + xtol)
        if np.isfinite(cost_new) and gain > 1e-4:
            reduction, stale = cost - cost_new, not fresh
            z, cost, r, c = z + delta, cost_new, r_new, c_new
            costs.append(cost)
            steps += 1
            damping *= max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3)
            growth = 2.0
            if callback is not None:
                callback(steps, z, cost, damping)
            stop = reduction <= ftol * cost or small_step
            if stop or reused >= reuse or gain < _CHORD_GAIN:
                refresh()
                # A chord step's small reduction may be the old Jacobian's: stop only if
                # the Jacobian at `z` predicts no more either.
                if stop and (not stale or _step(factorization, damping, units, resolution)[1]
                             <= ftol * cost):  # fmt: skip
                    converged = True
                    break
            else:
                factorization = _with_residuals(factorization, r, J, c, C, units)
                fresh, reused = False, reused + 1
        elif not fresh:
            refresh()  # the old Jacobian, not the damping, is the likelier cause
        else:
            if small_step:
                converged = True
                break
            damping *= growth
            growth *= 2.0
    if not fresh:
        refresh()  # the result's Jacobian is the one at its `z`
    return LevenbergMarquardtResult(
        z, r, J, c, C, costs, evaluations, trials, chords, steps, converged
    )
