r"""The metric of a tree of bodies and its derivative contractions, in closed form (screw theory)."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .. import lie
from .._lie._so3 import so3_dexp_second_derivative_along
from .._linalg import einsum, matmul, take
from ._metric_jet import AbstractMetricJet, derivative_by_along


def composite_metric(inertias, Z, path, at_or_above, strictly_above):
    r"""$G$ from composite (subtree) inertias, as in the composite-rigid-body algorithm.

    With $I^c_l = \sum_{a \succeq l} \tilde M_a$ the inertia of the bodies joint column $l$
    moves: $I_r = \sum_a \tilde M_a$, $B_l = I^c_l Z_l$ and, for $j$ at or above $l$,
    $M_{jl} = Z_j^T I^c_l Z_l$ (zero for columns on different branches). This equals
    $\sum_a \hat J_a^T \tilde M_a \hat J_a$ (`Multibody.metric`) at $O(nd + d^2)$ cost instead of
    $O(n d^2)$.
    """
    composite = jnp.einsum("al,aij->lij", path, inertias)
    B = jnp.einsum("lij,jl->il", composite, Z)
    C = matmul(Z.T, B)  # C[j, l] = Z_j · I^c_l Z_l
    M = at_or_above * C + (strictly_above * C).T
    top = jnp.concatenate([jnp.sum(inertias, axis=0), B], axis=1)
    return jnp.concatenate([top, jnp.concatenate([B.T, M], axis=1)], axis=0)


class BallColumnDerivative(eqx.Module):
    r"""$\partial Z_j/\partial q_m$ of the ball joints' own columns, kept per joint.

    A ball joint's three columns depend on its own three coordinates only (through its
    $\operatorname{dexp}$), so of the $d\times 6\times d$ array of derivatives only
    $3\times 3$ twists per joint are not zero: `values[k, l, i]` $= \partial Z_{c_{ki}} /
    \partial q_{c_{kl}}$ with $c_k$ = `columns[k]` joint $k$'s coordinates. The two
    contractions the metric jet needs are formed from these blocks and placed among the
    $d$ columns by constant slices. For the jet's second derivatives (the next derivative
    of each joint's $\operatorname{dexp}$, `so3_dexp_second_derivative_along`) it keeps the
    joints' coordinates, and their rotations and centres in the base frame, which turn a
    rotation axis $\omega$ of the joint's frame into the twist $(R\omega, c\times R\omega)$.
    """

    values: Float[Array, "k 3 3 6"]
    coordinates: Float[Array, "k 3"]
    rotations: Float[Array, "k 3 3"]
    centres: Float[Array, "k 3"]
    columns: tuple[tuple[int, int, int], ...] = eqx.field(static=True)
    shape_dim: int = eqx.field(static=True)

    def _placement(self):
        """For each of the $d$ columns, its row in the flattened blocks, or the zero row."""
        columns = np.array(self.columns).reshape(-1)
        index = np.full(self.shape_dim, columns.size)
        index[columns] = np.arange(columns.size)
        return index

    def _placed(self, blocks, axis):
        """`blocks` with the ball coordinates along `axis` (k·3 of them) spread over all $d$."""
        zero = jnp.zeros_like(take(blocks, [0], axis=axis))
        return take(jnp.concatenate([blocks, zero], axis=axis), self._placement(), axis=axis)

    def _own(self, x, axis=0):
        """Each joint's own coordinates of `x` (along `axis`), shape `(k, 3)` there."""
        return take(x, np.array(self.columns), axis=axis)

    def _in_base(self, axes):
        r"""Rotations about each joint's centre as base-frame twists: `axes` `(r, k, l, 3)`
        in the joints' frames, returned `(r, k, l, 6)`."""
        w = sum(self.rotations[None, :, None, :, j] * axes[..., j, None] for j in range(3))
        centres = jnp.broadcast_to(self.centres[None, :, None, :], axes.shape)
        return jnp.concatenate([w, jnp.cross(centres, w)], axis=-1)

    def along(self, u):
        r"""$\sum_m u_m\,\partial Z_j/\partial q_m$, shape `(6, d)`."""
        blocks = jnp.einsum("kl,klix->kix", self._own(u), self.values)
        return self._placed(blocks.reshape(-1, 6), axis=0).T

    def _blocks(self, v):
        r"""$\sum_i v_{ki}\,\partial Z_{c_{ki}}/\partial q_{c_{kl}}$ for the joints' own
        coordinates `v` `(r, k, 3)` of each row: shape `(r, k, l, 6)`."""
        return jnp.einsum("klix,rki->rklx", self.values, v)

    def applied(self, V):
        r"""$\sum_j (\partial Z_j/\partial q_m) v_j$ for each row $v$ of `V` `(r, d)`: shape `(r, d, 6)`."""
        blocks = self._blocks(self._own(V, axis=1))
        return self._placed(blocks.reshape(V.shape[0], -1, 6), axis=1)

    def applied_along(self, u, W_columns, V):
        r"""$\partial_u$ of `applied(V)` at fixed `V`.

        The joint's node moves with the twist $W$ of the joints at or above it, which turns
        each block by $\operatorname{ad}_W$, and its own coordinates move its
        $\operatorname{dexp}$ (`so3_dexp_second_derivative_along`).

        **Arguments:**

        - `u`: the shape velocity, shape `(d,)`.
        - `W_columns`: for each column, the twist of the joints at or above it, `(d, 6)`.
        - `V`: as in `applied`.
        """
        W = take(W_columns, np.array(self.columns)[:, 0])[None, :, None, :]
        v = self._own(V, axis=1)
        second = so3_dexp_second_derivative_along(self.coordinates, self._own(u), v)
        blocks = lie.bracket(W, self._blocks(v)) + self._in_base(second)
        return self._placed(blocks.reshape(V.shape[0], -1, 6), axis=1)


