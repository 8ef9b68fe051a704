r"""Butcher tableaus for the explicit Runge–Kutta–Munthe-Kaas solvers, with dense output.

A tableau here is the classical one: RKMK applies it unchanged to the ODE for the algebra
increment $\Omega$ (and to the Euclidean rest of the state), so any classical order-$p$
tableau gives an order-$p$ Lie-group method (Munthe-Kaas 1999). Each tableau also carries a
*continuous extension* $b_i(\theta) = \sum_{m\ge1} B_{m-1,i}\,\theta^m$ of its weights,
which the solvers use for dense output in the same chart.
"""

from typing import Any, cast

import diffrax
import equinox as eqx
import numpy as np

__all__ = [
    "LieButcherTableau",
    "euler_tableau",
    "rk4_tableau",
    "dopri5_tableau",
    "dopri8_tableau",
]


def _rows(a_lower) -> tuple[np.ndarray, ...]:
    return tuple(np.asarray(row) for row in a_lower)


def _optional(b_error) -> np.ndarray | None:
    return None if b_error is None else np.asarray(b_error)


class LieButcherTableau(eqx.Module):
    r"""An explicit Butcher tableau with an optional embedded pair and a dense output.

    A static description, used as a class-level attribute of a solver (not as a field).

    **Arguments:**

    - `a_lower`: rows $2..s$ of the strictly lower triangle, as a tuple of 1-D arrays of
        lengths $1, \dots, s-1$.
    - `b_sol`: weights of the propagated solution, shape `(s,)`.
    - `c`: nodes $c_2, \dots, c_s$, shape `(s-1,)` ($c_1 = 0$).
    - `dense`: coefficients $B$ of the continuous extension, shape `(degree, s)`:
        $b_i(\theta) = \sum_{m=1}^{\mathrm{degree}} B_{m-1,i}\,\theta^m$, with
        $b_i(1) = $ `b_sol[i]`.
    - `b_error`: optional, shape `(s,)`: weights $b_i - \hat b_i$ of the error estimate
        (the difference between the propagated and the embedded solution, as in
        `diffrax.ButcherTableau`); `None` for a method without an error estimate.

    Construction checks the shapes and the order conditions every tableau meets (each
    to `numpy.allclose`'s tolerance), and raises `ValueError` naming the one that fails
    and its residual: the row sums $\sum_j a_{ij} = c_i$, the consistency
    $\sum_i b_i = 1$, the continuous extension's end $b_i(1) = b_i$ and, with an error
    estimate, the embedded solution's consistency $\sum_i (b_i - \hat b_i) = 0$.

    Derived: `num_stages`, `step_stages` (the leading stages that the propagated solution
    and the error estimate use; later ones serve the dense output only), `fsal` (the last
    stage is evaluated at the propagated solution: $a_{s,j} = b_j$, $b_s = 0$, $c_s = 1$),
    the full `(s, s)` matrix `a` and the full node vector `c_full`.
    """

    a_lower: tuple[np.ndarray, ...] = eqx.field(converter=_rows)
    b_sol: np.ndarray = eqx.field(converter=np.asarray)
    c: np.ndarray = eqx.field(converter=np.asarray)
    dense: np.ndarray = eqx.field(converter=np.asarray)
    b_error: np.ndarray | None = eqx.field(default=None, converter=_optional)

    def __check_init__(self):
        name = "`LieButcherTableau`"
        if self.b_sol.ndim != 1 or self.b_sol.shape[0] < 1:
            raise ValueError(
                f"{name}: `b_sol` must be the (s,) weights of the s >= 1 stages, got shape "
                f"{self.b_sol.shape}."
            )
        s = self.b_sol.shape[0]
        if self.c.shape != (s - 1,) or len(self.a_lower) != s - 1:
            raise ValueError(
                f"{name}: with {s} weights `b_sol`, `c` must hold the {s - 1} nodes "
                f"c_2..c_s and `a_lower` the {s - 1} rows 2..s; got `c` of shape "
                f"{self.c.shape} and {len(self.a_lower)} rows."
            )
        for i, row in enumerate(self.a_lower):
            if row.shape != (i + 1,):
                raise ValueError(
                    f"{name}: row {i + 2} of `a_lower` (stage {i + 2}) must have {i + 1} "
                    f"entries a_{i + 2},1..a_{i + 2},{i + 1}, got shape {row.shape}."
                )
        if self.dense.ndim != 2 or self.dense.shape[1] != s:
            raise ValueError(
                f"{name}: `dense` must have shape (degree, {s}), one column per stage, got "
                f"{self.dense.shape}."
            )
        if self.b_error is not None and self.b_error.shape != (s,):
            raise ValueError(
                f"{name}: `b_error` must have shape ({s},), got {self.b_error.shape}; pass "
                "None for a method without an error estimate."
            )
        for i, row in enumerate(self.a_lower):
            if not np.allclose(row.sum(), self.c[i]):
                k = i + 2
                raise ValueError(
                    f"{name} breaks the row-sum condition Σ_j a_{k}j = c_{k} of stage {k}: "
                    f"the residual Σ_j a_{k}j - c_{k} is {row.sum() - self.c[i]:.3g}. Row {k} "
                    f"of the matrix (`a_lower[{i}]`) must sum to the stage's node `c[{i}]`."
                )
        if not np.allclose(self.b_sol.sum(), 1.0):
            raise ValueError(
                f"{name} breaks the first-order condition Σ_i b_i = 1: the residual "
                f"Σ_i b_i - 1 is {self.b_sol.sum() - 1.0:.3g}. The weights `b_sol` must sum "
                "to 1."
            )
        end = self.dense.sum(axis=0) - self.b_sol
        if not np.allclose(self.dense.sum(axis=0), self.b_sol):
            i = int(np.argmax(np.abs(end)))
            raise ValueError(
                f"{name} breaks the dense output's end condition b_i(1) = b_i, "
                f"b_i(1) = Σ_m B_m-1,i: the residual b_{i + 1}(1) - b_{i + 1} is "
                f"{end[i]:.3g} (the largest, stage {i + 1}). Each column of `dense` must sum "
                "to its stage's weight in `b_sol`, so that the dense output ends at the step's "
                "solution."
            )
        if self.b_error is not None and not np.allclose(self.b_error.sum(), 0.0):
            raise ValueError(
                f"{name} breaks the embedded solution's first-order condition "
                f"Σ_i (b_i - b̂_i) = 0: the residual Σ_i (b_i - b̂_i) is "
                f"{self.b_error.sum():.3g}. `b_error` holds the weights b - b̂ of the error "
                "estimate, both of which sum to 1, so it must sum to 0."
            )

    @property
    def num_stages(self) -> int:
        return self.b_sol.shape[0]

    @property
    def step_stages(self) -> int:
        used = (self.b_sol != 0) | (0 if self.b_error is None else self.b_error != 0)
        return int(np.flatnonzero(used)[-1]) + 1

    @property
    def fsal(self) -> bool:
        s = self.num_stages
        return bool(
            s > 1
            and self.b_sol[-1] == 0
            and bool(np.all(self.a_lower[-1] == self.b_sol[:-1]))
            and self.c[-1] == 1
        )

    @property
    def a(self) -> np.ndarray:
        s = self.num_stages
        a = np.zeros((s, s))
        for i, row in enumerate(self.a_lower):
            a[i + 1, : i + 1] = row
        return a

    @property
    def c_full(self) -> np.ndarray:
        return np.concatenate([np.zeros(1), self.c])


