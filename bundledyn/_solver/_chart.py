r"""The chart the Lie-group solvers step in, and the field read in it.

Around a base point $y_0 = (g_0, x_0)$ the solvers work in the chart
$(\Omega, \delta) \mapsto (g_0\exp\hat\Omega,\ x_0 + \delta)$, $\Omega\in\mathbb R^6$. A
"chart increment" is a pytree of the same structure as `y` whose first leaf is a twist
(or a stack of twists) instead of a $4\times4$ matrix. The field comes in the same form,
the pose's rate as its body twist (`body_field`): from an `AbstractBodyTerm` directly,
from any other term read off $\dot g$.
"""

import equinox as eqx
import jax.numpy as jnp
import jax.tree_util as jtu

from .. import lie
from .._linalg import dot
from .._term import AbstractBodyTerm, AbstractSceneTerm, split, twist_of_tangent

__all__ = ["body_field", "body_term", "checked_start", "from_chart", "recharted"]

NONFINITE_FIELD = (
    "bundledyn: the vector field is NaN or infinite at a finite state that the solver "
    "accepted, where a step starts: an effect (a force, wrench or potential) returned NaN "
    "or Inf there, or the system's metric is singular there (a degenerate model). With "
    "fixed steps it can also be the solve's own doing: a step too large for the motion "
    "carries the state where the field overflows; take smaller steps."
)
COLLAPSED_STEP = (
    "bundledyn: the step size fell to the rounding error of the time (100 ulps): the "
    "solution is singular at the time the solve stopped, just past the last accepted state: "
    "the vector field is NaN or Inf there (an effect that returns NaN or Inf from then on) "
    "or grows without bound (the metric becoming singular, a force blowing up). No step "
    "size can get past it."
)


def from_chart(g0, rest0, treedef, omega, deltas):
    r"""The state $(g_0\exp\hat\Omega,\ x_0 + \delta)$ with the structure of `y0`."""
    g = dot(g0, lie.se3_exp(omega).astype(g0.dtype))
    rest = [x + d.astype(x.dtype) for x, d in zip(rest0, deltas, strict=True)]
    return jtu.tree_unflatten(treedef, [g, *rest])


def body_term(terms):
    """`(term, direction)`: the `AbstractBodyTerm` that `terms` is (direction 1) or that
    the wrapper `diffeqsolve` puts around every term holds (a `term` and a time
    `direction`); `(None, None)` for any other term. Other wrappers, such as the
    adjoint's, change the state and are not looked into."""
    if isinstance(terms, AbstractBodyTerm):
        return terms, 1
    inner, direction = getattr(terms, "term", None), getattr(terms, "direction", None)
    if isinstance(inner, AbstractBodyTerm) and direction is not None:
        return inner, direction
    return None, None


def body_field(terms, t, y, args, control=1.0):
    r"""The field of `terms` at `y` times `control`, with the pose's rate as the body twist
    $\xi$ (first leaf).

    Read directly from an `AbstractBodyTerm` (`body_term`: the wrapper's `vf` evaluates
    its term at `direction * t`), otherwise as $(g^{-1}\dot g)^\vee$.
    """
    term, direction = body_term(terms)
    if term is not None:
        return terms.prod(term.body_vf(t * direction, y, args), control)
    g, _, treedef = split(y)
    gdot, *rest = jtu.tree_leaves(terms.prod(terms.vf(t, y, args), control))
    return jtu.tree_unflatten(treedef, [twist_of_tangent(g, gdot), *rest])


def recharted(terms, t, y):
    r"""`y` in the coordinates its scene steps best in (`SceneTerm.recharted`: ball joints'
    rotation vectors back in $|\varphi| \le \pi$), the term looked for by `body_term`; `y`
    itself for any other term."""
    term, direction = body_term(terms)
    if isinstance(term, AbstractSceneTerm):
        return term.recharted(t * direction, y)
    return y


def _finite(tree):
    return jnp.all(jnp.stack([jnp.all(jnp.isfinite(leaf)) for leaf in jtu.tree_leaves(tree)]))


def checked_start(y1, t0, t1, y0, field0):
    """`y1`, raising at run time if the field `field0` at the accepted state `y0` is not
    finite while `y0` is, or if the step from `t0` to `t1` is shorter than the rounding
    error of `t0` (but not zero: finished members of a `vmap`ped solve take steps of zero
    length; and diffrax never clips a last step that short).

    A non-finite field at a trial state may be the trial's fault (a step too long), and
    the step-size controller rejects it; at the state the step starts from, or when the
    controller has shrunk the step to rounding, it is the model's. diffrax's controller
    would shrink the step until `max_steps` and then advise raising it, which cannot help.
    """
    y1 = eqx.error_if(y1, _finite(y0) & ~_finite(field0), NONFINITE_FIELD)
    t0, t1 = jnp.asarray(t0), jnp.asarray(t1)
    ulps = 100 * jnp.finfo(jnp.result_type(t0, t1, float)).eps * jnp.abs(t0)
    h = jnp.abs(t1 - t0)
    return eqx.error_if(y1, (h > 0) & (h <= ulps), COLLAPSED_STEP)
