r"""Holonomic constraints $f(q, t) = 0$ carried beside kinematic ones (seed 001, §54)."""

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._implicit import implicit_root
from ._constraints import as_time

# Newton's iterations from the integrated configuration, which lies within the integrator's
# tolerance of the constraints: quadratic convergence needs two or three; the rest are for
# a starting configuration further off.
_NEWTON_STEPS = 8


class HolonomicConstraints(eqx.Module):
    r"""Holonomic constraints $f(q, t) = 0$ among the Lagrangian coordinates, carried in their
    differentiated form with the configuration kept on them (seed 001, §54).

    Differentiated along a motion they are Pfaffian rows (76),
    $\partial_q f\,\dot q + \partial_t f = 0$, which `PfaffianConstraints(holonomic=…)`
    stacks under its own and solves with them for the dependent velocities; Maggi's and
    Appell's equations then hold with them as with any rows. Integrated, though, the rows
    keep $f$ constant only to the integrator's tolerance, so the configuration is kept on
    $f = 0$ by coordinate partitioning: wherever the field is evaluated, the `dependent`
    coordinates $s$ are first solved from the others by Newton's method, started from
    their integrated values (`on_the_constraints`). The motion of the other coordinates is
    then the motion on the constraint manifold, and the integrated values of $s$ differ
    from the solved ones by the integrator's error, which `residual` reports
    (`NonholonomicTerm.constraint_residual` along a solution). Derivatives through the
    solve, also in $f$'s parameters, are the implicit function's, $\partial s =
    -(\partial_s f)^{-1}(\partial_p f\,\partial p + \partial_t f\,\partial t +
    \partial_\theta f\,\partial\theta)$.

    ```python
    hoop = bd.HolonomicConstraints(  # a bead on a hoop turning at rate Ω, q = (r, φ, z)
        lambda q, t: jnp.stack([q[1] - Ω * t, q[0] ** 2 + q[2] ** 2 - R**2]), dependent=(1, 2))
    constraints = bd.PfaffianConstraints(None, independent=(0,), holonomic=hoop)
    ```

    **Arguments:**

    - `function`: $f(q, t)$, shape `(n,) -> (h,)`, $h$ = `len(dependent)`; an
      `equinox.Module` whose array fields are its parameters to differentiate, or any
      function.
    - `dependent`: the indices of the $h$ coordinates $s$ solved for (static); $\partial_s f$
      must be invertible along the motion.

    These are constraints among a `NonholonomicSystem`'s Lagrangian coordinates; a bundle
    system's shape coordinates are tied by `ImplicitConstraints` or `JointCoupling`
    (`ConstrainedSystem`), which eliminate them instead.
    """

    function: Callable
    dependent: tuple[int, ...] = eqx.field(static=True)

    def __init__(self, function, dependent):
        self.function = function
        self.dependent = tuple(int(j) for j in dependent)

    def __check_init__(self):
        if not callable(self.function):
            raise ValueError("`HolonomicConstraints.function` must be a function f(q, t).")
        if not self.dependent or min(self.dependent) < 0:
            raise ValueError(
                "`HolonomicConstraints.dependent` must list at least one coordinate index, each "
                f"non-negative; got {self.dependent}."
            )
        if len(set(self.dependent)) != len(self.dependent):
            raise ValueError("`HolonomicConstraints.dependent` names each coordinate once.")

    def residual(self, q: Float[Array, " n"], t) -> Float[Array, " h"]:
        r"""$f(q, t)$, checked to have one equation per dependent coordinate.

        **Arguments:**

        - `q`: the coordinates, shape `(n,)`; `t`: the time.

        **Returns:**

        $f(q, t)$, shape `(h,)`; zero on the constraints.
        """
        if max(self.dependent) >= q.shape[0]:
            raise ValueError(
                f"`HolonomicConstraints.dependent` = {self.dependent} names coordinates beyond "
                f"the system's {q.shape[0]}."
            )
        f = jnp.asarray(self.function(q, as_time(t, q)))
        if f.shape != (len(self.dependent),):
            raise ValueError(
                f"`HolonomicConstraints.function` must return {len(self.dependent)} values, one "
                f"per dependent coordinate; got shape {f.shape}."
            )
        return f

    def rows(self, q: Float[Array, " n"], t) -> tuple[Float[Array, "h n"], Float[Array, " h"]]:
        r"""The differentiated constraints as Pfaffian rows (76): $(\partial_q f, \partial_t f)$.

        **Arguments:**

        - `q`: the coordinates, shape `(n,)`; `t`: the time.

        **Returns:**

        `(b, b0)` of shapes `(h, n)` and `(h,)`.
        """
        t = as_time(t, q)
        return jax.jacfwd(self.residual, argnums=(0, 1))(q, t)

    def on_the_constraints(self, q: Float[Array, " n"], t) -> Float[Array, " n"]:
        r"""$q$ with its dependent coordinates solved from the others so that $f(q, t) = 0$.

        Newton's method started from $q$'s own dependent values; a configuration from which
        it does not reach $|f| \le 10^{-10}(1 + |q|)$ raises (`equinox.error_if`).

        **Arguments:**

        - `q`: the coordinates, shape `(n,)`; `t`: the time.

        **Returns:**

        The configuration on the constraints, shape `(n,)`.
        """
        t = as_time(t, q)
        # A closure over traced values (a parameter being differentiated) becomes a module
        # holding them as leaves, so that they are differentiated, not taken as static.
        function = eqx.filter_closure_convert(self.function, q, t)
        constraints = HolonomicConstraints(function, self.dependent)
        s = implicit_root((constraints, q, t), residual=_residual_in_dependent, solve=_newton)
        return q.at[np.asarray(self.dependent)].set(s)


def _residual_in_dependent(inputs, s):
    constraints, q, t = inputs
    return constraints.residual(q.at[np.asarray(constraints.dependent)].set(s), t)


def _newton(inputs):
    constraints, q, _ = inputs
    f = lambda s: _residual_in_dependent(inputs, s)
    step = lambda _, s: s - jnp.linalg.solve(jax.jacfwd(f)(s), f(s))
    s = jax.lax.fori_loop(0, _NEWTON_STEPS, step, q[np.asarray(constraints.dependent)])
    return eqx.error_if(
        s,
        ~(jnp.max(jnp.abs(f(s))) <= 1e-10 * (1.0 + jnp.linalg.norm(q))),
        "HolonomicConstraints: Newton's method did not solve f(q, t) = 0 for the dependent "
        "coordinates from this configuration: it is too far from the constraints (start "
        "the motion from `on_the_constraints(q0, t0)` of a nearer q0), or df/ds is singular "
        "here (choose other dependent coordinates).",
    )
