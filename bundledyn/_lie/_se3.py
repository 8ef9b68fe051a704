r"""The rigid-motion group SE(3) and its Lie algebra, angular part first.

An element is a $4\times4$ homogeneous matrix $g = \begin{pmatrix}R & p\\0 & 1\end{pmatrix}$
acting $x \mapsto Rx + p$; a twist is $\xi = (\omega, v) \in \mathbb R^6$ with
$\hat\xi = \begin{pmatrix}\tilde\omega & v\\ 0 & 0\end{pmatrix}$. Every function accepts
leading batch dimensions and keeps the input dtype.

The block structure $\mathrm{ad}_\xi = \begin{pmatrix}\tilde\omega & 0\\ \tilde v &
\tilde\omega\end{pmatrix}$ is that of the dual numbers $\tilde\omega + \varepsilon\tilde v$,
so any power series $f$ of $\mathrm{ad}_\xi$ is $\begin{pmatrix} f(\tilde\omega) & 0\\
Df(\tilde\omega)[\tilde v] & f(\tilde\omega)\end{pmatrix}$: `se3_dexp` and `se3_dexp_inv`
are computed as one `jax.jvp` of their SO(3) counterparts, and inherit their exactness and
their safe branches.
"""

import jax
import jax.numpy as jnp

from .._linalg import matmul
from ._so3 import (
    _float,
    _so3_exp_and_left_jacobian,
    so3_dexp,
    so3_dexp_inv,
    so3_exp,
    so3_hat,
    so3_left_jacobian_inv,
    so3_log,
    so3_vee,
)

__all__ = [
    "hat",
    "vee",
    "se3_hat",
    "se3_vee",
    "se3_from_rotation_translation",
    "se3_rotation",
    "se3_translation",
    "se3_exp",
    "se3_log",
    "se3_inv",
    "Ad",
    "ad",
    "coAd",
    "coad",
    "bracket",
    "klein",
    "se3_dexp",
    "se3_dexp_inv",
    "dexp",
    "dexp_inv",
    "exp",
    "log",
]


def _block(a, b, c, d):
    """[[a, b], [c, d]] for (..., n, n) blocks."""
    top = jnp.concatenate([a, b], axis=-1)
    bot = jnp.concatenate([c, d], axis=-1)
    return jnp.concatenate([top, bot], axis=-2)


def se3_from_rotation_translation(R, p):
    r"""Homogeneous matrix $\begin{pmatrix}R & p\\0&1\end{pmatrix}$ from $R$ and $p$.

    **Arguments:**

    - `R`: rotation, shape `(..., 3, 3)`.
    - `p`: translation, shape `(..., 3)`.

    **Returns:**

    Array of shape `(..., 4, 4)` (leading dimensions broadcast).
    """
    R = jnp.asarray(R)
    p = jnp.asarray(p)
    dtype = jnp.result_type(R, p)
    batch = jnp.broadcast_shapes(R.shape[:-2], p.shape[:-1])
    R = jnp.broadcast_to(R, batch + (3, 3)).astype(dtype)
    p = jnp.broadcast_to(p, batch + (3,)).astype(dtype)
    bottom = jnp.broadcast_to(jnp.array([0.0, 0.0, 0.0, 1.0], dtype=dtype), batch + (1, 4))
    top = jnp.concatenate([R, p[..., None]], axis=-1)
    return jnp.concatenate([top, bottom], axis=-2)


def se3_rotation(g):
    """Rotation block `g[..., :3, :3]` of a homogeneous matrix.

    **Arguments:**

    - `g`: shape `(..., 4, 4)`.

    **Returns:**

    Shape `(..., 3, 3)`.
    """
    return jnp.asarray(g)[..., :3, :3]


def se3_translation(g):
    """Translation column `g[..., :3, 3]` of a homogeneous matrix.

    **Arguments:**

    - `g`: shape `(..., 4, 4)`.

    **Returns:**

    Shape `(..., 3)`.
    """
    return jnp.asarray(g)[..., :3, 3]


def se3_hat(xi):
    r"""$4\times4$ matrix $\hat\xi = \begin{pmatrix}\tilde\omega & v\\0&0\end{pmatrix}$ of a twist.

    **Arguments:**

    - `xi`: twist $(\omega, v)$, shape `(..., 6)`.

    **Returns:**

    Shape `(..., 4, 4)`.
    """
    xi = jnp.asarray(xi)
    W = so3_hat(xi[..., :3])
    top = jnp.concatenate([W, xi[..., 3:, None]], axis=-1)
    bottom = jnp.zeros(xi.shape[:-1] + (1, 4), dtype=xi.dtype)
    return jnp.concatenate([top, bottom], axis=-2)


