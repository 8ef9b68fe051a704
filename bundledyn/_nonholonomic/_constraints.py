r"""Kinematic constraints in the parametric form (77) of seed 001: the interface.

A system with coordinates $q_1, \dots, q_n$ is subject to $s$ kinematic constraints
(76), $\sum_h b_{jh}\dot q_h + b_{j0} = 0$, possibly not integrable (nonholonomic). Every
motion they allow is written with $\nu = n - s$ *kinematic characteristics* $e_\alpha$
(seed 001, §54) as

$$ \dot q_h = \sum_{\alpha=1}^{\nu} \eta_{h\alpha}(q, t)\, e_\alpha + \eta_{h0}(q, t)
   \qquad (77), $$

and every virtual displacement as $\delta q_h = \sum_\alpha \eta_{h\alpha}\,\delta\varepsilon_\alpha$
(78). Everything of seed 001 that follows (Maggi's and Appell's equations, the bilinear
covariants, the nonholonomic and holonomic terms) reads the constraints only through
`AbstractKinematicConstraints.parametric_form`.
"""

import abc

import equinox as eqx
import equinox.internal as eqxi
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

__all__ = [
    "AbstractKinematicConstraints",
    "as_time",
    "constrained_accelerations",
    "constrained_velocities",
    "kinematic_characteristics",
    "motion",
    "rank_checked",
    "smallest_singular_value",
]


def as_time(t, q) -> Array:
    """`t` as a scalar array of `q`'s floating dtype, so that it can carry a tangent."""
    dtype = q.dtype if jnp.issubdtype(q.dtype, jnp.floating) else jnp.result_type(float)
    return jnp.asarray(t, dtype=dtype)


def smallest_singular_value(matrix: Float[Array, "a b"]) -> Float[Array, ""]:
    r"""The smallest of the $\min(a, b)$ singular values of `matrix`: zero exactly where its
    rank drops below $\min(a, b)$."""
    return jnp.linalg.svd(matrix, compute_uv=False)[-1]


def _full_rank_certified(matrix, scale, tolerance: float) -> Array:
    r"""True where a cheap lower bound proves $\sigma_{\min}(\text{matrix}) >$ `tolerance` $\cdot$ `scale`.

    The bound is Gershgorin's on the Gram matrix $G$ ($AA^T$ or $A^TA$, whichever is
    $r\times r$, $r = \min(a, b)$) scaled to unit diagonal, $C = D^{-1/2}GD^{-1/2}$ with
    $D = \operatorname{diag}G$: $\sigma_{\min}^2 = \lambda_{\min}(G) \ge \min_i D_{ii}\,
    \lambda_{\min}(C) \ge \min_i D_{ii}\,(1 - \max_i\sum_{j\ne i}|C_{ij}|)$, less a margin
    for the rounding of $G$. Products and sums only, no factorization; where it returns False
    (a matrix near rank loss, or one whose columns are far from orthogonal) nothing is
    decided and the singular values must be taken.
    """
    a, b = matrix.shape
    gram = matrix @ matrix.T if a <= b else matrix.T @ matrix
    r, inner = min(a, b), max(a, b)
    diagonal = jnp.diagonal(gram)
    positive = diagonal > 0
    inverse_root = jnp.where(positive, jax.lax.rsqrt(jnp.where(positive, diagonal, 1.0)), 0.0)
    unit = gram * inverse_root[:, None] * inverse_root[None, :]
    radius = jnp.max(jnp.sum(jnp.abs(unit), axis=1) - jnp.abs(jnp.diagonal(unit)))
    # Rounding: each entry of G is off by at most inner·eps relative to sqrt(D_ii D_jj).
    margin = 2 * r * (inner + 4) * jnp.finfo(matrix.dtype).eps
    lower = jnp.min(diagonal) * (1 - radius - margin)
    return jnp.all(positive) & (lower > (tolerance * scale) ** 2 * (1 + margin))


