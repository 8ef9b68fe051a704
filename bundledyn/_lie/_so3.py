r"""The rotation group SO(3): hat/vee, exp/log and the left-trivialized dexp.

Every function accepts leading batch dimensions and keeps the input dtype. The
trigonometric coefficients are evaluated as functions of $x = \theta^2$: a Taylor series
for $x < 1$, the closed form on a *safe* substituted argument otherwise (the
double-`jnp.where` trick), so values and derivatives of every order are finite and exact
to rounding at $\theta = 0$, at tiny angles and up to $\theta = \pi$.
"""

import functools
import math
from fractions import Fraction

import jax
import jax.numpy as jnp

__all__ = [
    "so3_hat",
    "so3_vee",
    "so3_exp",
    "so3_log",
    "so3_dexp",
    "so3_dexp_inv",
    "so3_left_jacobian",
    "so3_left_jacobian_inv",
]

# Below this value of θ² the coefficients are evaluated by their Taylor series.
_SERIES_X = 1.0
_N_TERMS = 11


def _bernoulli(n: int) -> Fraction:
    """Bernoulli number B_n (B_1 = -1/2 convention, irrelevant here: only even n used)."""
    a = [Fraction(0)] * (n + 1)
    for m in range(n + 1):
        a[m] = Fraction(1, m + 1)
        for j in range(m, 0, -1):
            a[j - 1] = j * (a[j - 1] - a[j])
    return a[0]


# Power-series coefficients in x = θ², lowest order first.
# A = sinθ/θ,  B = (1 - cosθ)/θ²,  C = (θ - sinθ)/θ³,
# D = 1/θ² - cot(θ/2)/(2θ) = Σ_{n≥1} |B_{2n}| θ^{2n-2}/(2n)!.
_A_SERIES = tuple((-1) ** k / math.factorial(2 * k + 1) for k in range(_N_TERMS))
_B_SERIES = tuple((-1) ** k / math.factorial(2 * k + 2) for k in range(_N_TERMS))
_C_SERIES = tuple((-1) ** k / math.factorial(2 * k + 3) for k in range(_N_TERMS))
_D_SERIES = tuple(
    float(abs(_bernoulli(2 * n)) / math.factorial(2 * n)) for n in range(1, _N_TERMS + 1)
)
# dB/dx and dC/dx, the series differentiated term by term, and their derivatives.
_E_SERIES = tuple(k * b for k, b in enumerate(_B_SERIES) if k)
_F_SERIES = tuple(k * c for k, c in enumerate(_C_SERIES) if k)
_G_SERIES = tuple(k * e for k, e in enumerate(_E_SERIES) if k)
_H_SERIES = tuple(k * f for k, f in enumerate(_F_SERIES) if k)


def _horner(coeffs, x):
    out = jnp.full_like(x, coeffs[-1])
    for c in coeffs[-2::-1]:
        out = out * x + c
    return out


_SERIES = {
    "a": _A_SERIES,
    "b": _B_SERIES,
    "c": _C_SERIES,
    "d": _D_SERIES,
    "e": _E_SERIES,
    "f": _F_SERIES,
    "g": _G_SERIES,
    "h": _H_SERIES,
}


# Jitted, as `_poly` below: a solver's step and its adjoint call them dozens of times with
# the same shapes, and JAX then traces each once and reuses its jaxpr (and derivatives);
# XLA inlines the calls, so the optimized programs are those of the inlined code.
@functools.partial(jax.jit, static_argnames="names")
def _coefficients(x, names):
    """The coefficients `names` (from "abcdefgh") as functions of x = θ², safe at x = 0.

    `e` and `f` are dB/dx = (A - 2B)/(2x) and dC/dx = (B - 3C)/(2x); `g` and `h` are
    d²B/dx² = (A' - 4e)/(2x) and d²C/dx² = (e - 5f)/(2x), with A' = dA/dx = (cos θ - A)/(2x).

    One branch mask for all: Taylor series (Horner) for x < 1, closed form on a
    substituted safe argument otherwise, so neither branch produces inf/NaN, nor do their
    derivatives of any order.
    """
    small = x < _SERIES_X
    xs = jnp.where(small, x, 0.0)
    xl = jnp.where(small, 2.0 * _SERIES_X, x)
    t = jnp.sqrt(xl)
    h = 0.5 * t
    sin_t = jnp.sin(t)
    sin_h = jnp.sin(h)
    closed = {
        "a": lambda: sin_t / t,
        "b": lambda: 2.0 * sin_h * sin_h / xl,
        "c": lambda: (t - sin_t) / (xl * t),
        "d": lambda: (1.0 - h * jnp.cos(h) / sin_h) / xl,
        "e": lambda: (sin_t / t - 4.0 * sin_h * sin_h / xl) / (2.0 * xl),
        "f": lambda: (2.0 * sin_h * sin_h / xl - 3.0 * (t - sin_t) / (xl * t)) / (2.0 * xl),
        "g": lambda: ((jnp.cos(t) - sin_t / t) / (2.0 * xl) - 4.0 * closed["e"]()) / (2.0 * xl),
        "h": lambda: (closed["e"]() - 5.0 * closed["f"]()) / (2.0 * xl),
    }
    return tuple(jnp.where(small, _horner(_SERIES[n], xs), closed[n]()) for n in names)


