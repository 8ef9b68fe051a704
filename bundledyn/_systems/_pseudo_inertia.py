r"""A body's ten inertial parameters as a 4×4 pseudo-inertia, and its log-Cholesky coordinates.

A rigid body of mass $m$, centre of mass $c$ and rotational inertia $J_c$ about $c$ (in its
own frame) has the second moment $\Sigma = \int x x^T dm = \Sigma_c + m c c^T$ about its
frame's origin, $\Sigma_c = \tfrac12\operatorname{tr}(J_c)\mathbf 1 - J_c$, and the
pseudo-inertia

$$P = \int \begin{bmatrix} x \\ 1\end{bmatrix}\begin{bmatrix} x \\ 1\end{bmatrix}^T dm
    = \begin{bmatrix} \Sigma & m c \\ m c^T & m\end{bmatrix}.$$

A mass distribution has these parameters iff $P \succ 0$ (Wensing, Kim & Slotine 2017): then
$m > 0$ and $J_c$ is positive definite with the triangle inequalities. Writing
$P = UU^T$ with the upper-triangular
$U = e^\alpha\begin{bmatrix} e^{d_1} & s_{12} & s_{13} & t_1 \\ 0 & e^{d_2} & s_{23} & t_2 \\
0 & 0 & e^{d_3} & t_3 \\ 0 & 0 & 0 & 1 \end{bmatrix}$ gives the log-Cholesky coordinates
$\theta = (\alpha, d_1, d_2, d_3, s_{12}, s_{23}, s_{13}, t_1, t_2, t_3)$ (Rucker & Wensing
2022): every real 10-vector is a physical body and every physical body has one. Then
$m = e^{2\alpha}$, $c = t$ and $\Sigma_c = m AA^T$ with $A$ the upper-left 3×3 block of
$U e^{-\alpha}$.

The affinely deformable body's mass data, $m$ and $E = \int X X^T dm$ about its centre of
mass, is the same matrix with $c = 0$: $P = \operatorname{diag}(E, m)$, and its coordinates
are $\theta$ with $t = 0$.
"""

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

__all__ = [
    "inertial_from_pseudo_inertia",
    "log_cholesky_from_pseudo_inertia",
    "pseudo_inertia",
    "pseudo_inertia_from_log_cholesky",
]

_UPPER = ((0, 1), (1, 2), (0, 2))  # the order of s12, s23, s13 in θ
# Each function below is compiled whole (`jax.jit`): called outside a traced function, as
# model construction and identification reports call them, it runs as one program instead
# of one per operation (each compiled on first use).


def _eye3(like):
    return jnp.broadcast_to(jnp.eye(3, dtype=like.dtype), (*like.shape[:-2], 3, 3))


@jax.jit
def pseudo_inertia(mass, com, inertia) -> Float[Array, "... 4 4"]:
    r"""The pseudo-inertia $P$ of bodies of mass $m$, centre of mass $c$ and inertia $J_c$.

    **Arguments:**

    - `mass`: $m$, shape `(...)`.
    - `com`: $c$ in the body frame, shape `(..., 3)`.
    - `inertia`: $J_c$ about the centre of mass, in body axes, shape `(..., 3, 3)`.

    **Returns:**

    $P = \begin{bmatrix}\Sigma_c + m cc^T & mc\\ mc^T & m\end{bmatrix}$, shape `(..., 4, 4)`.
    """
    m = jnp.asarray(mass, dtype=float)
    c = jnp.asarray(com, dtype=float)
    J = jnp.asarray(inertia, dtype=float)
    trace = jnp.trace(J, axis1=-2, axis2=-1)[..., None, None]
    sigma = 0.5 * trace * _eye3(J) - J + m[..., None, None] * c[..., :, None] * c[..., None, :]
    h = m[..., None] * c
    top = jnp.concatenate([sigma, h[..., :, None]], axis=-1)
    bottom = jnp.concatenate([h, m[..., None]], axis=-1)[..., None, :]
    return jnp.concatenate([top, bottom], axis=-2)


