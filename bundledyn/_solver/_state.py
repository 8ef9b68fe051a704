r"""The state convention of the Lie-group solvers and the chart they step in.

A state is a pytree `y` whose **first leaf** (in `jax.tree_util` flattening order) is a
$4\times4$ SE(3) pose $g$; every other leaf is Euclidean. The library's states are
`y = (g, x)`; the convention also covers the augmented state `(y, a_y, a_args, a_terms)`
that `diffrax.BacksolveAdjoint` integrates backwards, so that the backward pass can use a
Lie-group solver too.

Around a base point $y_0 = (g_0, x_0)$ the solvers work in the chart
$(\Omega, \delta) \mapsto (g_0\exp\hat\Omega,\ x_0 + \delta)$, $\Omega\in\mathbb R^6$. A
"chart increment" is a pytree of the same structure as `y` whose first leaf is a twist
(or a stack of twists) instead of a $4\times4$ matrix. The field comes in the same form,
the pose's rate as its body twist (`body_field`): from an `AbstractBodyTerm` directly,
from any other term read off $\dot g$.
"""

import abc

import diffrax
import jax.lax as lax
import jax.numpy as jnp
import jax.tree_util as jtu

from .. import lie

__all__ = [
    "AbstractBodyTerm",
    "body_field",
    "split",
    "from_chart",
    "tangent_of_twist",
    "twist_of_tangent",
    "matmul",
]


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


def tangent_of_twist(g, xi):
    r"""$\dot g = g\hat\xi$: the tangent vector in $\mathbb R^{4\times4}$ of the body twist $\xi$ at $g$."""
    return matmul(g, lie.hat(xi))


class AbstractBodyTerm(diffrax.AbstractTerm):
    r"""A term whose vector field is also given left-trivialized, with the pose's rate as
    its body twist $\xi$ ($\dot g = g\hat\xi$).

    The Lie-group solvers step in the twist. Reading it off $\dot g$ as $(g^{-1}\dot g)^\vee$
    makes every stage form $g_i = g_0\exp\hat\Omega_i$, $g_i\hat\xi$ and $g_i^{-1}$ even for a
    field that never reads $g$, and reverse mode then sends cotangents through all three
    that cancel in the end. Read directly, an `RKMK87` step of the 5-body chain of
    `benchmarks/speed.py` compiles to 95 fusions instead of 105 and its VJP to 401
    instead of 446; both versions in one process, alternating over 15 rounds, `jax.grad` of
    that benchmark's 10 s rollout took 0.86× and the forward solve 0.91× the earlier time
    (medians of the per-round ratios). Subclasses give `body_vf`; `vf` is derived from it,
    so stock diffrax solvers integrate the term on the embedding.
    """

    @abc.abstractmethod
    def body_vf(self, t, y, args):
        r"""The vector field at `y`, a pytree shaped as `y` whose first leaf is the body
        twist $\xi$, shape `(6,)`, instead of $\dot g$."""

    def vf(self, t, y, args):
        g, _, treedef = split(y)
        xi, *rest = jtu.tree_leaves(self.body_vf(t, y, args))
        return jtu.tree_unflatten(treedef, [tangent_of_twist(g, xi), *rest])


def body_field(terms, t, y, args, control=1.0):
    r"""The field of `terms` at `y` times `control`, with the pose's rate as the body twist
    $\xi$ (first leaf).

    Read directly from an `AbstractBodyTerm`, also inside the wrapper that `diffeqsolve`
    puts around every term (a `term` and a time `direction`, whose `vf` evaluates the term
    at `direction * t`), and otherwise as $(g^{-1}\dot g)^\vee$. Other wrappers, such as
    the adjoint's, change the state and are not looked into.
    """
    if isinstance(terms, AbstractBodyTerm):
        return terms.prod(terms.body_vf(t, y, args), control)
    inner, direction = getattr(terms, "term", None), getattr(terms, "direction", None)
    if isinstance(inner, AbstractBodyTerm) and direction is not None:
        return terms.prod(inner.body_vf(t * direction, y, args), control)
    g, _, treedef = split(y)
    gdot, *rest = jtu.tree_leaves(terms.prod(terms.vf(t, y, args), control))
    return jtu.tree_unflatten(treedef, [twist_of_tangent(g, gdot), *rest])
