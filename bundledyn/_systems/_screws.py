r"""Joint screws: unit screws, their exponentials, and poses from rotation and translation."""

import jax
import jax.numpy as jnp

from .. import lie
from .._linalg import matmul


@jax.custom_jvp
def unit_screws(S):
    """The joint screws, differentiated along unit screws only (`Multibody`'s docstring)."""
    return S


@unit_screws.defjvp
def _unit_screws_jvp(primals, tangents):
    (S,), (dS,) = primals, tangents
    w, dw = S[..., :3], dS[..., :3]
    # |ω|² dω - ω (ω·dω): the tangent of |ω| = 1 at a rotation axis, zero at a translation's ω = 0.
    dw = jnp.sum(w * w, axis=-1, keepdims=True) * dw - w * jnp.sum(w * dw, axis=-1, keepdims=True)
    return S, jnp.concatenate([dw, dS[..., 3:]], axis=-1)


def unit_screw_exp(S, theta):
    r"""$\exp(\theta\hat S)$ for screws whose axis $\omega$ is a unit vector or zero.

    Rodrigues' formula with $|\omega| \in \{0, 1\}$ has no singular point, so joint screws
    need none of the Taylor branches of the general `lie.se3_exp`:
    $R = 1 + \sin\theta\,\tilde\omega + (1-\cos\theta)\tilde\omega^2$,
    $p = (\theta + (1-\cos\theta)\tilde\omega + (\theta-\sin\theta)\tilde\omega^2)\,v$.
    """
    w_hat = lie.hat(S[..., :3])
    w_hat2 = matmul(w_hat, w_hat)
    s, c = jnp.sin(theta)[..., None, None], (1.0 - jnp.cos(theta))[..., None, None]
    eye = jnp.broadcast_to(jnp.eye(3, dtype=S.dtype), w_hat.shape)
    R = eye + s * w_hat + c * w_hat2
    V = theta[..., None, None] * eye + c * w_hat + (theta[..., None, None] - s) * w_hat2
    return pose(R, matmul(V, S[..., 3:, None])[..., 0])


def pose(R, p):
    top = jnp.concatenate([R, p[..., None]], axis=-1)
    bottom = jnp.broadcast_to(jnp.array([0.0, 0.0, 0.0, 1.0], dtype=R.dtype), (*R.shape[:-2], 1, 4))
    return jnp.concatenate([top, bottom], axis=-2)