@jax.jit
def inertial_from_pseudo_inertia(P: Float[Array, "... 4 4"]):
    r"""Mass, centre of mass and inertia about it of pseudo-inertias $P$ (the inverse of `pseudo_inertia`).

    **Arguments:**

    - `P`: pseudo-inertias, shape `(..., 4, 4)`.

    **Returns:**

    `(mass, com, inertia)`, shapes `(...)`, `(..., 3)`, `(..., 3, 3)`:
    $m = P_{44}$, $c = P_{1:3,4}/m$, $J_c = \operatorname{tr}(\Sigma_c)\mathbf 1 - \Sigma_c$ with
    $\Sigma_c = P_{1:3,1:3} - m cc^T$.
    """
    m = P[..., 3, 3]
    c = P[..., :3, 3] / m[..., None]
    sigma_c = P[..., :3, :3] - m[..., None, None] * c[..., :, None] * c[..., None, :]
    trace = jnp.trace(sigma_c, axis1=-2, axis2=-1)[..., None, None]
    return m, c, trace * _eye3(sigma_c) - sigma_c


@jax.jit
def pseudo_inertia_from_log_cholesky(theta: Float[Array, "... 10"]) -> Float[Array, "... 4 4"]:
    r"""The pseudo-inertia $P = UU^T$ of log-Cholesky coordinates $\theta$ (module docstring).

    Every real `theta` gives a positive definite $P$: a physical body.

    **Arguments:**

    - `theta`: $(\alpha, d_1, d_2, d_3, s_{12}, s_{23}, s_{13}, t_1, t_2, t_3)$, shape `(..., 10)`.

    **Returns:**

    $P$, shape `(..., 4, 4)`.
    """
    theta = jnp.asarray(theta, dtype=float)
    alpha, d, s, t = theta[..., 0], theta[..., 1:4], theta[..., 4:7], theta[..., 7:10]
    A = jnp.zeros((*theta.shape[:-1], 3, 3), theta.dtype)
    A = A.at[..., (0, 1, 2), (0, 1, 2)].set(jnp.exp(d))
    A = A.at[..., (0, 1, 0), (1, 2, 2)].set(s)
    m = jnp.exp(2.0 * alpha)[..., None, None]
    sigma = m * (A @ jnp.swapaxes(A, -1, -2) + t[..., :, None] * t[..., None, :])
    h = m[..., 0] * t
    top = jnp.concatenate([sigma, h[..., :, None]], axis=-1)
    bottom = jnp.concatenate([h, m[..., 0]], axis=-1)[..., None, :]
    return jnp.concatenate([top, bottom], axis=-2)


def _upper_cholesky(S):
    """The upper-triangular $A$ with $S = AA^T$ (the Cholesky factor of the reversed matrix)."""
    flip = jnp.flip(jnp.flip(S, -1), -2)
    L = jnp.linalg.cholesky(flip)
    return jnp.flip(jnp.flip(L, -1), -2)


@jax.jit
def log_cholesky_from_pseudo_inertia(P: Float[Array, "... 4 4"]) -> Float[Array, "... 10"]:
    r"""The log-Cholesky coordinates $\theta$ of positive definite pseudo-inertias $P$.

    NaN where $P$ is not positive definite (no physical body has it).

    **Arguments:**

    - `P`: pseudo-inertias, shape `(..., 4, 4)`.

    **Returns:**

    $\theta$, shape `(..., 10)`; `pseudo_inertia_from_log_cholesky` inverts it.
    """
    m, c, _ = inertial_from_pseudo_inertia(P)
    sigma_c = P[..., :3, :3] - m[..., None, None] * c[..., :, None] * c[..., None, :]
    A = _upper_cholesky(sigma_c / m[..., None, None])
    d = jnp.log(jnp.diagonal(A, axis1=-2, axis2=-1))
    s = jnp.stack([A[..., i, j] for i, j in _UPPER], axis=-1)
    return jnp.concatenate([0.5 * jnp.log(m)[..., None], d, s, c], axis=-1)
