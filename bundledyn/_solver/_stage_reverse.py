r"""The stages of a Runge–Kutta–Munthe-Kaas step with their reverse pass written out.

Autodiff transposes the stage recursion stage by stage: inside the scan, each stage's
$\exp\hat\Omega_i$ and $\mathrm{dexp}^{-1}_{\Omega_i}$ are differentiated through their
trigonometric coefficients, dozens of scalar kernels per stage. Their derivatives depend
only on the stages' $\Omega_i$ and $\eta_i$, all known once the stages have run, so the
reverse pass here evaluates them for every stage at once, before its loop, and the loop
is left with products by these matrices and the field's own VJP.

With $\Omega_i = \sum_j a_{ij}\kappa_j$, $\delta_i = \sum_j a_{ij}k_j$,
$y_i = (g_0\exp\hat\Omega_i,\ x_0 + \delta_i)$, $(\eta_i, k_i) = f(t_i, y_i)$ and
$\kappa_i = \mathrm{dexp}^{-1}_{\Omega_i}\eta_i$ (`_rkmk.py`), the cotangents run backwards
from the last stage:
$\bar\eta_i = D_i^T\bar\kappa_i$ and $\bar\Omega_i = M_i^T\bar\kappa_i$ with
$D_i = \mathrm{dexp}^{-1}_{\Omega_i}$, $M_i = \partial_\Omega(\mathrm{dexp}^{-1}_\Omega
\eta_i)$; the field's VJP gives $(\bar g_i, \bar x_i)$ from $(\bar\eta_i, \bar k_i)$; since
$d(g_0 e^{\hat\Omega}) = g_0e^{\hat\Omega}(J\,d\Omega)^\wedge$ with $J = \mathrm{dexp}_\Omega$,
$\bar\Omega_i \mathrel{+}= J_i^T(g_i^T\bar g_i)^{\wedge*}$, $\bar g_0 \mathrel{+}=
\bar g_i e^{-\hat\Omega_i^T}$ and $\bar x_0 \mathrel{+}= \bar x_i$; finally
$\bar\kappa_j \mathrel{+}= a_{ij}\bar\Omega_i$ and $\bar k_j \mathrel{+}= a_{ij}\bar x_i$
for the earlier stages $j < i$.
"""

import functools

import equinox as eqx
import jax
import jax.lax as lax
import jax.numpy as jnp
import jax.tree_util as jtu

from .. import lie
from .._linalg import dot
from .._term import KEPT_FIELD_OUTPUTS
from ._chart import from_chart

__all__ = ["combine", "stages", "stages_with_reverse_pass"]

_HIGHEST = lax.Precision.HIGHEST
_KEPT = jax.checkpoint_policies.save_only_these_names(KEPT_FIELD_OUTPUTS)


def combine(w, stack):
    """Σ_i w_i stack[..., i] at full precision: for weights `w` of shape (s,), shape
    `stack.shape[:-1]`; for a (m, s) matrix, the m combinations stacked first.

    The stage axis is the stacks' last: under `vmap` the batch comes first, and a
    contraction over a leading stage axis made XLA's CPU copy the whole stack to bring that
    axis forward before every stage.
    """
    out = jnp.tensordot(stack, w.astype(stack.dtype), axes=([-1], [-1]), precision=_HIGHEST)
    return out if w.ndim == 1 else jnp.moveaxis(out, -1, 0)


def _outer(x, w):
    """`x[..., None] * w`: each entry of `x` times the weights `w` (s,), stacked last."""
    return x[..., None] * jnp.expand_dims(w, tuple(range(x.ndim)))


