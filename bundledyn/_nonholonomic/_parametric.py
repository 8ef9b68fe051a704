r"""Constraints given directly in the parametric form (77) of seed 001."""

from collections.abc import Callable

import equinox as eqx
import jax.numpy as jnp

from ._constraints import (
    AbstractKinematicConstraints,
    as_time,
    rank_checked,
    smallest_singular_value,
)

_DEPENDENT_COLUMNS = (
    "The columns of the parametric constraints' eta(q, t) (77) are linearly dependent here: "
    "the characteristics e do not parametrize the admissible velocities uniquely, and "
    "Maggi's equations (82) are singular. Give eta with nu independent columns at every "
    "configuration the motion reaches (`ParametricConstraints.smallest_singular_value` "
    "locates where they become dependent)."
)


class ParametricConstraints(AbstractKinematicConstraints):
    r"""Kinematic constraints given as $\dot q = \eta(q, t)\,e + \eta_0(q, t)$ (77).

    Use it when the characteristics $e$ are known quantities of the mechanism (a sleigh's
    forward speed and turning rate, a wheel's spin): $\eta$'s columns are then smooth by
    construction. The columns must stay independent; where they do not, the integration
    raises (`equinox.error_if`).

    **Arguments:**

    - `eta`: `eta(q, t) -> (n, nu)`, the coefficients $\eta_{h\alpha}$.
    - `eta0`: `eta0(q, t) -> (n,)`, the coefficients $\eta_{h0}$; `None` (the default) for
      constraints that do not depend on time, where $\eta_0 \equiv 0$.
    - `rank_tolerance`: the columns count as dependent where the smallest singular value of
      $\eta$ is at most this times its largest (default `1e-8`; a single column, where it
      vanishes).

    Make `eta` an `equinox.Module` (or a bound method of one) to differentiate with respect
    to its parameters.
    """

    eta: Callable
    eta0: Callable | None = None
    rank_tolerance: float = eqx.field(static=True, default=1e-8)

    def __check_init__(self):
        if not callable(self.eta):
            raise ValueError(
                "`ParametricConstraints.eta` must be a callable eta(q, t) -> (n, nu) array."
            )
        if self.eta0 is not None and not callable(self.eta0):
            raise ValueError(
                "`ParametricConstraints.eta0` must be a callable eta0(q, t) -> (n,) array, or "
                "None for constraints that do not depend on time."
            )
        if not 0 < self.rank_tolerance < 1:
            raise ValueError(
                "`ParametricConstraints.rank_tolerance` must be in (0, 1), got "
                f"{self.rank_tolerance}."
            )

    def _coefficients(self, q, t):
        t = as_time(t, q)
        eta = jnp.asarray(self.eta(q, t))
        n = q.shape[0]
        if eta.ndim != 2 or eta.shape[0] != n or not 0 < eta.shape[1] <= n:
            raise ValueError(
                f"`ParametricConstraints.eta(q, t)` must return an (n, nu) array with n = {n} "
                f"(the coordinates) and 0 < nu <= n; got shape {eta.shape}."
            )
        if self.eta0 is None:
            return eta, jnp.zeros_like(q)
        eta0 = jnp.asarray(self.eta0(q, t))
        if eta0.shape != (n,):
            raise ValueError(
                f"`ParametricConstraints.eta0(q, t)` must return an array of shape ({n},); got "
                f"shape {eta0.shape}."
            )
        return eta, eta0

    def parametric_form(self, q, t):
        eta, eta0 = self._coefficients(q, t)
        return rank_checked(eta, eta, self.rank_tolerance, _DEPENDENT_COLUMNS), eta0

    def smallest_singular_value(self, q, t):
        r"""The smallest singular value of $\eta(q, t)$: zero where its columns are dependent.

        **Arguments:**

        - `q`: the coordinates, shape `(n,)`; `t`: the time.

        **Returns:**

        $\sigma_\nu(\eta)$, a non-negative scalar.
        """
        return smallest_singular_value(self._coefficients(q, t)[0])
