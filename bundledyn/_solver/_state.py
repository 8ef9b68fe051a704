r"""The state convention of the Lie-group solvers and the chart they step in.

A state is a pytree `y` whose **first leaf** (in `jax.tree_util` flattening order) is a
$4\times4$ SE(3) pose $g$; every other leaf is Euclidean. The library's states are
`y = (g, x)`; the convention also covers the augmented state `(y, a_y, a_args, a_terms)`
that `diffrax.BacksolveAdjoint` integrates backwards, so that the backward pass can use a
Lie-group solver too.

Around a base point $y_0 = (g_0, x_0)$ the solvers work in the chart
$(\Omega, \delta) \mapsto (g_0\exp\hat\Omega,\ x_0 + \delta)$, $\Omega\in\mathbb R^6$. A
"chart increment" is a pytree of the same structure as `y` whose first leaf is a twist
(or a stack of twists) instead of a $4\times4$ matrix.
"""

import jax.lax as lax
import jax.numpy as jnp
import jax.tree_util as jtu

from .. import lie

__all__ = ["split", "from_chart", "twist_of_tangent", "matmul"]


def matmul(a, b):
    """Matrix product at full precision (no TF32 on accelerators)."""
    return jnp.matmul(a, b, precision=lax.Precision.HIGHEST)


def split(y):
    """`(g, rest, treedef)`: the pose leaf, the list of the other leaves, the structure."""
    leaves, treedef = jtu.tree_flatten(y)
    if len(leaves) == 0 or jnp.shape(leaves[0]) != (4, 4):
        shape = None if len(leaves) == 0 else jnp.shape(leaves[0])
        raise ValueError(
            "The Lie-group solvers expect a state whose first leaf is a 4x4 SE(3) pose, "
            f"e.g. y = (g, x); got a first leaf of shape {shape}."
        )
    return leaves[0], leaves[1:], treedef


def from_chart(g0, rest0, treedef, omega, deltas):
    r"""The state $(g_0\exp\hat\Omega,\ x_0 + \delta)$ with the structure of `y0`."""
    g = matmul(g0, lie.se3_exp(omega).astype(g0.dtype))
    rest = [x + d.astype(x.dtype) for x, d in zip(rest0, deltas, strict=True)]
    return jtu.tree_unflatten(treedef, [g, *rest])


def twist_of_tangent(g, gdot):
    r"""Body twist $\xi = (g^{-1}\dot g)^\vee$ of a tangent vector given in $\mathbb R^{4\times4}$.

    Reads only the entries of $g^{-1}\dot g$ that `vee` reads (the skew part of the
    rotation block is not symmetrized: for $\dot g = g\hat\xi$ with $g$ on the group the
    result is exact to rounding).
    """
    return lie.vee(matmul(lie.se3_inv(g), gdot))