def _float(x):
    x = jnp.asarray(x)
    if not jnp.issubdtype(x.dtype, jnp.inexact):
        x = x.astype(jnp.result_type(float))
    return x


def so3_hat(w):
    r"""Skew-symmetric matrix of a 3-vector, $\tilde w\,x = w \times x$.

    **Arguments:**

    - `w`: array of shape `(..., 3)`.

    **Returns:**

    Array of shape `(..., 3, 3)`.
    """
    w = jnp.asarray(w)
    w1, w2, w3 = w[..., 0], w[..., 1], w[..., 2]
    z = jnp.zeros_like(w1)
    return jnp.stack(
        [
            jnp.stack([z, -w3, w2], axis=-1),
            jnp.stack([w3, z, -w1], axis=-1),
            jnp.stack([-w2, w1, z], axis=-1),
        ],
        axis=-2,
    )


def so3_vee(W):
    r"""Inverse of `so3_hat`: the axial vector $(W_{32}, W_{13}, W_{21})$.

    Reads only those three entries; for a matrix that is not exactly skew, pass
    $\tfrac12(W - W^T)$ to get the axial vector of its skew part.

    **Arguments:**

    - `W`: array of shape `(..., 3, 3)`.

    **Returns:**

    Array of shape `(..., 3)`.
    """
    W = jnp.asarray(W)
    return jnp.stack([W[..., 2, 1], W[..., 0, 2], W[..., 1, 0]], axis=-1)


def _sq(w):
    return jnp.sum(w * w, axis=-1)


def _eye_like(w):
    return jnp.broadcast_to(jnp.eye(3, dtype=w.dtype), w.shape[:-1] + (3, 3))


@jax.jit
def _poly(w, c0, c1, c2):
    """c0 I + c1 w̃ + c2 w̃² with scalar (batched) coefficients; w̃² = w wᵀ - |w|² I."""
    e = lambda c: c[..., None, None]
    outer = w[..., :, None] * w[..., None, :]
    return e(c0 - c2 * _sq(w)) * _eye_like(w) + e(c1) * so3_hat(w) + e(c2) * outer


def so3_exp(w):
    r"""Exponential map of SO(3) (Rodrigues' formula).

    $\exp(\tilde w) = 1 + \frac{\sin\theta}{\theta}\tilde w
    + \frac{1-\cos\theta}{\theta^2}\tilde w^2$, $\theta = |w|$; the same tensor as the
    seed's eq. (39) with $\chi = \theta$, $q = w/\theta$. Smooth everywhere.

    **Arguments:**

    - `w`: rotation vector, shape `(..., 3)`.

    **Returns:**

    Rotation matrix, shape `(..., 3, 3)`.
    """
    w = _float(w)
    x = _sq(w)
    a, b = _coefficients(x, "ab")
    return _poly(w, jnp.ones_like(x), a, b)


def _so3_exp_and_left_jacobian(w):
    """(exp(w), J_l(w)) sharing the coefficient evaluation (used by se3_exp)."""
    x = _sq(w)
    a, b, c = _coefficients(x, "abc")
    one = jnp.ones_like(x)
    return _poly(w, one, a, b), _poly(w, one, b, c)