def stages(field, a, g0, rest0, treedef, ts, control, n):
    r"""The first `n` stages of the tableau with matrix `a`, from $y_0 = (g_0, x_0)$.

    **Arguments:**

    - `field`: `field(i, t, y, control)` gives stage `i`'s field times the control (its
      first leaf the body twist) and a value to stack over the stages.
    - `a`: the tableau's matrix; `g0`, `rest0`, `treedef`: $y_0$ as `split` gives it.
    - `ts`: the stages' times; `control`: the step's control.

    **Returns:**

    `(kappas, ks, kept, omegas, etas)`: the chart increments $\kappa_i$ of the pose and
    $k_i$ of the other leaves, stacked last; the field's stacked values; the stages'
    $\Omega_i$ and $\eta_i$, stacked last.
    """
    s = a.shape[0]

    def stage(carry, i):
        kappas, ks = carry
        omega = combine(a[i], kappas)
        yi = from_chart(g0, rest0, treedef, omega, [combine(a[i], k) for k in ks])
        out, kept = field(i, ts[i], yi, control)
        eta, *kx = jtu.tree_leaves(out)
        eta = eta.astype(omega.dtype)
        kappa = dot(lie.se3_dexp_inv(omega), eta)
        kappas = kappas.at[..., i].set(kappa)
        ks = [k.at[..., i].set(kxi.astype(k.dtype)) for k, kxi in zip(ks, kx, strict=True)]
        return (kappas, ks), (kept, omega, eta)

    # Rematerialized under reverse mode: the scan then stores each stage's inputs, not
    # the field's intermediates stacked over the stages (`AbstractRKMK`); a field's outputs
    # named `KEPT_FIELD_OUTPUTS` are kept. A scan body needs no CSE barrier.
    stage = jax.checkpoint(stage, prevent_cse=False, policy=_KEPT)
    kappas0 = jnp.zeros((6, s), dtype=g0.dtype)
    ks0 = [jnp.zeros((*jnp.shape(x), s), dtype=jnp.result_type(x)) for x in rest0]
    (kappas, ks), (kept, omegas, etas) = lax.scan(stage, (kappas0, ks0), jnp.arange(n), length=n)
    return kappas, ks, kept, omegas.T, etas.T


def _hat_dual(m):
    r"""The twist $X$ with $X\cdot Y = \langle m, \hat Y\rangle$ for every twist $Y$."""
    return jnp.stack(
        [m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1], m[0, 3], m[1, 3], m[2, 3]]
    )


def _dexp_inv_applied_derivative(xi, eta):
    r"""$M = \partial_\xi(\mathrm{dexp}^{-1}_\xi\eta)$, $6\times6$, by the dual-number
    structure of `se3_dexp_inv` (`_se3.py`): with $\xi = (\omega, v)$, $\eta = (a, b)$
    and $P_c = \partial_\omega(J_r^{-1}(\omega)c)$,
    $M = \begin{pmatrix}P_a & 0\\ \partial_\omega(P_a v) + P_b & P_a\end{pmatrix}$.
    Differentiating the SE(3) matrix directly (`jacfwd` of the $6\times6$ matrix) gives the
    same, but XLA compiles it, batched over the stages, into a much slower program."""
    w, v, a, b = xi[:3], xi[3:], eta[:3], eta[3:]

    def applied(w, c):
        return dot(lie.so3_dexp_inv(w), c)

    P_a, P_b = jax.jacfwd(applied)(w, a), jax.jacfwd(applied)(w, b)
    along_v = jax.jacfwd(lambda w: jax.jvp(lambda w: applied(w, a), (w,), (v,))[1])(w)
    top = jnp.concatenate([P_a, jnp.zeros_like(P_a)], axis=-1)
    return jnp.concatenate([top, jnp.concatenate([along_v + P_b, P_a], axis=-1)], axis=-2)


def _stage_matrices(omegas, etas):
    r"""For every stage at once: $e^{\hat\Omega_i}$, $J_i = \mathrm{dexp}_{\Omega_i}$,
    $D_i = \mathrm{dexp}^{-1}_{\Omega_i}$ and $M_i = \partial_\Omega(\mathrm{dexp}^{-1}_\Omega
    \eta_i)$, stacked first."""
    omegas, etas = omegas.T, etas.T
    return (
        lie.se3_exp(omegas),
        lie.se3_dexp(omegas),
        lie.se3_dexp_inv(omegas),
        jax.vmap(_dexp_inv_applied_derivative)(omegas, etas),
    )


