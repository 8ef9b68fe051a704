r"""Constraints given as Pfaffian rows (76) of seed 001, solved for the dependent velocities."""

from collections.abc import Callable

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._linalg import take
from ._constraints import (
    AbstractKinematicConstraints,
    as_time,
    rank_checked,
    smallest_singular_value,
)
from ._holonomic import HolonomicConstraints

_RANK_LOST = (
    "The Pfaffian constraints b(q, t) (76) lose rank here: their rows are linearly dependent "
    "at this configuration, so they do not define s independent constraints. "
    "`PfaffianConstraints.constraint_singular_value` locates where."
)
_PARTITION_SINGULAR = (
    "The dependent velocities cannot be solved for here: the columns of b(q, t) of the "
    "coordinates not in `PfaffianConstraints.independent` form a singular matrix at this "
    "configuration. Choose other independent coordinates for this region of the motion, "
    "or give the constraints in parametric form (`ParametricConstraints`); "
    "`PfaffianConstraints.smallest_singular_value` locates where this happens."
)


class PfaffianConstraints(AbstractKinematicConstraints):
    r"""Kinematic constraints given as Pfaffian rows $b(q, t)\,\dot q + b_0(q, t) = 0$ (76).

    The parametric form (77) is obtained as the seed first proposes (§54): the $s$ rows are
    solved for $s$ *dependent* velocities, the characteristics being the $\nu = n - s$ others,
    chosen once (`independent`): $e = \dot q_I$ and

    $$ \dot q_D = -b_D^{-1}(b_I\,\dot q_I + b_0), \qquad
       \eta = \begin{bmatrix} 1 \\ -b_D^{-1}b_I \end{bmatrix},\quad
       \eta_0 = \begin{bmatrix} 0 \\ -b_D^{-1}b_0 \end{bmatrix} $$

    (rows in the order of $q$), with $b_I$, $b_D$ the columns of $b$ of the independent and
    dependent coordinates. Why this choice rather than an orthonormal null-space basis (QR
    or SVD of $b$ with signs fixed): it is a rational function of $b$'s entries, so $\eta$
    is as smooth as $b$ and involves no choice of sign or of basis that could flip along a
    trajectory (an orthonormal basis of a null space of dimension $\nu > 1$ is fixed only up
    to a rotation, which no sign rule removes); its characteristics are velocities of the
    mechanism, so initial conditions are given directly; and when the constraints are
    integrable its characteristics are holonomic (the chart $q_I$ of their integral
    manifold), so the bilinear covariants (84) and the nonholonomic terms $A_\alpha$ vanish
    identically, as §57–§58 require of holonomic characteristics. The price is that a
    static choice can fail where the constraints do not: it breaks down where $b_D$ is
    singular (the sleigh's blade $-\sin\theta\,\dot x + \cos\theta\,\dot y - a\dot\theta = 0$
    solved for $\dot y$ fails at $\cos\theta = 0$; solved for $\dot\theta$, never), and for
    some constraints no static choice is global. So this is reported:
    `smallest_singular_value` is $\sigma_{\min}(b_D)$, zero where the choice fails
    (and wherever the rows themselves lose rank, $\sigma_{\min}(b) \ge \sigma_{\min}(b_D)$);
    `constraint_singular_value` is $\sigma_{\min}(b)$, zero where the constraints lose rank.
    At run time both raise (`equinox.error_if`, inside `jit` and `grad` too).

    Holonomic constraints $f(q, t) = 0$ (`HolonomicConstraints`, `holonomic`) join as the
    rows $\partial_q f\,\dot q + \partial_t f = 0$ below the others; their dependent
    coordinates must be among the dependent velocities, and `on_the_constraints` keeps the
    configuration on $f = 0$ where the field is evaluated.

    **Arguments:**

    - `b`: `b(q, t) -> (s, n)`, the rows $b_{jh}$; `None` where `holonomic` gives every row.
    - `independent`: the indices of the $\nu = n - s$ coordinates whose velocities are the
      characteristics $e$, in the order of $e$ (static).
    - `b0`: `b0(q, t) -> (s,)`, the terms $b_{j0}$; `None` (the default) for constraints that
      do not depend on time.
    - `rank_tolerance`: $b$ counts as having lost rank where $\sigma_{\min}(b) \le$
      `rank_tolerance` $\sigma_{\max}(b)$, and the choice as failing where
      $\sigma_{\min}(b_D) \le$ `rank_tolerance` $\sigma_{\max}(b)$ (default `1e-8`).
    - `holonomic`: a `HolonomicConstraints`, or `None` (the default). With it, $s$ counts
      its rows too: `b` gives $s - h$.
    """

    b: Callable | None
    independent: tuple[int, ...] = eqx.field(static=True)
    b0: Callable | None = None
    rank_tolerance: float = eqx.field(static=True, default=1e-8)
    holonomic: HolonomicConstraints | None = None

    def __init__(self, b, independent, b0=None, rank_tolerance=1e-8, holonomic=None):
        self.b = b
        self.independent = tuple(int(i) for i in independent)
        self.b0 = b0
        self.rank_tolerance = float(rank_tolerance)
        self.holonomic = holonomic

    def __check_init__(self):
        if self.holonomic is not None and not isinstance(self.holonomic, HolonomicConstraints):
            raise ValueError(
                "`PfaffianConstraints.holonomic` must be a `HolonomicConstraints`, or None; got "
                f"{type(self.holonomic).__name__}."
            )
        if self.b is None and self.holonomic is None:
            raise ValueError(
                "`PfaffianConstraints` needs rows: give `b(q, t)`, `holonomic=` "
                "`HolonomicConstraints(f, dependent)`, or both."
            )
        if self.b is not None and not callable(self.b):
            raise ValueError("`PfaffianConstraints.b` must be a callable b(q, t) -> (s, n) array.")
        if self.b is None and self.b0 is not None:
            raise ValueError("`PfaffianConstraints.b0` is given without the rows `b` it goes with.")
        if self.b0 is not None and not callable(self.b0):
            raise ValueError(
                "`PfaffianConstraints.b0` must be a callable b0(q, t) -> (s,) array, or None "
                "for constraints that do not depend on time."
            )
        independent = self.independent
        if not independent or min(independent) < 0 or len(set(independent)) != len(independent):
            raise ValueError(
                "`PfaffianConstraints.independent` must list at least one coordinate index, "
                f"each non-negative and none twice; got {independent}."
            )
        if not 0 < self.rank_tolerance < 1:
            raise ValueError(
                f"`PfaffianConstraints.rank_tolerance` must be in (0, 1), got {self.rank_tolerance}."
            )
        held = set(self.independent) & set(
            () if self.holonomic is None else self.holonomic.dependent
        )
        if held:
            raise ValueError(
                f"`PfaffianConstraints`: coordinates {sorted(held)} are solved for by the "
                "holonomic constraints and listed as independent; their velocities follow from "
                "the constraints, so take them out of `independent`."
            )

    def rows(self, q, t):
        r"""$b(q, t)$ and $b_0(q, t)$ of (76), the holonomic rows last, their shapes checked
        against `independent`.

        **Arguments:**

        - `q`: the coordinates, shape `(n,)`; `t`: the time.

        **Returns:**

        `(b, b0)` of shapes `(s, n)` and `(s,)` ($b_0 = 0$ when not given).
        """
        t = as_time(t, q)
        n, nu = q.shape[0], len(self.independent)
        h = 0 if self.holonomic is None else len(self.holonomic.dependent)
        if max(self.independent) >= n:
            raise ValueError(
                f"`PfaffianConstraints.independent` = {self.independent} names coordinates "
                f"beyond the system's {n}."
            )
        parts = [] if self.b is None else [self._given_rows(q, t, n - nu - h)]
        if self.holonomic is not None:
            parts.append(self.holonomic.rows(q, t))
        b = jnp.concatenate([rows for rows, _ in parts])
        if b.shape[0] != n - nu:
            raise ValueError(
                f"`PfaffianConstraints`: with n = {n} coordinates and independent = "
                f"{self.independent}, the constraints need s = {n - nu} rows; the holonomic "
                f"constraints give {h} and `b` none."
            )
        return b, jnp.concatenate([b0 for _, b0 in parts]).astype(b.dtype)

    def _given_rows(self, q, t, s):
        """`b(q, t)` and `b0(q, t)` as given, checked to have `s` rows."""
        b = jnp.asarray(self.b(q, t))  # pyright: ignore[reportOptionalCall]
        n = q.shape[0]
        if b.shape != (s, n):
            raise ValueError(
                f"`PfaffianConstraints`: with n = {n} coordinates, independent = "
                f"{self.independent} and {n - len(self.independent) - s} holonomic rows, "
                f"b(q, t) must have shape ({s}, {n}) (one row per constraint); b has shape "
                f"{b.shape}."
            )
        if self.b0 is None:
            return b, jnp.zeros(s, b.dtype)
        b0 = jnp.asarray(self.b0(q, t))
        if b0.shape != (s,):
            raise ValueError(
                f"`PfaffianConstraints.b0(q, t)` must have shape ({s},); got {b0.shape}."
            )
        return b, b0

    def on_the_constraints(self, q, t):
        r"""$q$ with the holonomic constraints' dependent coordinates solved for
        (`HolonomicConstraints.on_the_constraints`); $q$ itself without them."""
        if self.holonomic is None:
            return q
        return self.holonomic.on_the_constraints(q, t)

    def holonomic_residual(self, q, t):
        r"""$f(q, t)$ of the holonomic constraints; empty without them."""
        if self.holonomic is None:
            return super().holonomic_residual(q, t)
        return self.holonomic.residual(q, t)

    def _partition(self, n):
        independent = np.asarray(self.independent)
        dependent = np.setdiff1d(np.arange(n), independent)
        return independent, dependent

    def parametric_form(self, q, t):
        b, b0 = self.rows(q, t)
        n, nu = q.shape[0], len(self.independent)
        independent, dependent = self._partition(n)
        b = rank_checked(
            b,
            take(b, dependent, axis=1),
            self.rank_tolerance,
            _PARTITION_SINGULAR,
            whole=b,
            whole_message=_RANK_LOST,
        )
        b_dependent = take(b, dependent, axis=1)
        right = jnp.concatenate([take(b, independent, axis=1), b0[:, None]], axis=1)
        solved = -jnp.linalg.solve(b_dependent, right)  # [-b_D^-1 b_I, -b_D^-1 b0]
        # The rows of (eta, eta0) in q's order, stacked (constant indices: no scatter).
        unit = jnp.eye(nu + 1, dtype=b.dtype)  # the independent rows: (e_alpha, 0)
        rows = {int(h): unit[alpha] for alpha, h in enumerate(independent)}
        rows |= {int(h): solved[j] for j, h in enumerate(dependent)}
        coefficients = jnp.stack([rows[h] for h in range(n)])
        return coefficients[:, :nu], coefficients[:, nu]

    def smallest_singular_value(self, q, t):
        r"""$\sigma_{\min}(b_D)$: zero where the dependent velocities cannot be solved for.

        **Arguments:**

        - `q`: the coordinates, shape `(n,)`; `t`: the time.

        **Returns:**

        The smallest singular value of the columns of $b(q, t)$ of the dependent coordinates.
        """
        b, _ = self.rows(q, t)
        return smallest_singular_value(take(b, self._partition(q.shape[0])[1], axis=1))

    def constraint_singular_value(self, q, t):
        r"""$\sigma_{\min}(b)$: zero where the constraints (76) lose rank.

        **Arguments:**

        - `q`: the coordinates, shape `(n,)`; `t`: the time.

        **Returns:**

        The $s$-th singular value of $b(q, t)$.
        """
        return smallest_singular_value(self.rows(q, t)[0])

    def residual(self, q, qdot, t):
        r"""The constraints' residual $b(q, t)\,\dot q + b_0(q, t)$ (76), zero on admissible motions.

        **Arguments:**

        - `q`, `qdot`: coordinates and velocities, shape `(n,)`; `t`: the time.

        **Returns:**

        The residual, shape `(s,)`.
        """
        b, b0 = self.rows(q, t)
        return b @ qdot + b0
