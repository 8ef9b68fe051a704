"""An affinely deformable body: x = c + F X (seed 004, §4; DESIGN §2)."""

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .. import lie
from .._linalg import expm
from ._base import AbstractSystem
from ._validation import check_mass, check_shape, check_spd

_SYM_ROWS = (0, 1, 2, 0, 0, 1)
_SYM_COLS = (0, 1, 2, 1, 2, 2)


def symmetric_from_vector(q: Float[Array, "... 6"]) -> Float[Array, "... 3 3"]:
    """The symmetric 3×3 matrix with diagonal $(q_0, q_1, q_2)$ and off-diagonal
    $(q_3, q_4, q_5)$ at positions (0,1), (0,2), (1,2)."""
    S = jnp.zeros((*q.shape[:-1], 3, 3), q.dtype)
    S = S.at[..., _SYM_ROWS, _SYM_COLS].set(q)
    return S.at[..., _SYM_COLS, _SYM_ROWS].set(q)


def stretch(q: Float[Array, " 6"]) -> Float[Array, "3 3"]:
    """The stretch $U(q) = \\exp(\\operatorname{sym}(q))$: symmetric positive definite for every $q$.

    The matrix exponential of a symmetric matrix cannot leave the SPD cone, so no shape
    coordinate value leaves it; $q = 0$ is the undeformed body. Computed by `expm`
    (Taylor series, scaling and squaring), which is NaN past
    $\\|\\operatorname{sym}(q)\\|_\\infty = 256$: principal stretches beyond $e^{\\pm 256}$.
    """
    return expm(symmetric_from_vector(q))


class AffineBody(AbstractSystem):
    """An affinely deformable body, $x = c + F X$ with $F = R\\,U(q)$ (seed 004, §4, (4.3)).

    Kinetic energy $T = \\tfrac12 m|\\dot c|^2 + \\tfrac12\\operatorname{tr}(\\dot F E \\dot F^T)$ with
    $E = \\int X X^T dm$. The section is $r(q) = (U(q), c = 0)$: the section frame sits at
    the centre of mass, so with $g = (R, c)$ and $\\xi = (\\omega, v)$,
    $\\dot c = R v$ and $\\dot F = R(\\tilde\\omega U + \\dot U)$.

    **Arguments:**

    - `mass`: $m > 0$.
    - `second_moment`: $E$ (3×3, symmetric positive definite) of the reference
      configuration about its centre of mass; a solid ellipsoid with semi-axes $a_i$ has
      $E = \\tfrac{m}{5}\\operatorname{diag}(a_i^2)$.
    """

    mass: Float[Array, ""]
    second_moment: Float[Array, "3 3"]

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
        # Ḟ = R W·(ω, q̇) with W = [ê_1 U, ê_2 U, ê_3 U, dU/dq_1, ..., dU/dq_6].
        W = jnp.concatenate([lie.hat(jnp.eye(3, dtype=q.dtype)) @ U, jnp.moveaxis(dU, -1, 0)])
        K = jnp.einsum("aij,jk,bik->ab", W, self.second_moment, W)  # tr(W_a E W_bᵀ)
        d = self.shape_dim
        G = jnp.zeros((6 + d, 6 + d), q.dtype)
        G = G.at[:3, :3].set(K[:3, :3]).at[:3, 6:].set(K[:3, 3:])
        G = G.at[6:, :3].set(K[3:, :3]).at[6:, 6:].set(K[3:, 3:])
        return G.at[3:6, 3:6].set(self.mass * jnp.eye(3, dtype=q.dtype))
