r"""Dense output that stays on the group: a polynomial in the chart of the step's start."""

import jax.numpy as jnp
import jax.tree_util as jtu
from diffrax import AbstractLocalInterpolation
from jaxtyping import Array, PyTree

from .._term import split
from ._chart import from_chart

__all__ = ["LieLocalInterpolation"]


def _rescale(t0, t, t1):
    """(t - t0) / (t1 - t0), zero (with zero gradients) when t0 == t1."""
    cond = t0 == t1
    return jnp.where(cond, 0, t - t0) / jnp.where(cond, 1, t1 - t0)


class LieLocalInterpolation(AbstractLocalInterpolation):
    r"""Interpolation over one step of a Lie-group solver, exact on SE(3).

    Over the step $[t_0, t_1]$ with $s = (t - t_0)/(t_1 - t_0)$ the solution is
    $$g(t) = g_0\exp\big(\Theta(s)^\wedge\big),\qquad x(t) = x_0 + \Delta(s),$$
    with $(\Theta, \Delta)(s) = \sum_{m=1}^{d} s^m\,C_{m-1}$ a polynomial in the chart
    centred at $y_0$ (so $\Theta(0) = 0$ and the value at $t_0$ is $y_0$ exactly). The
    coefficients $C$ are the solver's continuous extension applied to its stages: for an
    RKMK method this is the classical dense output of the same tableau applied to the ODE
    $\dot\Omega = \mathrm{dexp}^{-1}_\Omega\xi$, so it has that dense output's order
    (fifth for `RKMK87`, the sextic of `diffrax.Dopri8`; fourth for `RKMK54`, the quartic of
    `diffrax.Dopri5`; third for `RKMK4`; first, the geodesic, for `LieEuler`), and $g(t)$ is on the group to rounding error for every $t$.

    Built by diffrax as `interpolation_cls(t0=..., t1=..., **dense_info)`.

    **Arguments:**

    - `t0`, `t1`: the step's endpoints.
    - `y0`: the state at `t0`; its first leaf is the pose $g_0$.
    - `coeffs`: pytree with the structure of `y0`; first leaf shape `(d, 6)` (the twist
        coefficients of $\Theta$), other leaves `(d, *leaf.shape)`.
    """

    # diffrax declares `t0`, `t1` class variables to type checkers (for properties); here
    # they are fields, as in diffrax's own interpolations.
    t0: Array  # pyright: ignore[reportIncompatibleVariableOverride]
    t1: Array  # pyright: ignore[reportIncompatibleVariableOverride]
    y0: PyTree[Array]
    coeffs: PyTree[Array]

    def evaluate(self, t0, t1=None, left: bool = True) -> PyTree[Array]:
        r"""The state at `t0`, or, given `t1`, the increment $y(t_1) - y(t_0)$.

        The increment is the componentwise difference of the two states (for the pose a
        difference of $4\times4$ matrices), which is what diffrax expects of
        `evaluate(t0, t1)`; the values themselves are always on the group.
        """
        del left
        if t1 is not None:
            return jtu.tree_map(lambda a, b: a - b, self.evaluate(t1), self.evaluate(t0))
        g0, rest0, treedef = split(self.y0)
        s = _rescale(self.t0, t0, self.t1)

        def _poly(c):
            s_ = s.astype(c.dtype)
            out = c[-1]
            for m in range(c.shape[0] - 2, -1, -1):
                out = c[m] + s_ * out
            return s_ * out

        chart = [_poly(c) for c in jtu.tree_leaves(self.coeffs)]
        return from_chart(g0, rest0, treedef, chart[0], chart[1:])