def so3_dexp(w):
    r"""Left-trivialized differential of `so3_exp` (the right Jacobian $J_r$).

    $\exp(w)^{-1}\,\frac{d}{dt}\exp(w(t)) = (\mathrm{dexp}(w)\,\dot w)^\wedge$ with
    $\mathrm{dexp}(w) = \sum_k (-\tilde w)^k/(k+1)!
    = 1 - \frac{1-\cos\theta}{\theta^2}\tilde w + \frac{\theta-\sin\theta}{\theta^3}\tilde w^2$.
    Smooth everywhere; singular (not invertible) at $\theta = 2\pi k$, $k \ge 1$.

    **Arguments:**

    - `w`: rotation vector, shape `(..., 3)`.

    **Returns:**

    Array of shape `(..., 3, 3)`.
    """
    w = _float(w)
    x = _sq(w)
    b, c = _coefficients(x, "bc")
    return _poly(w, jnp.ones_like(x), -b, c)


def so3_dexp_derivative(w):
    r"""The derivative of `so3_dexp`: $\partial\,\mathrm{dexp}(w)/\partial w_l$ for $l = 1, 2, 3$.

    With $\mathrm{dexp}(w) = 1 - B\tilde w + C\tilde w^2$, $B(x) = (1-\cos\theta)/\theta^2$,
    $C(x) = (\theta - \sin\theta)/\theta^3$ of $x = \theta^2$:
    $\partial_l\,\mathrm{dexp} = -B\tilde e_l + C(w e_l^T + e_l w^T - 2w_l 1)
    + 2w_l(-B'\tilde w + C'\tilde w^2)$, the primes $d/dx$ (Taylor series below $x = 1$).
    Written out, it costs a fraction of `jax.jacfwd(so3_dexp)`.

    **Arguments:**

    - `w`: rotation vector, shape `(..., 3)`.

    **Returns:**

    Array of shape `(..., 3, 3, 3)`, the derivative along $w_l$ first.
    """
    w = _float(w)
    x = _sq(w)
    b, c, db, dc = (k[..., None, None, None] for k in _coefficients(x, "bcef"))
    e = jnp.eye(3, dtype=w.dtype)

    def batched(a):  # a constant of the formula, with the rotations' leading dimensions
        return jnp.broadcast_to(a, w.shape[:-1] + a.shape)

    wl = w[..., :, None, None]
    outer = (
        w[..., None, :, None] * batched(e[:, None, :])
        + batched(e[:, :, None]) * w[..., None, None, :]
    )
    hat_w = so3_hat(w)[..., None, :, :]
    hat_w2 = (w[..., :, None] * w[..., None, :] - x[..., None, None] * batched(e))[..., None, :, :]
    return (
        -b * batched(so3_hat(e))
        + c * (outer - 2.0 * wl * batched(e)[..., None, :, :])
        + 2.0 * wl * (-db * hat_w + dc * hat_w2)
    )


