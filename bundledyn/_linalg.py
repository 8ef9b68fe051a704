"""Small dense linear algebra as fused elementwise work: products, inverses and SPD solves.

The vector field of a tree of bodies is a few dozen products of 3×3 to 6×6 matrices. On
XLA's CPU every `dot` is a kernel of its own, which XLA does not fuse with its neighbours,
and launching one costs more than the arithmetic of a 6×6 product; a LAPACK
factorization of a 6×6 matrix costs more still (a call with a pivot loop) and under `vmap`
runs once per instance.
Written as broadcast products and sums (`einsum`, `matmul`) and closed-form inverses
(`inverse_3x3`, `spd_inverse_6x6`) and unrolled Cholesky solves (`spd_solve`, up to 6×6),
the same work is elementwise, fuses into a few kernels and batches for free. Larger
contractions (sums over many bodies) keep a real matrix kernel: fused, they made vmapped
rollouts slower.
"""

import functools
import math
import operator
from typing import cast

import jax
import jax.lax as lax
import jax.numpy as jnp
import jax.scipy.linalg as jsl
import numpy as np
from jaxtyping import Array, Float

# A 6×6 by 6×6 product, per member of a batch (the indices every operand and the output
# share: one product per body): up to it, fused broadcast products beat `dot` kernels, and
# their VJPs more so; with a larger limit the sums over bodies fuse too, and vmapped
# rollouts get slower.
_FUSED_PRODUCT_LIMIT = 216
# Runs of consecutive indices past which `take` gathers: on 85 rows, slices and a gather
# cost the same in reverse mode at 8 runs.
_MOST_RUNS = 8


def einsum(subscripts: str, *operands) -> Array:
    """`jnp.einsum` for small operands, as one broadcast product and a sum that XLA fuses.

    Contractions whose broadcast product has more than 216 entries (a 6×6 by 6×6 product)
    per member of a batch (the indices that every operand and the output share, as one
    product per body), and subscripts with a repeated index in one operand, go to
    `jnp.einsum` (at `Precision.HIGHEST`). The small ones are exact products summed in
    index order, at full precision on every backend.

    **Arguments:**

    - `subscripts`: explicit einsum subscripts with `->`; `...` may lead each term.
    - `operands`: the arrays.

    **Returns:**

    The same array as `jnp.einsum(subscripts, *operands)`.
    """
    operands = [jnp.asarray(x) for x in operands]
    plan = _plan(subscripts, operands)
    if plan is None:
        return jnp.einsum(subscripts, *operands, precision=lax.Precision.HIGHEST)
    return _fused_einsum(*plan, *operands)


def _plan(subscripts, operands):
    """`(letters, order, n_out)` of a small contraction, or None for `jnp.einsum`'s."""
    inputs, output = subscripts.replace(" ", "").split("->")
    inputs = inputs.split(",")
    if len(inputs) != len(operands):
        raise ValueError(f"{subscripts!r} names {len(inputs)} operands, got {len(operands)}.")
    # `...` becomes explicit upper-case indices, right-aligned as in broadcasting.
    extra = [
        x.ndim - len(spec.replace("...", "")) for spec, x in zip(inputs, operands, strict=True)
    ]
    ellipsis = "".join(chr(ord("A") + i) for i in range(max(extra)))
    letters = [
        spec.replace("...", ellipsis[len(ellipsis) - k :])
        for spec, k in zip(inputs, extra, strict=True)
    ]
    output = output.replace("...", ellipsis)
    order = output + "".join(dict.fromkeys(c for spec in letters for c in spec if c not in output))
    sizes = dict.fromkeys(order, 1)
    for spec, x in zip(letters, operands, strict=True):
        for c, n in zip(spec, x.shape, strict=True):
            sizes[c] = max(sizes[c], n)
    repeated = any(len(set(spec)) < len(spec) for spec in letters)
    batch = [c for c in output if all(c in spec for spec in letters)]
    each = math.prod(n for c, n in sizes.items() if c not in batch)
    if repeated or each > _FUSED_PRODUCT_LIMIT:
        return None
    return tuple(letters), order, len(output)


def _broadcast_product(letters, order, n_out, operands):
    """The operands' product broadcast over all indices, contracted ones flattened last."""
    product = 1
    for spec, x in zip(letters, operands, strict=True):
        perm = sorted(range(len(spec)), key=lambda i: order.index(spec[i]))
        own = dict(zip(spec, x.shape, strict=True))
        product = product * jnp.transpose(x, perm).reshape([own.get(c, 1) for c in order])
    # `_plan` matched an operand to each term (one at least): an array, not the starting 1.
    product = cast(Array, product)
    kept = product.shape[:n_out]
    return product.reshape(*kept, math.prod(product.shape[n_out:]))


