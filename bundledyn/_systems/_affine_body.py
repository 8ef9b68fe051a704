"""An affinely deformable body: x = c + F X (seed 004, §4; architecture §2)."""

import itertools
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .. import lie
from .._linalg import expm
from .._validation import check_shape
from ._base import AbstractInertialSystem
from ._metric_jet import DenseMetricJet
from ._validation import check_mass, check_spd, checked_mass, checked_spd

_SYM_ROWS = (0, 1, 2, 0, 0, 1)
_SYM_COLS = (0, 1, 2, 1, 2, 2)


def symmetric_from_vector(q: Float[Array, "... 6"]) -> Float[Array, "... 3 3"]:
    """The symmetric 3×3 matrix with diagonal $(q_0, q_1, q_2)$ and off-diagonal
    $(q_3, q_4, q_5)$ at positions (0,1), (0,2), (1,2)."""
    S = jnp.zeros((*q.shape[:-1], 3, 3), q.dtype)
    S = S.at[..., _SYM_ROWS, _SYM_COLS].set(q)
    return S.at[..., _SYM_COLS, _SYM_ROWS].set(q)


def stretch(q: Float[Array, " 6"]) -> Float[Array, "3 3"]:
    r"""The stretch $U(q) = \exp(\operatorname{sym}(q))$: symmetric positive definite for every $q$.

    The matrix exponential of a symmetric matrix cannot leave the SPD cone, so no shape
    coordinate value leaves it; $q = 0$ is the undeformed body. Computed by `expm`
    (Taylor series, scaling and squaring), which is NaN past
    $\|\operatorname{sym}(q)\|_\infty = 256$: principal stretches beyond $e^{\pm 256}$.
    """
    return expm(symmetric_from_vector(q))


def _divided_differences_of_exp(lam: Float[Array, " 3"], order: int):
    r"""The divided differences of $\exp$ at the eigenvalues, up to `order` (static, 1–4).

    Opitz: the exponential of the bidiagonal matrix with $x_0, \dots, x_r$ on its diagonal
    and ones above holds $e^{[x_0, \dots, x_r]}$ at $(0, r)$, for equal arguments too
    (where quotients of differences cancel). They are symmetric in their arguments, so one
    exponential per multiset of eigenvalue indices serves all its orderings: 10 for order 2
    (of 27 orderings), 15 for order 3 (of 81). A sorted multiset padded with the largest index holds every shorter one as
    its leading part.

    **Returns:**

    A list: `D[r - 1][i_0, ..., i_r]` $= e^{[\lambda_{i_0}, \dots, \lambda_{i_r}]}$.
    """
    n = order + 1
    multisets = list(itertools.combinations_with_replacement(range(3), n))
    diagonals = jax.vmap(jnp.diag)(lam[np.array(multisets)])
    B = diagonals + jnp.broadcast_to(jnp.eye(n, k=1, dtype=lam.dtype), diagonals.shape)
    first_row = jax.vmap(expm)(B)[:, 0]  # [m, r] = e^{[x_0..x_r]}, x the multiset m
    row = {m: i for i, m in enumerate(multisets)}

    def table(r):
        rows = [
            row[(*sorted(t), *(2,) * (order - r))]
            for t in itertools.product(range(3), repeat=r + 1)
        ]
        return first_row[np.array(rows), r].reshape((3,) * (r + 1))

    return [table(r) for r in range(1, n)]


def _eigen_frame(q):
    r"""$\operatorname{sym}(q) = V\Lambda V^T$ and the coordinate directions in that frame,
    $\tilde E_k = V^T(\partial_k \operatorname{sym})V$, `(6, 3, 3)`."""
    lam, V = jnp.linalg.eigh(symmetric_from_vector(q))
    basis = symmetric_from_vector(jnp.eye(6, dtype=q.dtype))
    return lam, V, jnp.einsum("ai,kab,bj->kij", V, basis, V)