class TreeMetricJet(AbstractMetricJet):
    r"""The metric jet of a tree of bodies (section at the base), contracted in closed form.

    With $V_a(x) = \hat J_a x$ each body's twist (base frame) for a velocity $x = [\xi; \dot q]$,
    $N_k(x)$ the twist of joint $k$'s parent node and $\Pi_k(x) = \sum_{a \succeq k} \tilde M_a V_a(x)$
    the momentum of the subtree that joint $k$ moves,

    $$x^T \partial_k G\, y = -[Z_k, N_k(x)]\cdot\Pi_k(y) - [Z_k, N_k(y)]\cdot\Pi_k(x)$$

    (plus a ball joint's $\operatorname{dexp}$ term), which follows from `Multibody.metric_jet`'s
    derivatives of $Z$ and $\tilde M_a$ because all terms inside the subtree cancel. Every
    contraction works on per-body 6-vectors; no $(6+d)$-wide matrix per body is formed.
    """

    metric: Float[Array, "6+d 6+d"]
    Z: Float[Array, "6 d"]
    inertias: Float[Array, "n 6 6"]
    ball_dZ: BallColumnDerivative | None
    path: Float[Array, "n d"]
    joints_at_or_above: Float[Array, "d d"]
    strictly_above: Float[Array, "d d"]

    def _twists(self, Z, X):
        r"""$\hat J_a x$ with the columns `Z`, for each row $x$ of `X`: shape (m, n, 6)."""
        return X[:, None, :6] + einsum("il,ml,al->mai", Z, X[:, 6:], self.path)

    def _parent_twists(self, Z, X):
        r"""$N_k(x)$, the twist of joint $k$'s parent node, with the columns `Z`, for each row
        $x$ of `X`: shape (m, d, 6)."""
        return X[:, None, :6] + einsum("ij,mj,jk->mki", Z, X[:, 6:], self.strictly_above)

    def _shape_part(self, X):
        r"""The rows $[0; \dot q]$ of velocities $[\xi; \dot q]$: what moves the columns' rates."""
        return jnp.concatenate([jnp.zeros_like(X[:, :6]), X[:, 6:]], 1)

    def _subtree_sums(self, f):
        r"""$\sum_{a \succeq l} f_a$ for each column $l$ of per-body vectors `f` (m, n, 6): (m, d, 6)."""
        return jnp.einsum("al,mai->mli", self.path, f)

    def _rates(self, u):
        r"""How moving the joints by $u$ moves the tree: for each column the twist $W_j$ of
        the joints at or above it `(d, 6)`, the columns' derivative $\partial_u Z_j =
        [W_j, Z_j]$ (plus a ball joint's $\operatorname{dexp}$ term) `(6, d)`, and each
        body's twist $W_a$ `(n, 6)`."""
        Zu = self.Z * u[None, :]
        # Row j of `joints_at_or_above` (`at_or_above` transposed) marks the joints at or
        # above j. As its own constant XLA lays it out for this product alone; sharing
        # `composite_metric`'s table cost a copy into the other layout on every call.
        W_columns = matmul(self.joints_at_or_above, Zu.T)
        dZ = lie.bracket(W_columns, self.Z.T).T
        if self.ball_dZ is not None:
            dZ = dZ + self.ball_dZ.along(u)
        return W_columns, dZ, einsum("il,al->ai", Zu, self.path)

    def _momenta(self, W, dZ, X):
        r"""Each body's momentum $p_a = \tilde M_a V_a(x)$ and its derivative along $u$,
        $\operatorname{ad}^*_{W_a} p_a + \tilde M_a \delta V_a$ with
        $\delta V_a = (\partial_u \hat J_a)x - [W_a, V_a]$ (`_rates`' `W`, `dZ`): (m, n, 6) each."""
        V = self._twists(self.Z, X)
        p = jnp.einsum("aij,maj->mai", self.inertias, V)
        dV = self._twists(dZ, self._shape_part(X))
        dV = dV - lie.bracket(W, V)
        return p, lie.coad_action(W, p) + jnp.einsum("aij,maj->mai", self.inertias, dV)

    def _column_brackets(self, X):
        r"""$[Z_k, N_k(x)]$ (minus a ball joint's $\operatorname{dexp}$ term) and $N_k(x)$."""
        N = self._parent_twists(self.Z, X)
        ZN = lie.bracket(self.Z.T, N)
        if self.ball_dZ is not None:
            ZN = ZN - self.ball_dZ.applied(X[:, 6:])
        return ZN, N

    def along(self, u):
        return self.along_applied(u, jnp.eye(self.metric.shape[0], dtype=self.metric.dtype))

    def along_applied(self, u, X):
        _, dZ, W = self._rates(u)
        return self._along_applied(dZ, *self._momenta(W, dZ, X))

    def _along_applied(self, dZ, p, f):
        # Moving the joints by u moves body a by W_a and column j by ∂_u Z_j = [W_j, Z_j];
        # then with V = Ĵx and p = M̃V, (∂_u G)x = Σ_a Ĵ_aᵀ ∂_u p_a + [0; ∂_u Z_l · Π_l].
        shape = jnp.einsum("il,mli->ml", self.Z, self._subtree_sums(f)) + jnp.einsum(
            "il,mli->ml", dZ, self._subtree_sums(p)
        )
        return jnp.concatenate([jnp.sum(f, axis=1), shape], axis=1)

    def forms(self, X):
        ZN, _ = self._column_brackets(X)
        Pi = self._subtree_sums(jnp.einsum("aij,maj->mai", self.inertias, self._twists(self.Z, X)))
        half = -jnp.einsum("ikx,jkx->ijk", ZN, Pi)
        return half + jnp.swapaxes(half, 0, 1)

    def forms_along(self, u, X, jet_along):
        r"""$\partial_u$ of `forms(X)`, differentiating $-[Z_k, N_k(x)]\cdot\Pi_k(y)$ factor by
        factor: $\partial_u Z_k$, $\partial_u N_k(x) = N_k(x)$ with the columns $\partial_u Z$
        and no base twist, and $\partial_u \Pi_k(y)$ the subtree sum of `_momenta`' rates
        (the same rates as `along_applied`); `jet_along` is not called."""
        return self.along_both(u, X, jet_along)[1]

    def along_both(self, u, X, jet_along):
        # One `_rates` and `_momenta` for both (`forms_along` alone leaves the first to
        # XLA's dead-code elimination).
        W_columns, dZ, W = self._rates(u)
        p, f = self._momenta(W, dZ, X)
        ZN, N = self._column_brackets(X)
        dN = self._parent_twists(dZ, self._shape_part(X))
        dZN = lie.bracket(dZ.T, N) + lie.bracket(self.Z.T, dN)
        if self.ball_dZ is not None:
            dZN = dZN - self.ball_dZ.applied_along(u, W_columns, X[:, 6:])
        Pi, dPi = self._subtree_sums(p), self._subtree_sums(f)
        half = -jnp.einsum("ikx,jkx->ijk", dZN, Pi) - jnp.einsum("ikx,jkx->ijk", ZN, dPi)
        return self._along_applied(dZ, p, f), half + jnp.swapaxes(half, 0, 1)

    def derivative(self):
        return derivative_by_along(self)