def _materialized(cotangents, like):
    """`cotangents` with every missing (None) one replaced by zeros shaped as in `like`."""
    return jtu.tree_map(
        lambda o, c: jnp.zeros_like(o) if c is None else c,
        like,
        cotangents,
        is_leaf=lambda x: x is None,
    )


def stages_with_reverse_pass(field, a, g0, rest0, treedef, ts, control, n):
    """`stages`, differentiated in reverse mode by the pass written out in the module
    docstring; not differentiable in forward mode (`equinox.filter_custom_vjp`). The
    field's traced constants (a term's numbers, `args`) get their cotangents from the
    field's VJP, as do the stages' times and the control where they are differentiated."""
    y0 = jtu.tree_unflatten(treedef, [g0, *rest0])
    closed, consts = jax.closure_convert(field, 0, ts[0], y0, control)

    def run(inputs):
        g0, rest0, ts, control, consts = inputs

        def plain(i, t, y, c):
            return closed(i, t, y, c, *consts)

        return stages(plain, a, g0, rest0, treedef, ts, control, n)

    @eqx.filter_custom_vjp
    def with_reverse(inputs):
        return run(inputs)[:3]

    @with_reverse.def_fwd
    def forward(perturbed, inputs):
        del perturbed
        kappas, ks, kept, omegas, etas = run(inputs)
        return (kappas, ks, kept), ((kappas, ks, kept), omegas, etas)

    @with_reverse.def_bwd
    def backward(residuals, cotangents, perturbed, inputs):
        outputs, omegas, etas = residuals
        kappas_bar, ks_bar, kept_bar = _materialized(cotangents, outputs)
        g0, rest0, ts, control, consts = inputs
        # Only what is differentiated: the replayed field refuses a tangent on its time.
        varied, fixed = eqx.partition((ts, control, consts), perturbed[2:])
        exps, dexps, dexp_invs, applied = _stage_matrices(omegas, etas)
        deltas = [combine(a[:n], k) for k in outputs[1]]  # stacked first

        def stage_field(i, y, varied):
            ts, control, consts = eqx.combine(varied, fixed)
            return closed(i, ts[i], y, control, *consts)

        def reverse_stage(carry, i):
            kappas_bar, ks_bar, g0_bar, rest0_bar, varied_bar = carry
            kappa_bar = kappas_bar[:, i]
            omega_bar = dot(applied[i].T, kappa_bar)
            gi = dot(g0, exps[i])
            rest = [x + d[i] for x, d in zip(rest0, deltas, strict=True)]
            (out, _), vjp = jax.vjp(
                lambda y, v: stage_field(i, y, v), jtu.tree_unflatten(treedef, [gi, *rest]), varied
            )
            eta_bar = dot(dexp_invs[i].T, kappa_bar).astype(jtu.tree_leaves(out)[0].dtype)
            out_bar = jtu.tree_unflatten(
                jtu.tree_structure(out), [eta_bar] + [kb[..., i] for kb in ks_bar]
            )
            y_bar, v_bar = vjp((out_bar, jtu.tree_map(lambda kb: kb[i], kept_bar)))
            gi_bar, *xi_bar = jtu.tree_leaves(y_bar)
            omega_bar = omega_bar + dot(dexps[i].T, _hat_dual(dot(gi.T, gi_bar)))
            carry = (
                kappas_bar + _outer(omega_bar, a[i]),
                [kb + _outer(xb, a[i]) for kb, xb in zip(ks_bar, xi_bar, strict=True)],
                g0_bar + dot(gi_bar, exps[i].T),
                [r + xb for r, xb in zip(rest0_bar, xi_bar, strict=True)],
                jtu.tree_map(jnp.add, varied_bar, v_bar),
            )
            return carry, None

        zeros = functools.partial(jtu.tree_map, jnp.zeros_like)
        carry = (kappas_bar, list(ks_bar), zeros(g0), zeros(rest0), zeros(varied))
        carry, _ = lax.scan(reverse_stage, carry, jnp.arange(n), reverse=True)
        _, _, g0_bar, rest0_bar, varied_bar = carry
        return (g0_bar, rest0_bar, *varied_bar)

    return with_reverse((g0, rest0, ts, control, consts))