@jax.custom_jvp
def stretch_derivatives(q: Float[Array, " 6"]):
    r"""$U(q)$ with its first and second derivatives, by the Daleckii–Krein formulas.

    (Daleckiĭ & Kreĭn 1965; Higham, *Functions of Matrices*, 2008, ch. 3, where the divided
    differences of Opitz's bidiagonal form are too.)

    With $\operatorname{sym}(q) = V\Lambda V^T$ and $\tilde E_k = V^T (\partial_k\operatorname{sym}) V$,
    $\partial_k U = V\,(e^{[\lambda_i,\lambda_j]}\,\tilde E_{k,ij})\,V^T$ and
    $\partial_k\partial_l U = V\big(\sum_m e^{[\lambda_i,\lambda_m,\lambda_j]}
    (\tilde E_{k,im}\tilde E_{l,mj} + \tilde E_{l,im}\tilde E_{k,mj})\big)V^T$: one symmetric
    eigendecomposition and elementwise work, where forward-mode autodiff of `expm` twice
    carries 49 tangent streams through its 21 products. Differentiated, the tangent holds
    the third derivatives in the same form (`_stretch_third_derivatives`); the eigenvectors,
    undefined where eigenvalues repeat (at $q = 0$ all three do), are never differentiated.

    One exception, JAX's (0.10): when reverse mode linearizes a `lax.scan`, JAX hoists loop
    invariants by partially evaluating the primal loop body with the carry unknown, and
    that inlines every custom-JVP function whose inputs depend on the carry, rule dropped.
    Differentiating that primal loop again (`jax.hessian`, or `jax.grad` of a gradient)
    then differentiates this function's eigenvectors: through the Lie-group solvers'
    stage loop such second derivatives are NaN where eigenvalues repeat and lose digits
    near it (1e-10 relative at $|q| = 10^{-9}$). Forward-first ones
    (`jax.jacfwd(jax.jacfwd(f))`, `jax.jacrev(jax.jacfwd(f))`) keep this rule and are
    finite and correct there.

    **Arguments:**

    - `q`: shape coordinates, `(6,)`.

    **Returns:**

    `(U, dU, d2U)`: `U` `(3, 3)`; `dU[..., k]` $= \partial_k U$, `(3, 3, 6)`;
    `d2U[..., k, l]` $= \partial_k\partial_l U$, `(3, 3, 6, 6)` (the layout of `jax.jacfwd`).
    """
    lam, V, E = _eigen_frame(q)
    D1, D2 = _divided_differences_of_exp(lam, 2)
    U = (V * jnp.exp(lam)[None, :]) @ V.T
    return U, _daleckii_krein(V, E, D1), _daleckii_krein(V, E, D2)


@stretch_derivatives.defjvp
def _stretch_derivatives_jvp(primals, tangents):
    (q,), (q_dot,) = primals, tangents
    U, dU, d2U = stretch_derivatives(q)
    return (U, dU, d2U), (dU @ q_dot, d2U @ q_dot, _stretch_third_derivatives(q) @ q_dot)


def _daleckii_krein(V, E, D):
    r"""The $r$-th derivatives of $U$ from the $r$-th divided differences `D` (Daleckii–Krein).

    $\partial_{k_1}\cdots\partial_{k_r} U = V\big(\sum_{m}
    e^{[\lambda_i,\lambda_{m_1},\dots,\lambda_{m_{r-1}},\lambda_j]} \sum_\sigma
    \tilde E_{\sigma_1,im_1}\tilde E_{\sigma_2,m_1m_2}\cdots\tilde E_{\sigma_r,m_{r-1}j}\big)V^T$
    over the orderings $\sigma$ of $(k_1, \dots, k_r)$; $r$ = `D.ndim - 1`, 1–4.

    **Returns:**

    `(3, 3, 6, ..., 6)`, the layout of $r$ nested `jax.jacfwd`s.
    """
    order = D.ndim - 1
    nodes = ("i", *"mno"[: order - 1], "j")
    directions = "klps"[:order]
    steps = ",".join(
        f"{k}{a}{b}" for k, a, b in zip(directions, nodes[:-1], nodes[1:], strict=True)
    )
    ordered = jnp.einsum(f"{''.join(nodes)},{steps}->{directions}ij", D, *[E] * order)
    summed = sum(
        jnp.transpose(ordered, (*o, order, order + 1)) for o in itertools.permutations(range(order))
    )
    return jnp.einsum(f"ai,{directions}ij,bj->ab{directions}", V, summed, V)


def _stretch_higher_derivatives(q, order):
    lam, V, E = _eigen_frame(q)
    return _daleckii_krein(V, E, _divided_differences_of_exp(lam, order)[-1])


@jax.custom_jvp
def _stretch_third_derivatives(q):
    r"""$\partial_k\partial_l\partial_p U$, `(3, 3, 6, 6, 6)`, by `_daleckii_krein`. The
    tangent of `stretch_derivatives` is this contracted with $\dot q$, a product JAX
    transposes without looking inside, so that differentiating a gradient never reaches
    the eigenvectors either; its own tangent is the fourth derivatives contracted the same
    way."""
    return _stretch_higher_derivatives(q, 3)


@_stretch_third_derivatives.defjvp
def _stretch_third_derivatives_jvp(primals, tangents):
    (q,), (q_dot,) = primals, tangents
    return _stretch_third_derivatives(q), _stretch_fourth_derivatives(q) @ q_dot


@jax.custom_jvp
def _stretch_fourth_derivatives(q):
    r"""$\partial_k\partial_l\partial_p\partial_s U$, `(3, 3, 6, 6, 6, 6)`, by
    `_daleckii_krein`. Reached by second-order differentiation of the vector field (a
    Hessian of a step), where it compiles and runs faster than autodiff of `expm`, and
    stays exact where eigenvalues repeat."""
    return _stretch_higher_derivatives(q, 4)


@_stretch_fourth_derivatives.defjvp
def _stretch_fourth_derivatives_jvp(primals, tangents):
    # Reached only by third-order differentiation: autodiff of `expm`, not of eigenvectors.
    return jax.jvp(jax.jacfwd(jax.jacfwd(jax.jacfwd(jax.jacfwd(stretch)))), primals, tangents)