def se3_vee(X):
    r"""Inverse of `se3_hat`: the twist $(\omega, v)$ of a $4\times4$ algebra element.

    **Arguments:**

    - `X`: shape `(..., 4, 4)`.

    **Returns:**

    Shape `(..., 6)`.
    """
    X = jnp.asarray(X)
    return jnp.concatenate([so3_vee(X[..., :3, :3]), X[..., :3, 3]], axis=-1)


def _on_algebra(name, x, on_so3, on_se3):
    """Dispatch on a vector's last dimension: 3 (so(3)) or 6 (se(3))."""
    n = jnp.shape(x)[-1]
    if n not in (3, 6):
        raise ValueError(f"{name} expects a last dimension of 3 or 6, got shape {jnp.shape(x)}")
    return on_so3(x) if n == 3 else on_se3(x)


def _on_group(name, X, on_so3, on_se3):
    """Dispatch on a matrix's trailing shape: (3, 3) (SO(3)) or (4, 4) (SE(3))."""
    shape = jnp.shape(X)
    if shape[-2:] not in ((3, 3), (4, 4)):
        raise ValueError(f"{name} expects trailing shape (3, 3) or (4, 4), got {shape}")
    return on_so3(X) if shape[-2:] == (3, 3) else on_se3(X)


def hat(x):
    r"""Hat map, dispatching on the last dimension.

    `(..., 3)` → skew matrix `(..., 3, 3)`; `(..., 6)` twist $(\omega, v)$ → `(..., 4, 4)`
    matrix $\begin{pmatrix}\tilde\omega & v\\0&0\end{pmatrix}$.

    **Arguments:**

    - `x`: shape `(..., 3)` or `(..., 6)`.

    **Returns:**

    Shape `(..., 3, 3)` or `(..., 4, 4)`.
    """
    return _on_algebra("hat", x, so3_hat, se3_hat)


def vee(X):
    r"""Vee map (inverse of `hat`), dispatching on the trailing matrix shape.

    **Arguments:**

    - `X`: shape `(..., 3, 3)` or `(..., 4, 4)`.

    **Returns:**

    Shape `(..., 3)` or `(..., 6)`.
    """
    return _on_group("vee", X, so3_vee, se3_vee)


def se3_exp(xi):
    r"""Exponential map of SE(3), $\exp(\omega, v) = (\exp\tilde\omega,\ J_l(\omega)\,v)$.

    $J_l(\omega) = 1 + \frac{1-\cos\theta}{\theta^2}\tilde\omega
    + \frac{\theta-\sin\theta}{\theta^3}\tilde\omega^2$. Smooth everywhere.

    **Arguments:**

    - `xi`: twist $(\omega, v)$, shape `(..., 6)`.

    **Returns:**

    Homogeneous matrix, shape `(..., 4, 4)`.
    """
    xi = _float(xi)
    w, v = xi[..., :3], xi[..., 3:]
    R, V = _so3_exp_and_left_jacobian(w)
    p = jnp.einsum("...ij,...j->...i", V, v)
    return se3_from_rotation_translation(R, p)


def se3_log(g):
    r"""Logarithm of SE(3): $(\omega, v)$ with $\omega = \log R$, $v = J_l(\omega)^{-1} p$.

    Uses `so3_log` (see there for the branches and for the value at exactly
    $\theta = \pi$, where the logarithm is two-valued). $|\omega| \le \pi$.

    **Arguments:**

    - `g`: homogeneous matrix, shape `(..., 4, 4)`.

    **Returns:**

    Twist, shape `(..., 6)`.
    """
    g = _float(g)
    w = so3_log(g[..., :3, :3])
    v = jnp.einsum("...ij,...j->...i", so3_left_jacobian_inv(w), g[..., :3, 3])
    return jnp.concatenate([w, v], axis=-1)


def se3_inv(g):
    r"""Inverse $(R, p)^{-1} = (R^T, -R^T p)$ of a homogeneous matrix.

    **Arguments:**

    - `g`: shape `(..., 4, 4)`.

    **Returns:**

    Shape `(..., 4, 4)`.
    """
    g = jnp.asarray(g)
    RT = jnp.swapaxes(g[..., :3, :3], -1, -2)
    p = -jnp.einsum("...ij,...j->...i", RT, g[..., :3, 3])
    return se3_from_rotation_translation(RT, p)


def exp(x):
    """`so3_exp` for `(..., 3)`, `se3_exp` for `(..., 6)`.

    **Arguments:**

    - `x`: shape `(..., 3)` or `(..., 6)`.

    **Returns:**

    Shape `(..., 3, 3)` or `(..., 4, 4)`.
    """
    return _on_algebra("exp", x, so3_exp, se3_exp)


