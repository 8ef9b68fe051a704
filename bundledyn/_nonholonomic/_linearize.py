r"""The linearization of a nonholonomic system's equations about a state, by autodiff."""

import functools
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._term import NonholonomicTerm

__all__ = ["linearization", "stability_boundary"]


def linearization(
    term: NonholonomicTerm, y: tuple[Float[Array, " n"], Float[Array, " nu"]], t=0.0
) -> Float[Array, "n+nu n+nu"]:
    r"""The Jacobian of the field $(\dot q, \dot e)$ of (77) with (82) (or §60) at the state
    $y = (q, e)$: the linearized equations $\delta\dot y = J\,\delta y$ about an
    equilibrium or a steady motion.

    At a steady motion of a system with cyclic coordinates (those the field does not depend
    on: a rolling disc's position, heading and spin angle) $J$ is block-triangular: the
    rows and columns of the other variables form the reduced field's Jacobian, whose
    eigenvalues decide the stability (`jnp.linalg.eigvals(J[np.ix_(kept, kept)])`). The
    cyclic block only adds zero eigenvalues, defective ones (a heading moves the position),
    which an eigenvalue solver returns only to about $\sqrt{\varepsilon}$: take the reduced
    block. The Jacobian is differentiable in the system's parameters, so are its
    eigenvalues.

    **Arguments:**

    - `term`: a `NonholonomicTerm` (the system and Maggi's or Appell's equations).
    - `y`: the state `(q, e)`, shapes `(n,)` and `(nu,)`.
    - `t`: the time.

    **Returns:**

    $J = \partial(\dot q, \dot e)/\partial(q, e)$, shape `(n + nu, n + nu)`, rows and
    columns ordered as $(q, e)$.
    """
    q, e = y
    n = q.shape[0]

    def field(z):
        q_dot, e_dot = term.vf(t, (z[:n], z[n:]), None)
        return jnp.concatenate([q_dot, e_dot])

    return jax.jacfwd(field)(jnp.concatenate([q, e]))


def stability_boundary(
    growth_rate: Callable[[Float[Array, ""], Any], Float[Array, ""]],
    bracket: tuple[float, float],
    args: Any = None,
    *,
    halvings: int = 64,
) -> Float[Array, ""]:
    r"""Where a steady motion changes stability: the root $v^*$ of a growth rate, $\sigma(v^*, p) = 0$.

    Found by bisection of `bracket`, whose ends $\sigma$ must have of opposite signs (it
    raises otherwise, `equinox.error_if`); bisection needs no derivative of $\sigma$, which
    is itself a derivative of the equations (the spectral abscissa of a `linearization`).
    The root is differentiable with respect to `args` by the implicit function theorem,
    $\partial v^* = -\sigma_v^{-1}\,\partial_p\sigma\,\partial p$: `jax.grad` of a critical
    speed with respect to a model's parameters.

    **Arguments:**

    - `growth_rate`: `growth_rate(v, args) -> scalar`, e.g. the spectral abscissa
      `lambda v, bike: bike.spectral_abscissa(v)` (`WhippleBicycle`).
    - `bracket`: `(lower, upper)`, values of $v$ on either side of a single root.
    - `args`: what `growth_rate` depends on besides $v$ (a model: its array leaves are
      differentiated).
    - `halvings`: the number of bisections (static); 64 reach the rounding of $v$ from any
      bracket of width below $10^4$.

    **Returns:**

    $v^*$.
    """
    lower, upper = (jnp.asarray(end, dtype=float) for end in bracket)
    return _boundary(growth_rate, halvings, lower, upper, args)


@functools.partial(jax.custom_jvp, nondiff_argnums=(0, 1))
def _boundary(growth_rate, halvings, lower, upper, args):
    return _bisection(growth_rate, halvings, lower, upper, args)


# The bisection and the slope are compiled each on its own, once per growth rate (a
# static argument): called outside `jax.jit`, a second bracket or the derivative's rule
# reuses them, where a program holding both compiles in more than their sum. Inside
# `jax.jit` they are inlined. The bisection's loop also evaluates the two ends (its first two
# passes), so the growth rate is traced and compiled once, not three times.
@eqx.filter_jit
def _bisection(growth_rate, halvings, lower, upper, args):
    def step(i, interval):
        low, high, at_lower, at_upper = interval
        middle = 0.5 * (low + high)
        point = jnp.where(i == 0, low, jnp.where(i == 1, high, middle))
        value = jnp.asarray(growth_rate(point, args), dtype=low.dtype)
        at_lower = jnp.where(i == 0, value, at_lower)
        at_upper = jnp.where(i == 1, value, at_upper)
        past = (value > 0) == (at_upper > at_lower)
        halving = i >= 2
        return (
            jnp.where(halving & ~past, middle, low),
            jnp.where(halving & past, middle, high),
            at_lower,
            at_upper,
        )

    start = (lower, upper, jnp.zeros_like(lower), jnp.zeros_like(upper))
    low, high, at_lower, at_upper = jax.lax.fori_loop(0, halvings + 2, step, start)
    return eqx.error_if(
        0.5 * (low + high),
        jnp.sign(at_lower) == jnp.sign(at_upper),
        "stability_boundary: the growth rate has the same sign at both ends of the bracket; "
        "give a bracket with the root inside.",
    )


# Both slopes in forward mode (v is a scalar): the growth rate is already a derivative of the
# equations, and reverse mode over it compiles far larger programs. One program gives both,
# its tangents arguments: the slope in speed is `_slope(..., 1, 0)`, the one along the
# parameters `_slope(..., 0, dp)`, which stays linear in dp (reverse mode transposes it).
@eqx.filter_jit
def _slope(growth_rate, root, args, speed_tangent, args_tangent):
    return jax.jvp(growth_rate, (root, args), (speed_tangent, args_tangent))[1]


@_boundary.defjvp
def _boundary_jvp(growth_rate, halvings, primals, tangents):
    lower, upper, args = primals
    root = _boundary(growth_rate, halvings, lower, upper, args)
    # A float0 tangent (of an integer leaf) is zero already.
    no_args = jax.tree.map(
        lambda t: t if t.dtype == jax.dtypes.float0 else jnp.zeros_like(t), tangents[2]
    )
    no_speed = jnp.zeros_like(root)
    along = _slope(growth_rate, root, args, no_speed, tangents[2])
    return root, -along / _slope(growth_rate, root, args, jnp.ones_like(root), no_args)