class AffineBody(AbstractInertialSystem):
    r"""An affinely deformable body, $x = c + F X$ with $F = R\,U(q)$ (seed 004, §4, (4.3)).

    Kinetic energy $T = \tfrac12 m|\dot c|^2 + \tfrac12\operatorname{tr}(\dot F E \dot F^T)$ with
    $E = \int X X^T dm$. The section is $r(q) = (U(q), c = 0)$: the section frame sits at
    the centre of mass, so with $g = (R, c)$ and $\xi = (\omega, v)$,
    $\dot c = R v$ and $\dot F = R(\tilde\omega U + \dot U)$.

    **Arguments:**

    - `mass`: $m > 0$.
    - `second_moment`: $E$ (3×3, symmetric positive definite) of the reference
      configuration about its centre of mass; a solid ellipsoid with semi-axes $a_i$ has
      $E = \tfrac{m}{5}\operatorname{diag}(a_i^2)$.
    """

    mass: Float[Array, ""]
    second_moment: Float[Array, "3 3"]
    fixed_centres: ClassVar[bool] = True

    def __init__(self, mass, second_moment):
        self.mass = jnp.asarray(mass, dtype=float)
        self.second_moment = jnp.asarray(second_moment, dtype=float)

    def __check_init__(self):
        check_shape("AffineBody.mass", self.mass, ())
        check_shape("AffineBody.second_moment", self.second_moment, (3, 3))
        check_mass("AffineBody.mass", self.mass)
        check_spd("AffineBody.second_moment", self.second_moment)

    @property
    def shape_dim(self) -> int:
        return 6

    def metric(self, q):
        U = stretch(q)
        dU = jax.jacfwd(stretch)(q)  # (3, 3, 6): dU[..., k] = dU/dq_k
        return self._metric_from(self._velocity_maps(U, dU))

    def metric_jet(self, q):
        r"""$G(q)$ and $\partial G/\partial q_l$ in closed form, from `stretch_derivatives`.

        With $W$ as in `metric`, $K_{ab} = \operatorname{tr}(W_a E W_b^T)$ and
        $\partial_l K_{ab} = \operatorname{tr}(\partial_l W_a E W_b^T) + (a \leftrightarrow b)$,
        where $\partial_l W = [\hat e_i\,\partial_l U,\ \partial_l\partial_k U]$.
        """
        U, dU, d2U = stretch_derivatives(q)
        W = self._velocity_maps(U, dU)
        dW = jax.vmap(self._velocity_maps, in_axes=(-1, -1))(dU, d2U)  # (l, a, 3, 3)
        P = jnp.einsum("laij,jk,bik->lab", dW, self.second_moment, W)
        dK = P + jnp.swapaxes(P, 1, 2)
        zero = jnp.zeros((), q.dtype)
        return DenseMetricJet(self._metric_from(W), jax.vmap(lambda K: self._assemble(K, zero))(dK))

    def pseudo_inertias(self):
        E, m = self.second_moment, self.mass
        zero = jnp.zeros((3, 1), E.dtype)
        top = jnp.concatenate([E, zero], axis=1)
        return jnp.concatenate([top, jnp.concatenate([zero.T, m[None, None]], axis=1)])[None]

    def with_pseudo_inertias(self, P) -> "AffineBody":
        """The body with the mass $P_{44}$ and the second moment about the centre of mass of
        `P` (an offset centre in `P` is dropped: the section frame sits at the centre)."""
        m, h = P[0, 3, 3], P[0, :3, 3]
        E = P[0, :3, :3] - h[:, None] * h[None, :] / m
        return eqx.tree_at(lambda b: (b.mass, b.second_moment), self, (m, E))

    def checked(self) -> "AffineBody":
        mass = checked_mass("AffineBody.mass", self.mass)
        second_moment = checked_spd("AffineBody.second_moment", self.second_moment)
        return eqx.tree_at(lambda b: (b.mass, b.second_moment), self, (mass, second_moment))

    @staticmethod
    def _velocity_maps(U, dU):
        r"""$W = [\hat e_1 U, \hat e_2 U, \hat e_3 U, \partial_1 U, \dots, \partial_6 U]$, with
        $\dot F = R\,W\cdot(\omega, \dot q)$."""
        return jnp.concatenate([lie.hat(jnp.eye(3, dtype=U.dtype)) @ U, jnp.moveaxis(dU, -1, 0)])

    def _metric_from(self, W):
        K = jnp.einsum("aij,jk,bik->ab", W, self.second_moment, W)  # tr(W_a E W_bᵀ)
        return self._assemble(K, self.mass)

    @staticmethod
    def _assemble(K, mass):
        r"""$G$ from $K$ (rows and columns $\omega, \dot q$) and the translational block $m\mathbf 1$."""
        G = jnp.zeros((12, 12), K.dtype)
        G = G.at[:3, :3].set(K[:3, :3]).at[:3, 6:].set(K[:3, 3:])
        G = G.at[6:, :3].set(K[3:, :3]).at[6:, 6:].set(K[3:, 3:])
        return G.at[3:6, 3:6].set(mass * jnp.eye(3, dtype=K.dtype))