@functools.partial(jax.custom_jvp, nondiff_argnums=(0, 1, 2))
def _fused_einsum(letters, order, n_out, *operands):
    terms = _broadcast_product(letters, order, n_out, operands)
    # Explicit adds, not a `reduce`: XLA's CPU hands batched reductions to YNNPACK, which
    # runs these tiny ones several times slower under `vmap`.
    if terms.shape[-1] == 0:
        return jnp.zeros(terms.shape[:-1], terms.dtype)
    return functools.reduce(operator.add, (terms[..., k] for k in range(terms.shape[-1])))


@functools.partial(_fused_einsum.defjvp, symbolic_zeros=True)
def _fused_einsum_jvp(letters, order, n_out, primals, tangents):
    # The tangent sums with a `reduce`, whose transpose is a broadcast that fuses with the
    # product. Transposing the explicit adds gave one `pad` kernel per contracted entry,
    # which made the vector field's VJP far dearer.
    out = _fused_einsum(letters, order, n_out, *primals)
    parts = [
        _summed(_broadcast_product(letters, order, n_out, (*primals[:i], t, *primals[i + 1 :])))
        for i, t in enumerate(tangents)
        if not isinstance(t, jax.custom_derivatives.SymbolicZero)
    ]
    return out, functools.reduce(operator.add, parts) if parts else jnp.zeros_like(out)


def _summed(terms):
    """`terms` summed over its last axis; zeros, not a sum, over an empty one (an empty
    contraction: its transpose under `vmap` would broadcast to the wrong rank)."""
    if terms.shape[-1] == 0:
        return jnp.zeros(terms.shape[:-1], terms.dtype)
    return jnp.sum(terms, -1)


def dot(a, b) -> Array:
    """`a @ b` as XLA's own `dot` kernel, at full precision (no TF32 on accelerators).

    For the solvers' products with the pose, which stay one kernel each rather than the
    fused elementwise work of `matmul`.
    """
    return jnp.matmul(a, b, precision=lax.Precision.HIGHEST)


def materialized(x) -> Array:
    r"""`x`, computed once into a buffer of its own rather than inlined into its consumers.

    XLA fuses a chain of elementwise work into each consumer, so a recursion of fused
    products (a tree's levels, the pointer jumps of its poses) would recompute every step
    before it in each of its kernels (an 80-body chain's pass from the root: 275k HLO
    instructions and 40 s to compile, 21k and 5 s with this). A `lax.optimization_barrier`
    there left the recomputation in place; XLA's CPU fusion puts no `reduce` inside a
    consumer, and a sum with zero is one.

    **Arguments:**

    - `x`: an array.

    **Returns:**

    `x`, equal to it.
    """
    return jnp.sum(jnp.stack([x, jnp.zeros_like(x)], axis=-1), axis=-1)


def take(x, indices, axis: int = 0) -> Array:
    """`x` indexed by constant integers along `axis`: slices of their consecutive runs where
    the runs are few, else one gather.

    Reverse mode transposes a slice to a `pad` of the whole axis, which fuses with its
    neighbours, and a gather to a `scatter-add`, a loop over the indices on XLA's CPU. The
    pads' work grows with the runs times the axis, the loop's with the indices alone: past
    `_MOST_RUNS` runs (a bushy tree's parents in level order) the gather is the cheaper
    one both ways; a chain's few runs stay slices.

    **Arguments:**

    - `x`: an array.
    - `indices`: a NumPy integer array (any shape) of positions along `axis`.
    - `axis`: the axis to index.

    **Returns:**

    `jnp.take(x, indices, axis)`: `axis` replaced by the shape of `indices`.
    """
    indices = np.asarray(indices, dtype=int)
    axis = axis % x.ndim
    flat = indices.reshape(-1) % x.shape[axis]
    breaks = np.flatnonzero(np.diff(flat) != 1) + 1
    runs = [(r[0], r[-1] + 1) for r in np.split(flat, breaks) if r.size]
    if len(runs) > _MOST_RUNS:
        at = (slice(None),) * axis + (flat.reshape(indices.shape),)
        return x.at[at].get(mode="promise_in_bounds")
    if runs == [(0, x.shape[axis])]:
        picked = x
    elif not runs:
        picked = lax.slice_in_dim(x, 0, 0, axis=axis)
    else:
        picked = jnp.concatenate(
            [lax.slice_in_dim(x, int(a), int(b), axis=axis) for a, b in runs], axis=axis
        )
    return picked.reshape(x.shape[:axis] + indices.shape + x.shape[axis + 1 :])