def log(g):
    """`so3_log` for `(..., 3, 3)`, `se3_log` for `(..., 4, 4)`.

    **Arguments:**

    - `g`: shape `(..., 3, 3)` or `(..., 4, 4)`.

    **Returns:**

    Shape `(..., 3)` or `(..., 6)`.
    """
    return _on_group("log", g, so3_log, se3_log)


def Ad(g):
    r"""Adjoint matrix $\mathrm{Ad}_g = \begin{pmatrix}R & 0\\ \tilde pR & R\end{pmatrix}$.

    $\mathrm{Ad}_g(\omega, v) = (R\omega, Rv + p\times R\omega)$, equivalently
    $(\mathrm{Ad}_g\xi)^\wedge = g\hat\xi g^{-1}$. For a rotation matrix (`(..., 3, 3)`)
    returns $R$ itself (the adjoint of SO(3)).

    **Arguments:**

    - `g`: shape `(..., 4, 4)` (or `(..., 3, 3)`).

    **Returns:**

    Shape `(..., 6, 6)` (or `(..., 3, 3)`).
    """
    g = jnp.asarray(g)
    if g.shape[-2:] == (3, 3):
        return g
    R = g[..., :3, :3]
    P = so3_hat(g[..., :3, 3])
    return _block(R, jnp.zeros_like(R), matmul(P, R), R)


def coAd(g):
    r"""Coadjoint matrix $\mathrm{Ad}^*_g := (\mathrm{Ad}_{g^{-1}})^T$, acting on wrenches $(\tau, f)$.

    $\mathrm{Ad}^*_g = \begin{pmatrix}R & \tilde pR\\ 0 & R\end{pmatrix}$. Satisfies $\langle \mathrm{Ad}^*_g w, \mathrm{Ad}_g x\rangle = \langle w, x\rangle$.

    **Arguments:**

    - `g`: shape `(..., 4, 4)` (or `(..., 3, 3)`, giving $R$).

    **Returns:**

    Shape `(..., 6, 6)` (or `(..., 3, 3)`).
    """
    g = jnp.asarray(g)
    if g.shape[-2:] == (3, 3):
        return g
    R = g[..., :3, :3]
    P = so3_hat(g[..., :3, 3])
    return _block(R, matmul(P, R), jnp.zeros_like(R), R)


def ad(x):
    r"""Adjoint of the Lie algebra, $\mathrm{ad}_X Y = [X, Y]$.

    For a twist: $\mathrm{ad}_{(\omega,v)} = \begin{pmatrix}\tilde\omega & 0\\
    \tilde v & \tilde\omega\end{pmatrix}$; for a 3-vector: $\tilde\omega$.

    **Arguments:**

    - `x`: shape `(..., 6)` (or `(..., 3)`).

    **Returns:**

    Shape `(..., 6, 6)` (or `(..., 3, 3)`).
    """
    x = jnp.asarray(x)
    if x.shape[-1] == 3:
        return so3_hat(x)
    W = so3_hat(x[..., :3])
    V = so3_hat(x[..., 3:])
    return _block(W, jnp.zeros_like(W), V, W)


def coad(x):
    r"""The seed's coadjoint $\mathrm{ad}^*_X := -(\mathrm{ad}_X)^T$ of a twist.

    $\mathrm{ad}^*_{(\omega, v)} = \begin{pmatrix}\tilde\omega & \tilde v\\ 0 &
    \tilde\omega\end{pmatrix}$, acting on wrenches $(\tau, f)$.

    **Arguments:**

    - `x`: twist, shape `(..., 6)` (or `(..., 3)`, giving $\tilde\omega$).

    **Returns:**

    Shape `(..., 6, 6)` (or `(..., 3, 3)`).
    """
    x = jnp.asarray(x)
    if x.shape[-1] == 3:
        return so3_hat(x)
    W = so3_hat(x[..., :3])
    V = so3_hat(x[..., 3:])
    return _block(W, V, jnp.zeros_like(W), W)


def coad_action(x, mu):
    r"""$\mathrm{ad}^*_X\mu = -\mathrm{ad}_X^T\mu = (\omega\times\tau + v\times f,\ \omega\times f)$
    for a twist $X = (\omega, v)$ and a wrench or momentum $\mu = (\tau, f)$.

    Equals `coad(x) @ mu` without forming the matrix (cross products only, which XLA fuses).

    **Arguments:**

    - `x`: twist, shape `(..., 6)`; `mu`: wrench, shape `(..., 6)`; leading dimensions broadcast.

    **Returns:**

    Shape `(..., 6)`.
    """
    x = jnp.asarray(x)
    mu = jnp.asarray(mu)
    w, v = x[..., :3], x[..., 3:]
    tau, f = mu[..., :3], mu[..., 3:]
    w, v, tau, f = jnp.broadcast_arrays(w, v, tau, f)
    return jnp.concatenate([jnp.cross(w, tau) + jnp.cross(v, f), jnp.cross(w, f)], axis=-1)