def so3_dexp_second_derivative_along(w, u, v):
    r"""The second derivative of `so3_dexp` along $u$, applied to $v$: $\partial_u\partial_l\,
    \big(\mathrm{dexp}(w)\,v\big)$ for $l = 1, 2, 3$.

    Differentiating `so3_dexp_derivative` once more along $u$, with $P_l = w e_l^T + e_l w^T -
    2w_l 1$ ($= \partial_l \tilde w^2$), $P_u = \sum_m u_m P_m$, $\partial_u P_l = u e_l^T +
    e_l u^T - 2u_l 1$ and the primes $d/dx$, $x = \theta^2$:
    $-2B'\big((u\cdot w)\,e_l\times v + w_l\,u\times v\big) + 2C'\big((u\cdot w)P_l + w_lP_u\big)v
    + C\,(\partial_u P_l)v + 2u_l(-B'\,w\times v + C'\tilde w^2 v)
    + 4w_l(u\cdot w)(-B''\,w\times v + C''\tilde w^2 v)$. A ball joint's metric jet needs only
    these contractions, not the whole $3\times3\times3\times3$ tensor.

    **Arguments:**

    - `w`: rotation vector, shape `(..., 3)`.
    - `u`: the direction of differentiation, shape `(..., 3)`.
    - `v`: the vector `dexp` is applied to, shape `(..., 3)`.

    The three broadcast against each other.

    **Returns:**

    Array of shape `(..., 3, 3)`: row $l$ is $\partial_u\partial_l(\mathrm{dexp}(w)\,v)$.
    """
    w, u, v = _float(w), _float(u), _float(v)
    x = _sq(w)[..., None, None]  # before broadcasting: the coefficients once per rotation
    c, db, dc, ddb, ddc = _coefficients(x, "cefgh")
    shape = jnp.broadcast_shapes(w.shape, u.shape, v.shape)
    w, u, v = (jnp.broadcast_to(a, shape) for a in (w, u, v))
    x, c, db, dc, ddb, ddc = (
        jnp.broadcast_to(k, shape[:-1] + (1, 1)) for k in (x, c, db, dc, ddb, ddc)
    )

    def dot(a, b):
        return jnp.sum(a * b, axis=-1)[..., None, None]

    def row(a):  # the same 3-vector in every row l
        return a[..., None, :]

    def per_l(a):  # a_l, the l-th component, as a factor of row l
        return a[..., :, None]

    # The terms gathered by the vector each multiplies: w, u, v, u×v, w×v, e_l and e_l×v.
    uw, uv, wv = dot(u, w), dot(u, v), dot(w, v)
    w_l, u_l, v_l = per_l(w), per_l(u), per_l(v)
    along_w = 2.0 * dc * (uw * v_l + w_l * uv + u_l * wv) + 4.0 * ddc * uw * w_l * wv
    along_u = c * v_l + 2.0 * dc * w_l * wv
    along_v = -2.0 * (c + dc * x) * u_l - 4.0 * (2.0 * dc + ddc * x) * uw * w_l
    along_w_cross_v = -2.0 * db * u_l - 4.0 * ddb * uw * w_l
    e = _eye_like(w)
    return (
        along_w * row(w)
        + along_u * row(u)
        + along_v * row(v)
        - 2.0 * db * w_l * row(jnp.cross(u, v))
        + along_w_cross_v * row(jnp.cross(w, v))
        + (2.0 * dc * uw * wv + c * uv) * e
        - 2.0 * db * uw * jnp.cross(e, row(v))
    )


def so3_dexp_inv(w):
    r"""Inverse of `so3_dexp` (inverse right Jacobian $J_r^{-1}$).

    $\mathrm{dexp}^{-1}(w) = 1 + \tfrac12\tilde w
    + \Big(\frac{1}{\theta^2} - \frac{1+\cos\theta}{2\theta\sin\theta}\Big)\tilde w^2$.
    Valid for $\theta < 2\pi$ (singular at $\theta = 2\pi$); finite at $\theta = \pi$.

    **Arguments:**

    - `w`: rotation vector, shape `(..., 3)`.

    **Returns:**

    Array of shape `(..., 3, 3)`.
    """
    w = _float(w)
    x = _sq(w)
    (d,) = _coefficients(x, "d")
    return _poly(w, jnp.ones_like(x), 0.5 * jnp.ones_like(x), d)


def so3_left_jacobian(w):
    r"""Right-trivialized differential of `so3_exp` (left Jacobian $J_l(w) = J_r(-w)$).

    Also the matrix $V$ in $\exp(\omega, v) = (\exp\tilde\omega, V v)$ on SE(3).

    **Arguments:**

    - `w`: rotation vector, shape `(..., 3)`.

    **Returns:**

    Array of shape `(..., 3, 3)`.
    """
    return so3_dexp(-_float(w))


def so3_left_jacobian_inv(w):
    r"""Inverse of `so3_left_jacobian`, $J_l^{-1}(w) = J_r^{-1}(-w)$; valid for $\theta<2\pi$.

    **Arguments:**

    - `w`: rotation vector, shape `(..., 3)`.

    **Returns:**

    Array of shape `(..., 3, 3)`.
    """
    return so3_dexp_inv(-_float(w))


# so3_log ---------------------------------------------------------------------------------

_LOG_SMALL_Y = 1e-2  # series branch when (sinθ/cosθ)² < this and cosθ > 0
_LOG_NEAR_PI_C = -0.5  # dedicated branch when cosθ < this (θ > 2π/3)
_ATAN_SERIES = tuple((-1) ** k / (2 * k + 1) for k in range(10))