def matmul(a, b) -> Array:
    """`a @ b` (batched over leading axes; a 1-D `b` is a vector) through `einsum`."""
    if jnp.ndim(b) == 1:
        return einsum("...ij,j->...i", a, b)
    if jnp.ndim(a) == 1:
        return einsum("j,...jk->...k", a, b)
    return einsum("...ij,...jk->...ik", a, b)


# adj(M)[i, j] = M[j+1, i+1] M[j+2, i+2] - M[j+2, i+1] M[j+1, i+2] (indices mod 3): one gather
# pattern per factor, so the adjugate is a single fused elementwise kernel.
_I, _J = np.indices((3, 3))
_NEXT, _AFTER = (_J + 1) % 3, (_J + 2) % 3
_NEXT_T, _AFTER_T = (_I + 1) % 3, (_I + 2) % 3


@jax.custom_jvp
def inverse_3x3(M: Float[Array, "3 3"]) -> Float[Array, "3 3"]:
    r"""$M^{-1} = \operatorname{adj}(M)/\det M$ (the rows of the adjugate are cross products of columns).

    **Arguments:**

    - `M`: an invertible 3×3 matrix.

    **Returns:**

    $M^{-1}$, with rows $(c_1\times c_2,\ c_2\times c_0,\ c_0\times c_1)/(c_0\cdot(c_1\times c_2))$
    for the columns $c_j$ of $M$.
    """
    adjugate = M[_NEXT, _NEXT_T] * M[_AFTER, _AFTER_T] - M[_AFTER, _NEXT_T] * M[_NEXT, _AFTER_T]
    return adjugate / jnp.dot(M[:, 0], adjugate[0])


@inverse_3x3.defjvp
def _inverse_3x3_jvp(primals, tangents):
    # $d(M^{-1}) = -M^{-1}\,dM\,M^{-1}$: products, whose transposes are products too; the
    # adjugate's gathers would transpose into scatter-adds.
    (M,), (dM,) = primals, tangents
    inverse = inverse_3x3(M)
    return inverse, -matmul(inverse, matmul(dM, inverse))


def spd_inverse_6x6(M: Float[Array, "6 6"]) -> Float[Array, "6 6"]:
    r"""Inverse of a symmetric positive definite 6×6 matrix by its 3×3 blocks (Schur complement).

    With $M = \begin{bmatrix} P & Q \\ Q^T & D\end{bmatrix}$, $K = QD^{-1}$ and the Schur
    complement $S = P - KQ^T$ (SPD whenever $M$ is),

    $$M^{-1} = \begin{bmatrix} S^{-1} & X \\ X^T & D^{-1} - K^T X\end{bmatrix},\quad X = -S^{-1}K.$$

    For a spatial inertia (angular first; every locked inertia is one) $D = m\mathbf 1$ and $S$
    is the rotational inertia about the centre of mass, so both 3×3 inverses are as well
    conditioned as the body and the result is as accurate as LAPACK's (tests: forward error
    within 4 κ ε up to κ ~ 1e10). For an arbitrary SPD matrix the form is not backward
    stable (forward error ~80 κ ε measured at κ = 1e6).

    **Arguments:**

    - `M`: symmetric positive definite, shape `(6, 6)` (only the blocks $P$, $Q$, $D$ are read).

    **Returns:**

    $M^{-1}$, symmetric by construction.
    """
    P, Q, D = M[:3, :3], M[:3, 3:], M[3:, 3:]
    D_inv = inverse_3x3(D)
    K = matmul(Q, D_inv)
    S_inv = inverse_3x3(P - matmul(K, Q.T))
    X = -matmul(S_inv, K)
    return jnp.block([[S_inv, X], [X.T, D_inv - matmul(K.T, X)]])


# Largest SPD solve that `spd_solve` unrolls: up to here the unrolled factorization beats
# LAPACK's two custom calls on XLA's CPU; beyond, its d³ elementwise work, inlined into each
# use, costs more.
_UNROLLED_SOLVE_LIMIT = 6


def spd_solve(M: Float[Array, "d d"], b: Float[Array, " d"]) -> Float[Array, " d"]:
    """Solve $Mx = b$ for a symmetric positive definite $M$ by Cholesky, $M = LL^T$.

    Up to 6×6 the factorization and both triangular solves are unrolled into elementwise
    work that XLA fuses (and that batches for free under `vmap`, where LAPACK runs once per
    instance); larger systems use LAPACK (`jax.scipy.linalg.cho_solve`).

    **Arguments:**

    - `M`: symmetric positive definite, shape `(d, d)` (its lower triangle is read).
    - `b`: right-hand side, shape `(d,)`.

    **Returns:**

    $x = M^{-1}b$, shape `(d,)`.
    """
    if not 0 < M.shape[-1] <= _UNROLLED_SOLVE_LIMIT:
        return jsl.cho_solve(jsl.cho_factor(M, lower=True), b)
    return _unrolled_spd_solve(M, b)