def bracket(x, y):
    r"""Lie bracket $[X, Y] = (\omega_X\times\omega_Y,\ \omega_X\times v_Y - \omega_Y\times v_X)$.

    Equals the matrix commutator $\hat X\hat Y - \hat Y\hat X$. For 3-vectors: the cross
    product.

    **Arguments:**

    - `x`, `y`: shape `(..., 6)` (or both `(..., 3)`); leading dimensions broadcast.

    **Returns:**

    Shape `(..., 6)` (or `(..., 3)`).
    """
    x, y = jnp.broadcast_arrays(jnp.asarray(x), jnp.asarray(y))
    if x.shape[-1] == 3:
        return jnp.cross(x, y)
    wx, vx = x[..., :3], x[..., 3:]
    wy, vy = y[..., :3], y[..., 3:]
    return jnp.concatenate([jnp.cross(wx, wy), jnp.cross(wx, vy) - jnp.cross(wy, vx)], axis=-1)


def klein(x, y):
    r"""Klein form $[X\,|\,Y] = \omega_X\cdot v_Y + \omega_Y\cdot v_X$ (Ad-invariant).

    **Arguments:**

    - `x`, `y`: twists, shape `(..., 6)`; leading dimensions broadcast.

    **Returns:**

    Shape `(...)`.
    """
    x, y = jnp.broadcast_arrays(jnp.asarray(x), jnp.asarray(y))
    return jnp.sum(x[..., :3] * y[..., 3:], axis=-1) + jnp.sum(y[..., :3] * x[..., 3:], axis=-1)


def _dual_block(fn, xi):
    xi = _float(xi)
    w, v = xi[..., :3], xi[..., 3:]
    A, B = jax.jvp(fn, (w,), (v,))
    return _block(A, jnp.zeros_like(A), B, A)


def se3_dexp(xi):
    r"""Left-trivialized differential of `se3_exp`.

    $\exp(\xi)^{-1}\frac{d}{dt}\exp(\xi(t)) = (\mathrm{dexp}(\xi)\dot\xi)^\wedge$,
    $\mathrm{dexp}(\xi) = \sum_{k\ge0} (-\mathrm{ad}_\xi)^k/(k+1)!
    = \begin{pmatrix}J_r(\omega) & 0\\ DJ_r(\omega)[v] & J_r(\omega)\end{pmatrix}$
    (the SE(3) right Jacobian; Barfoot's $\mathcal J_l(-\xi)$ with the blocks swapped to
    angular-first). Smooth everywhere; not invertible at $\theta = 2\pi k$, $k\ge1$.

    **Arguments:**

    - `xi`: twist, shape `(..., 6)`.

    **Returns:**

    Shape `(..., 6, 6)`.
    """
    return _dual_block(so3_dexp, xi)


def se3_dexp_inv(xi):
    r"""Inverse of `se3_dexp` (closed form, no matrix inversion).

    $\mathrm{dexp}^{-1}(\xi) = \begin{pmatrix}J_r^{-1}(\omega) & 0\\ DJ_r^{-1}(\omega)[v] &
    J_r^{-1}(\omega)\end{pmatrix}$, the lower block by one `jax.jvp` of `so3_dexp_inv`.

    Used by Runge–Kutta–Munthe-Kaas: $g = g_0\exp(\Omega)$, $\dot g = g\hat\xi
    \iff \dot\Omega = \mathrm{dexp}^{-1}(\Omega)\,\xi$. Valid for $\theta < 2\pi$.

    **Arguments:**

    - `xi`: twist, shape `(..., 6)`.

    **Returns:**

    Shape `(..., 6, 6)`.
    """
    return _dual_block(so3_dexp_inv, xi)


def dexp(x):
    """`so3_dexp` for `(..., 3)`, `se3_dexp` for `(..., 6)`.

    **Arguments:**

    - `x`: shape `(..., 3)` or `(..., 6)`.

    **Returns:**

    Shape `(..., 3, 3)` or `(..., 6, 6)`.
    """
    return _on_algebra("dexp", x, so3_dexp, se3_dexp)


def dexp_inv(x):
    """`so3_dexp_inv` for `(..., 3)`, `se3_dexp_inv` for `(..., 6)`.

    **Arguments:**

    - `x`: shape `(..., 3)` or `(..., 6)`.

    **Returns:**

    Shape `(..., 3, 3)` or `(..., 6, 6)`.
    """
    return _on_algebra("dexp_inv", x, so3_dexp_inv, se3_dexp_inv)