# Lie–Euler: one stage, linear (geodesic) dense output.
euler_tableau = LieButcherTableau(
    a_lower=(),
    b_sol=np.array([1.0]),
    c=np.zeros(0),
    dense=np.array([[1.0]]),
)

# Classical RK4 with its free third-order continuous extension (Hairer–Nørsett–Wanner,
# Solving ODEs I, §II.6): b1 = θ - 3θ²/2 + 2θ³/3, b2 = b3 = θ² - 2θ³/3, b4 = -θ²/2 + 2θ³/3.
rk4_tableau = LieButcherTableau(
    a_lower=(np.array([0.5]), np.array([0.0, 0.5]), np.array([0.0, 0.0, 1.0])),
    b_sol=np.array([1 / 6, 1 / 3, 1 / 3, 1 / 6]),
    c=np.array([0.5, 0.5, 1.0]),
    dense=np.array(
        [
            [1.0, 0.0, 0.0, 0.0],
            [-1.5, 1.0, 1.0, -0.5],
            [2 / 3, -2 / 3, -2 / 3, 2 / 3],
        ]
    ),
)


def _dopri5():
    a_lower = (
        np.array([1 / 5]),
        np.array([3 / 40, 9 / 40]),
        np.array([44 / 45, -56 / 15, 32 / 9]),
        np.array([19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729]),
        np.array([9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656]),
        np.array([35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84]),
    )
    b_sol = np.array([35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0])
    # Embedded fourth-order weights as in `diffrax.Dopri5` (Shampine 1986).
    b_hat = np.array(
        [1951 / 21600, 0, 22642 / 50085, 451 / 720, -12231 / 42400, 649 / 6300, 1 / 60]
    )
    c = np.array([1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0])
    # Shampine's (1986) midpoint weights: y(1/2) ≈ y0 + Σ c_mid_i k_i. With y0 = 0 (the
    # chart is centred at the step's start), f0 = k_1, f1 = k_7 (FSAL) and y1 = Σ b_i k_i,
    # the quartic through y0, y1, ymid with slopes f0, f1 (the interpolant of
    # `diffrax.Dopri5`) is linear in the stages: p(θ) = Σ_m θ^m B_{m-1} k.
    c_mid = 0.5 * np.array(
        [
            6025192743 / 30085553152,
            0,
            51252292925 / 65400821598,
            -2691868925 / 45128329728,
            187940372067 / 1594534317056,
            -1776094331 / 19743644256,
            11237099 / 235043384,
        ]
    )
    f0 = np.eye(7)[0]
    f1 = np.eye(7)[-1]
    quartic = 2 * (f1 - f0) - 8 * b_sol + 16 * c_mid
    cubic = 5 * f0 - 3 * f1 + 14 * b_sol - 32 * c_mid
    quadratic = f1 - 4 * f0 - 5 * b_sol + 16 * c_mid
    dense = np.stack([f0, quadratic, cubic, quartic])
    return LieButcherTableau(a_lower=a_lower, b_sol=b_sol, c=c, dense=dense, b_error=b_sol - b_hat)