@jax.custom_jvp
def _unrolled_spd_solve(M, b):
    """`spd_solve` for small `d`: the Cholesky factor row by row, then $Ly = b$ and
    $L^Tx = y$, every entry a scalar expression."""
    d = M.shape[-1]
    L = {}
    for j in range(d):
        L[j, j] = jnp.sqrt(M[j, j] - sum(L[j, k] * L[j, k] for k in range(j)))
        for i in range(j + 1, d):
            L[i, j] = (M[i, j] - sum(L[i, k] * L[j, k] for k in range(j))) / L[j, j]
    y = []
    for i in range(d):
        y.append((b[i] - sum(L[i, k] * y[k] for k in range(i))) / L[i, i])
    x = [None] * d
    for i in reversed(range(d)):
        x[i] = (y[i] - sum(L[k, i] * x[k] for k in range(i + 1, d))) / L[i, i]
    # The barrier keeps XLA from fusing the whole factorization into every consumer of x,
    # each then recomputing it, which slows a whole solver step.
    return lax.optimization_barrier(jnp.stack(x))


@_unrolled_spd_solve.defjvp
def _unrolled_spd_solve_jvp(primals, tangents):
    # $dx = M^{-1}(db - dM\,x)$: the tangent is one more solve with the same factor (which
    # XLA computes once), linear in $(dM, db)$, so its transpose is a solve too; autodiff of
    # the factorization itself would differentiate every square root and division.
    (M, b), (dM, db) = primals, tangents
    x = _unrolled_spd_solve(M, b)
    return x, _unrolled_spd_solve(M, db - matmul(dM, x))


# Taylor degree and largest scaling of `expm`: at ‖A‖∞ ≤ 1/4 the remainder of the degree-12
# polynomial is ≤ e^{1/4} 4^{-13}/13! ≈ 2.6e-18, below half an ulp. Every squaring is
# evaluated (and selected), so their number bounds the cost: 10 reach ‖S‖∞ = 256; more
# squarings slow the affine body's vector field down.
_EXPM_DEGREE = 12
_EXPM_SQUARINGS = 10


def expm(S: Float[Array, "n n"]) -> Float[Array, "n n"]:
    r"""Matrix exponential of a small square matrix by Taylor series, scaling and squaring.

    $e^S = \big(T_{12}(2^{-k}S)\big)^{2^k}$ with $T_{12}$ the degree-12 Taylor polynomial
    (Horner's scheme) and $k = \max(0, \lceil\log_2 4\|S\|_\infty\rceil)$, so that
    $\|2^{-k}S\|_\infty \le 1/4$ and the truncation is below rounding (Moler & Van Loan,
    *Nineteen dubious ways to compute the exponential of a matrix*, method 3).
    `jax.scipy.linalg.expm` chooses among five Padé orders with a `switch`, solves
    $Q^{-1}P$ by LU and squares under a `cond` per step, which traces, compiles and
    differentiates slower. The affine body's stretch, its divided differences (batches of
    bidiagonal matrices) and the autodiff behind its jet's derivatives use this one. Here
    the work is eleven products, ten squarings and selects, differentiable in both modes;
    the products stay `dot`s (as fused broadcasts they are slower).
    $k$ is piecewise constant in $S$ and is not differentiated: the result is $e^S$ for
    every $k$, so its derivative is that of $e^S$.

    **Arguments:**

    - `S`: a small $n\times n$ matrix.

    **Returns:**

    $e^S$; NaN where $\|S\|_\infty > 256$, past the ten squarings.
    """
    norm = jnp.max(jnp.sum(jnp.abs(S), axis=-1))
    tiny = jnp.finfo(S.dtype).tiny
    k = lax.stop_gradient(jnp.clip(jnp.ceil(jnp.log2(4.0 * jnp.maximum(norm, tiny))), 0, None))
    A = S * jnp.exp2(-k)
    eye = jnp.eye(S.shape[-1], dtype=S.dtype)
    T = eye + A / _EXPM_DEGREE
    for j in range(_EXPM_DEGREE - 1, 0, -1):
        T = eye + (A @ T) / j
    for i in range(_EXPM_SQUARINGS):
        T = jnp.where(i < k, T @ T, T)
    return jnp.where(k <= _EXPM_SQUARINGS, T, jnp.nan)