def rank_checked(
    value, matrix, tolerance: float, message: str, whole=None, whole_message: str = ""
):
    r"""`value`, with `equinox.error_if` raising `message` where `matrix` has lost rank.

    `matrix` has lost rank where its smallest singular value is at most `tolerance` times
    the largest singular value of `whole` (default: of `matrix` itself). `whole`, when
    given, is a matrix of which `matrix` is a block of columns, with at least as many
    columns as rows (so $\sigma_{\min}(\text{whole}) \ge \sigma_{\min}(\text{matrix})$); it is
    checked too, against its own largest singular value, and its loss of rank raises
    `whole_message` instead. The singular values are taken with gradients stopped: the
    check is a predicate, never differentiated, and a singular value decomposition's
    derivative at repeated values would only produce NaNs that nobody reads.

    The predicate is exactly that, but the singular values are taken only where they can
    decide it: a bound from products of `matrix` (`_full_rank_certified`, against the
    Frobenius norm of `whole`, which bounds its largest singular value from above) first
    proves full rank wherever the block is well conditioned, and the singular value
    decompositions run in the branch of a `jax.lax.cond` that the bound does not settle
    (under `jax.vmap`, for the whole batch where it does not settle every instance).
    Why: a LAPACK singular value decomposition of a tiny matrix costs several times the
    rest of a nonholonomic field.
    """

    def predicate_input(x):  # gradients stopped; an integer matrix taken as floating
        x = jax.lax.stop_gradient(jnp.asarray(x))
        return x.astype(jnp.result_type(x.dtype, float))

    matrix = predicate_input(matrix)
    whole = None if whole is None else predicate_input(whole)

    def decide(value):
        values = jnp.linalg.svd(matrix, compute_uv=False)
        if whole is None:
            return eqx.error_if(value, values[-1] <= tolerance * values[0], message)
        whole_values = jnp.linalg.svd(whole, compute_uv=False)
        threshold = tolerance * whole_values[0]
        lost, whole_lost = values[-1] <= threshold, whole_values[-1] <= threshold
        return eqx.branched_error_if(
            value, lost | whole_lost, whole_lost.astype(int), (message, whole_message)
        )

    frobenius = jnp.sqrt(jnp.sum((matrix if whole is None else whole) ** 2))
    # Under `vmap` the branch is taken for the whole batch unless every instance is
    # certified, so that the predicate stays unbatched and `cond` does not become `select`
    # (which would run the decompositions for every instance).
    certified = eqxi.unvmap_all(_full_rank_certified(matrix, frobenius, tolerance))
    return jax.lax.cond(certified, lambda value: value, decide, value)


def motion(constraints: "AbstractKinematicConstraints", q, e, t):
    r"""$(\eta, \dot q, c)$ at $(q, e, t)$: the coefficients (77), the velocities (77) and the
    accelerations' part free of $\dot e$, $c = (\partial_q\eta\,\dot q + \partial_t\eta)\,e +
    \partial_q\eta_0\,\dot q + \partial_t\eta_0$, so that $\ddot q = \eta\dot e + c$.

    (77) is linearized once in $(q, t)$ and the linear map applied to $(\dot q, 1)$: one
    evaluation of $\eta$ gives the velocities and the accelerations.
    """
    t = as_time(t, q)

    def coefficients_and_velocities(q, t):
        eta, eta0 = constraints.parametric_form(q, t)
        return eta, eta @ e + eta0

    (eta, qdot), linear = jax.linearize(coefficients_and_velocities, q, t)
    return eta, qdot, linear(qdot, jnp.ones_like(t))[1]