def so3_log(R):
    r"""Logarithm of SO(3): the rotation vector $w$ with $\exp(\tilde w) = R$, $|w| \le \pi$.

    With $s = \tfrac12 (R - R^T)^\vee = \sin\theta\,n$ and $c = \tfrac12(\operatorname{tr}R-1)
    = \cos\theta$, three branches are selected with the double-`jnp.where` trick:

    - small angle ($c > 0$, $|s|^2 < 10^{-2}c^2$): $w = s\,\arctan(|s|/c)/|s|$ by its
      Taylor series in $|s|^2/c^2$ (no square root at 0);
    - generic: $w = s\,\operatorname{atan2}(|s|, c)/|s|$;
    - near $\pi$ ($c < -1/2$): the axis from the symmetric part,
      $n n^T = (\tfrac12(R+R^T) - c)/(1-c)$ (column of largest diagonal entry), its sign
      from $n\cdot s \ge 0$, and $\theta = \operatorname{atan2}(|n\cdot s|, c)$, so the
      result stays accurate to rounding at $\theta = \pi - 10^{-7}$.

    Each branch is a smooth function of the nine entries of $R$ (so derivatives with
    respect to $R$ are finite, also off the group, as finite differences see them); on
    SO(3) the branches agree, so derivatives along the group are continuous, and
    $\partial\log(R\exp\delta)/\partial\delta = $ `so3_dexp_inv` $(\log R)$ holds to rounding
    up to $\theta = \pi$.

    At exactly $\theta = \pi$ the logarithm is two-valued ($\pm\pi n$). When $R$ is exactly
    symmetric ($s = 0$ to the last bit) this returns $\pi n$ with the sign that makes the
    component of largest magnitude (the largest diagonal entry of $R$) positive; otherwise
    the sign of the rounding-level skew part decides, which is the continuous choice from
    $\theta < \pi$. Values and derivatives stay finite there.

    **Arguments:**

    - `R`: rotation matrix, shape `(..., 3, 3)`.

    **Returns:**

    Rotation vector, shape `(..., 3)`.
    """
    R = _float(R)
    RT = jnp.swapaxes(R, -1, -2)
    s = 0.5 * so3_vee(R - RT)
    c = 0.5 * (jnp.trace(R, axis1=-2, axis2=-1) - 1.0)
    x2 = _sq(s)

    near_pi = c < _LOG_NEAR_PI_C
    small = (~near_pi) & (c > 0.0) & (x2 < _LOG_SMALL_Y * c * c)

    # small angle: atan(|s|/c)/|s| = (1/c) Σ (-y)^k/(2k+1), y = |s|²/c²
    c_small = jnp.where(small, c, 1.0)
    y = jnp.where(small, x2, 0.0) / (c_small * c_small)
    f_small = _horner(_ATAN_SERIES, y) / c_small

    # near π: axis from the symmetric part, nnᵀ = (sym(R) - c)/(1 - c)
    c_pi = jnp.where(near_pi, c, -1.0)
    M = (0.5 * (R + RT) - c_pi[..., None, None] * _eye_like(s)) / (1.0 - c_pi)[..., None, None]
    diag = jnp.diagonal(M, axis1=-2, axis2=-1)
    onehot = jax.nn.one_hot(jnp.argmax(diag, axis=-1), 3, dtype=M.dtype)
    col = jnp.einsum("...ij,...j->...i", M, onehot)  # M[..., :, k], k = argmax diag
    mkk = jnp.sum(diag * onehot, axis=-1)
    n = col / jnp.sqrt(jnp.where(near_pi & (mkk > 0.0), mkk, 1.0))[..., None]
    ns = jnp.sum(n * s, axis=-1)  # = sin θ up to the sign of n

    # one atan2 for both: generic atan2(|s|, c), near π atan2(|n·s|, c)
    xg = jnp.sqrt(jnp.where(near_pi | small, 1.0, x2))
    theta = jnp.arctan2(
        jnp.where(near_pi, jnp.abs(ns), xg), jnp.where(near_pi, c_pi, jnp.where(small, 1.0, c))
    )
    f = jnp.where(small, f_small, theta / xg)
    w_pi = (jnp.where(ns < 0.0, -theta, theta))[..., None] * n
    return jnp.where(near_pi[..., None], w_pi, f[..., None] * s)