# Dormand–Prince 5(4) (Dormand & Prince 1980; Shampine 1986), the tableau of
# `diffrax.Dopri5`, with its fourth-order dense output.
dopri5_tableau = _dopri5()


def _dopri8():
    # Read off `diffrax.Dopri8` rather than copied: its 13-stage Prince–Dormand 8(7)
    # tableau plus a 14th, FSAL stage at the propagated solution (b_14 = 0, used only by
    # the dense output), and its embedded seventh-order error weights.
    ref = diffrax.Dopri8.tableau
    # diffrax's dense output: y(θ) = y0 + Σ_i θ polyval(E[i], θ) k_i with E of shape
    # (s, d) (highest power first), so B[m-1, i] = E[i, d-m]. d = 6: a sextic.
    interpolation = cast(Any, diffrax.Dopri8.interpolation_cls)  # a class, typed as a callable
    eval_coeffs = np.asarray(interpolation.eval_coeffs, dtype=np.float64)
    dense = eval_coeffs[:, ::-1].T.copy()
    # The published decimals give b_i(1) = Σ_m B[m-1, i] ≠ b_i by up to 1e-12 (against
    # coefficients up to ~120), so the dense output would miss the step's end by that
    # much. Folding the difference into the θ⁶ row makes b_i(1) = b_i to rounding and
    # leaves the continuous order conditions (fifth order, see `RKMK87`) satisfied to
    # 4e-15 instead of 2e-14.
    dense[-1] += ref.b_sol - dense.sum(axis=0)
    return LieButcherTableau(
        a_lower=tuple(np.asarray(row, dtype=np.float64) for row in ref.a_lower),
        b_sol=np.asarray(ref.b_sol, dtype=np.float64),
        c=np.asarray(ref.c, dtype=np.float64),
        dense=dense,
        b_error=np.asarray(ref.b_error, dtype=np.float64),
    )


# Dormand–Prince 8(7) (Prince & Dormand 1981), the tableau of `diffrax.Dopri8`, with its
# 14th (FSAL) stage and the sextic dense output of `diffrax.Dopri8` (Bogacki & Shampine
# 1990), which is of fifth order between the step's ends.
dopri8_tableau = _dopri8()