class AbstractKinematicConstraints(eqx.Module):
    r"""Kinematic constraints, read in the parametric form (77) $\dot q = \eta(q, t)\,e + \eta_0(q, t)$.

    Subclasses give `parametric_form` (the matrices $\eta$, $\eta_0$) and
    `smallest_singular_value` (where the parametrization breaks down). The velocities (77)
    and accelerations along a motion follow (`constrained_velocities`,
    `constrained_accelerations`), as do the characteristics of a given admissible velocity
    (`kinematic_characteristics`).
    """

    @abc.abstractmethod
    def parametric_form(
        self, q: Float[Array, " n"], t
    ) -> tuple[Float[Array, "n nu"], Float[Array, " n"]]:
        r"""The coefficients $\eta_{h\alpha}(q, t)$ and $\eta_{h0}(q, t)$ of (77).

        **Arguments:**

        - `q`: the Lagrangian coordinates, shape `(n,)`.
        - `t`: the time (a scalar).

        **Returns:**

        `(eta, eta0)`: $\eta$ of shape `(n, nu)`, whose column $\alpha$ is $\partial\dot q/\partial
        e_\alpha$ (78), and $\eta_0$ of shape `(n,)` (zero for constraints that do not depend
        on time).
        """

    @abc.abstractmethod
    def smallest_singular_value(self, q: Float[Array, " n"], t) -> Float[Array, ""]:
        r"""The smallest singular value of the matrix the parametrization (77) is built on.

        It vanishes exactly where (77) breaks down at $(q, t)$: where the constraints lose
        rank or the characteristics $e$ stop parametrizing the admissible velocities. The
        integration raises there (`equinox.error_if`).

        **Arguments:**

        - `q`: the coordinates, shape `(n,)`; `t`: the time.

        **Returns:**

        A non-negative scalar.
        """

    def on_the_constraints(self, q: Float[Array, " n"], t) -> Float[Array, " n"]:
        r"""$q$ carried onto the holonomic constraints the kinematic ones include, where the
        field is evaluated; $q$ itself when they include none.

        **Arguments:**

        - `q`: the coordinates, shape `(n,)`; `t`: the time.

        **Returns:**

        The configuration on the holonomic constraints, shape `(n,)`.
        """
        return q

    def holonomic_residual(self, q: Float[Array, " n"], t) -> Float[Array, " h"]:
        r"""$f(q, t)$ of the holonomic constraints included, zero on them; empty when none.

        **Arguments:**

        - `q`: the coordinates, shape `(n,)`; `t`: the time.

        **Returns:**

        The residual, shape `(h,)`.
        """
        return jnp.zeros((0,), q.dtype)


def constrained_velocities(
    constraints: AbstractKinematicConstraints, q: Float[Array, " n"], e: Float[Array, " nu"], t
) -> Float[Array, " n"]:
    r"""The Lagrangian velocities (77) the constraints allow, $\dot q = \eta(q, t)\,e + \eta_0(q, t)$.

    **Arguments:**

    - `constraints`: an `AbstractKinematicConstraints`.
    - `q`: the coordinates, shape `(n,)`.
    - `e`: the kinematic characteristics, shape `(nu,)`.
    - `t`: the time.

    **Returns:**

    $\dot q$, shape `(n,)`.
    """
    eta, eta0 = constraints.parametric_form(q, t)
    return eta @ e + eta0


def constrained_accelerations(
    constraints: AbstractKinematicConstraints,
    q: Float[Array, " n"],
    e: Float[Array, " nu"],
    edot: Float[Array, " nu"],
    t,
) -> Float[Array, " n"]:
    r"""The Lagrangian accelerations along a motion, $\ddot q = \tfrac{d}{dt}(\eta e + \eta_0)$.

    $\ddot q = \eta\,\dot e + (\partial_q\eta\,\dot q + \partial_t\eta)\,e
    + \partial_q\eta_0\,\dot q + \partial_t\eta_0$ with $\dot q$ from (77), by one
    linearization of (77) in $(q, t)$ applied to $(\dot q, 1)$; so
    $\partial\ddot q_h/\partial\dot e_\alpha = \eta_{h\alpha}$ (§60).

    **Arguments:**

    - `constraints`: an `AbstractKinematicConstraints`.
    - `q`: the coordinates, shape `(n,)`.
    - `e`, `edot`: the characteristics and their rates, shape `(nu,)`.
    - `t`: the time.

    **Returns:**

    $\ddot q$, shape `(n,)`.
    """
    eta, _, drift = motion(constraints, q, e, t)
    return eta @ edot + drift


def kinematic_characteristics(
    constraints: AbstractKinematicConstraints, q: Float[Array, " n"], qdot: Float[Array, " n"], t
) -> Float[Array, " nu"]:
    r"""The kinematic characteristics $e$ of an admissible velocity $\dot q$: the solution of (77).

    Solved in the least-squares sense, $\eta^T\eta\, e = \eta^T(\dot q - \eta_0)$, which is
    exact when $\dot q$ satisfies the constraints; use it to start a motion from
    Lagrangian velocities.

    **Arguments:**

    - `constraints`: an `AbstractKinematicConstraints`.
    - `q`: the coordinates, shape `(n,)`.
    - `qdot`: velocities that satisfy the constraints at $(q, t)$, shape `(n,)`.
    - `t`: the time.

    **Returns:**

    $e$, shape `(nu,)`.
    """
    eta, eta0 = constraints.parametric_form(q, t)
    return jnp.linalg.solve(eta.T @ eta, eta.T @ (qdot - eta0))
