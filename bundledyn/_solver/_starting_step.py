r"""The starting step of an adaptive solve, from two evaluations of the vector field."""

import equinox as eqx
import jax.lax as lax
import jax.numpy as jnp
import jax.tree_util as jtu
import optimistix as optx

from .. import lie
from .._term import split
from ._chart import body_field, from_chart

__all__ = ["starting_step"]


def _scaled_rms(leaves, scales):
    """RMS norm of the leaves divided elementwise by their scales: the error norm of
    `diffrax.PIDController` (`optx.rms_norm`)."""
    return optx.rms_norm([v / s for v, s in zip(leaves, scales, strict=True)])


def starting_step(term, t0, y0, args, *, error_order, rtol, atol):
    r"""Initial step size of an adaptive solve of `term` from `y0`, in the solvers' chart.

    The algorithm of Hairer, Nørsett & Wanner (Solving ODEs I, §II.4), with the pose's
    rate read as its body twist $\xi$ (`_chart.body_field`) and the Euler step taken in the
    chart $(g_0\exp\hat\Omega,\ x_0 + \delta)$ of `_chart.py`, so that it stays on the
    group:
    $d_0 = \|y_0\|$, $d_1 = \|f_0\|$, $h_0 = 0.01\,d_0/d_1$,
    $y_1 = (g_0\exp(h_0\hat\xi_0),\ x_0 + h_0\dot x_0)$, $d_2 = \|f_1 - f_0\|/h_0$,
    $h = \min\big(100h_0,\ (0.01/\max(d_1, d_2))^{1/p}\big)$, with $p$ the error order
    and RMS norms scaled by $\mathrm{atol} + \mathrm{rtol}\,|y_0|$ entrywise, twists arranged
    as $\hat\xi$ as in the solvers' error estimate.

    diffrax 0.7's `PIDController` has this algorithm, but runs it only for a bare
    `diffrax.ODETerm`, and `diffeqsolve` wraps every term: every solve then starts at
    $h = 0.01$ whatever the time scale of the motion, and spends its first steps growing
    the step by the controller's factor of 10 per step, with rejections on the way.

    The field is traced once (both evaluations run in a `lax.scan`) and not
    differentiated: the step is a choice of discretization, not a function of the
    parameters.

    **Arguments:**

    - `term`: the diffrax term: its `vf(t, y, args)` returns $(\dot g, \dot x)$, or an
      `AbstractBodyTerm`.
    - `t0`, `y0`, `args`: the start of the solve; `y0`'s first leaf is the pose.
    - `error_order`: the order $p$ of the solver's error estimate (`solver.error_order`).
    - `rtol`, `atol`: the step-size controller's tolerances.

    **Returns:**

    The starting step $h > 0$, a scalar of `y0`'s dtype.
    """
    dynamic, static = eqx.partition((term, y0, args), eqx.is_inexact_array)
    term, y0, args = eqx.combine(lax.stop_gradient(dynamic), static)
    g0, rest0, treedef = split(y0)
    t0 = jnp.asarray(t0, dtype=g0.dtype)
    scales = [atol + rtol * jnp.abs(leaf) for leaf in (g0, *rest0)]
    d0 = _scaled_rms([g0, *rest0], scales)

    def rates(t, y):
        xi, *xdot = jtu.tree_leaves(body_field(term, t, y, args))
        return xi, [v.astype(x.dtype) for v, x in zip(xdot, rest0, strict=True)]

    def norm(xi, xdot):
        return _scaled_rms([lie.hat(xi), *xdot], scales)

    def first_guess(f0):
        d1 = norm(*f0)
        small = (d0 < 1e-5) | (d1 < 1e-5)
        return jnp.where(small, 1e-6, 0.01 * d0 / jnp.where(small, 1.0, d1)), d1

    def evaluate(point, _):
        f = rates(*point)
        # The Euler step along f, meaningful after the first evaluation (f = f_0) only.
        h0, _ = first_guess(f)
        xi, xdot = f
        y1 = from_chart(g0, rest0, treedef, h0 * xi, [h0 * v for v in xdot])
        return (t0 + h0, y1), f

    _, (xis, xdots) = lax.scan(evaluate, (t0, y0), None, length=2)
    h0, d1 = first_guess((xis[0], [v[0] for v in xdots]))
    d2 = norm(xis[1] - xis[0], [v[1] - v[0] for v in xdots]) / h0
    d12 = jnp.maximum(d1, d2)
    h1 = jnp.where(
        d12 <= 1e-15,
        jnp.maximum(1e-6, h0 * 1e-3),
        (0.01 / jnp.where(d12 <= 1e-15, 1.0, d12)) ** (1.0 / error_order),
    )
    return jnp.minimum(100 * h0, h1)
