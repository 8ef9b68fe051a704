"""Holonomy of the dynamic connection: horizontal lifts of closed shape loops."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from . import lie
from ._geometry import connection
from ._systems._base import AbstractSystem

_GAUSS = (0.5 - np.sqrt(3.0) / 6.0, 0.5 + np.sqrt(3.0) / 6.0)


@eqx.filter_jit
def horizontal_lift(system: AbstractSystem, path, *, steps: int = 64) -> Float[Array, "4 4"]:
    r"""Group displacement of the horizontal lift of a shape path $s\mapsto q(s)$, $s\in[0,1]$.

    A horizontal motion has zero locked velocity, $U = \xi + A(q)\dot q = 0$ (seed 004, §2),
    so the section frame obeys $\dot g = g\,\hat\xi$ with $\xi = -A(q)\,q'(s)$. This
    integrates it with the fourth-order Magnus method (two Gauss points), exactly on SE(3).

    **Arguments:**

    - `system`: any system.
    - `path`: a JAX function `s -> q(s)`, smooth on $[0, 1]$.
    - `steps`: number of Magnus steps (static).

    **Returns:**

    $g(0)^{-1} g(1)$, a 4×4 pose: for a closed path, the holonomy of the loop.
    """
    h = 1.0 / steps

    def algebra(s):
        q, dq = jax.jvp(path, (s,), (jnp.ones_like(s),))
        return -connection(system, q) @ dq

    def step(g, s0):
        X1, X2 = algebra(s0 + _GAUSS[0] * h), algebra(s0 + _GAUSS[1] * h)
        increment = 0.5 * h * (X1 + X2) - np.sqrt(3.0) / 12.0 * h * h * lie.bracket(X2, X1)
        return g @ lie.se3_exp(increment), None

    s0 = jnp.asarray(path(0.0)).dtype.type(0) + h * jnp.arange(steps).astype(float)
    g, _ = jax.lax.scan(step, jnp.eye(4, dtype=s0.dtype), s0)
    return g


@eqx.filter_jit
def square_loop_holonomy(system, q, u, w, eps, *, steps: int = 16):
    r"""Holonomy of the square loop $q \to q+\varepsilon u \to q+\varepsilon(u+w) \to q+\varepsilon w \to q$.

    **Arguments:**

    - `q`: the corner, `(d,)`; `u`, `w`: the side directions, `(d,)`; `eps`: the side length.
    - `steps`: Magnus steps per side (static).

    **Returns:**

    The 4×4 holonomy; to second order it is $\exp(-\varepsilon^2\,\Omega(u, w))$ with the
    curvature $\Omega$ of `curvature`, the error being $O(\varepsilon^3)$.
    """
    corners = jnp.stack([q, q + eps * u, q + eps * (u + w), q + eps * w, q])

    def path(s):
        # One parameter for the four sides; Magnus steps never straddle a corner.
        corner = jnp.clip(jnp.floor(4 * s), 0, 3)
        side = corner.astype(int)
        t = 4 * s - corner
        return corners[side] + t * (corners[side + 1] - corners[side])

    return horizontal_lift(system, path, steps=4 * steps)


@eqx.filter_jit
def curvature_by_holonomy(system: AbstractSystem, q, eps, *, steps: int = 16):
    r"""The curvature estimated from holonomies of small horizontal square loops.

    $\Omega(e_j, e_k) \approx -\log(\text{hol}_{jk}) / \varepsilon^2$ for every pair of shape
    coordinates: an independent check of `curvature` (error $O(\varepsilon)$).

    **Arguments:**

    - `q`: shape, `(d,)`; `eps`: loop side; `steps`: Magnus steps per side (static).

    **Returns:**

    The estimate, shape `(6, d, d)`, antisymmetric in the last two indices.
    """
    d = system.shape_dim
    j, k = np.triu_indices(d, 1)
    E = jnp.eye(d, dtype=q.dtype)

    def estimate(u, w):
        return -lie.se3_log(square_loop_holonomy(system, q, u, w, eps, steps=steps)) / eps**2

    upper = jax.vmap(estimate)(E[j], E[k])  # (pairs, 6)
    Omega = jnp.zeros((6, d, d), q.dtype).at[:, j, k].set(upper.T)
    return Omega.at[:, k, j].set(-upper.T)
