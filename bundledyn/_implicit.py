r"""Roots of equations, differentiated as the implicit functions they define.

A root $s(x)$ of $F(x, s) = 0$ found by an iteration (Newton's method, a continuation) is
differentiated by the implicit function theorem, $\partial s = -(\partial_s F)^{-1}\,
\partial_x F\,\partial x$, not through the iteration: the derivatives are exact at the root
whatever the iteration did, cost one linear solve, and exist to every order (the rule calls
the root again, so differentiating it differentiates the rule).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float, PyTree

__all__ = ["implicit_root"]


@eqx.filter_custom_jvp
def implicit_root(inputs: PyTree, *, residual, solve) -> Float[Array, "..."]:
    r"""The root $s$ of $F(x, s) = 0$ that `solve` finds, with the implicit function's derivatives.

    **Arguments:**

    - `inputs`: $x$, a pytree; its floating arrays are differentiated.
    - `residual`: $F(x, s)$, as many equations as $s$ has entries (a pure function: every
      array it depends on must come through `inputs`).
    - `solve`: `solve(inputs) -> s`, the iteration.

    **Returns:**

    $s$, of the shape `solve` returns (a scalar or a vector).
    """
    return solve(inputs)


@implicit_root.def_jvp
def _implicit_root_jvp(primals, tangents, *, residual, solve):
    (inputs,), (tangent,) = primals, tangents
    root = implicit_root(inputs, residual=residual, solve=solve)
    dynamic, static = eqx.partition(inputs, eqx.is_inexact_array)
    tangent = _zeros_for_none(dynamic, tangent)
    at_root = lambda dynamic: residual(eqx.combine(dynamic, static), root)
    _, moved = jax.jvp(at_root, (dynamic,), (tangent,))
    slope = jax.jacfwd(lambda s: jnp.ravel(residual(inputs, s)))(root)
    slope = slope.reshape(moved.size, root.size)
    step = jnp.linalg.solve(slope, jnp.ravel(moved))
    return root, -step.reshape(root.shape)


def _zeros_for_none(dynamic, tangent):
    """`tangent` with zeros for the arrays of `dynamic` it leaves undifferentiated (`None`)."""
    if tangent is None:
        return jax.tree.map(jnp.zeros_like, dynamic)
    return jax.tree.map(
        lambda x, t: None if x is None else (jnp.zeros_like(x) if t is None else t),
        dynamic,
        tangent,
        is_leaf=lambda x: x is None,
    )
