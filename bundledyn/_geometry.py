r"""Bundle geometry from the invariant metric: locked inertia, connection, shape metric, curvature.

All functions are pure functions of a system and its shape $q$; they vmap over $q$ and
differentiate, and are compiled (`equinox.filter_jit`): called on concrete values, each
runs as one program rather than op by op (which lowers one program per primitive).
Notation of architecture §2: $G = [[I_r, B], [B^T, M]]$ in the variables $(\xi, \dot q)$
with $\xi = g^{-1}\dot g$ of the section frame.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from . import lie
from ._systems._base import AbstractSystem


@eqx.filter_jit
def metric(system: AbstractSystem, q: Float[Array, " d"]) -> Float[Array, "6+d 6+d"]:
    r"""The invariant metric $G(q)$ in the trivialization variables $(\xi, \dot q)$.

    **Arguments:**

    - `system`: any system.
    - `q`: shape coordinates, shape `(d,)`.

    **Returns:**

    $G(q)$, shape `(6+d, 6+d)`: $T = \tfrac12[\xi;\dot q]^T G [\xi;\dot q]$ (architecture §2).
    """
    return system.metric(q)


def _blocks(G):
    return G[:6, :6], G[:6, 6:], G[6:, 6:]


@eqx.filter_jit
def locked_inertia(system: AbstractSystem, q) -> Float[Array, "6 6"]:
    r"""The locked inertia $I_r(q)$: the inertia of the frozen system (seed 004: $\mathbf I(s)$).

    **Returns:**

    The 6×6 block $I_r$ of the metric, acting on twists of the section frame
    (angular first): $\mathbf J(s)(X, Y) = X^T I_r Y$.
    """
    return system.metric(q)[:6, :6]


def _connection_from_metric(G):
    I_r, B, _ = _blocks(G)
    return jnp.linalg.solve(I_r, B)


@eqx.filter_jit
def connection(system: AbstractSystem, q) -> Float[Array, "6 d"]:
    r"""The local form $A(q) = I_r^{-1} B$ of the dynamic connection (seed 004, §2).

    The connection form is $\boldsymbol\omega(\dot s) = \operatorname{Ad}_g U$ with the locked
    velocity $U = \xi + A\dot q$; a motion is horizontal iff $U = 0$, i.e. iff its total
    momentum $I_r U$ vanishes.

    **Returns:**

    $A(q)$, shape `(6, d)`.
    """
    return _connection_from_metric(system.metric(q))


@eqx.filter_jit
def shape_metric(system: AbstractSystem, q) -> Float[Array, "d d"]:
    r"""The shape metric $\mathcal J_{\text{def}}(q) = M - B^T I_r^{-1} B$ of (2.1).

    **Returns:**

    The $d\times d$ metric of the deformation kinetic energy $K_{\text{def}} =
    \tfrac12\dot q^T \mathcal J_{\text{def}}\dot q$, so that
    $T = \tfrac12 U^T I_r U + \tfrac12 \dot q^T \mathcal J_{\text{def}} \dot q$.
    """
    G = system.metric(q)
    _, B, M = _blocks(G)
    return M - B.T @ _connection_from_metric(G)


def curvature_from_connection(A: Float[Array, "6 d"], dA: Float[Array, "d 6 d"]):
    r"""The curvature of a connection with local form $A$ and derivative $dA[k, :, j] = \partial_k A_j$.

    $\Omega(u, w) = dA(u, w) - [A u, A w]$ with $dA(u,w) = (\partial_u A) w - (\partial_w A) u$;
    with this sign a small horizontal loop of area $\varepsilon^2$ traversed first along
    $u$ then along $w$ displaces the section frame by $g \mapsto g\exp(-\varepsilon^2\Omega(u,w))$.

    **Returns:**

    $\Omega$, shape `(6, d, d)`, antisymmetric in the last two indices.
    """
    T = jnp.moveaxis(dA, 1, 0)  # T[:, j, k] = ∂_j A_k
    brackets = jnp.moveaxis(lie.bracket(A.T[:, None, :], A.T[None, :, :]), -1, 0)
    return T - jnp.swapaxes(T, 1, 2) - brackets


@eqx.filter_jit
def curvature(system: AbstractSystem, q) -> Float[Array, "6 d d"]:
    r"""The curvature $\Omega_r(\delta q, \delta' q)$ of the dynamic connection on the section.

    Computed from the Jacobian of $A$ by forward-mode autodiff (structure equation,
    seed 004 §2; see `curvature_from_connection` for the sign convention).

    **Returns:**

    $\Omega_r$, shape `(6, d, d)`, with $\Omega_r(u, w) = $ `einsum("ijk,j,k", Omega, u, w)`.
    """

    def connection_twice(q_):
        A = connection(system, q_)
        return A, A

    dA, A = jax.jacfwd(connection_twice, has_aux=True)(q)
    return curvature_from_connection(A, jnp.moveaxis(dA, -1, 0))


@eqx.filter_jit
def kinetic_energy(system: AbstractSystem, q, xi, qdot) -> Float[Array, ""]:
    r"""$T = \tfrac12 [\xi;\dot q]^T G(q) [\xi;\dot q]$ (2.1).

    **Arguments:**

    - `q`, `qdot`: shape and shape velocity, `(d,)`.
    - `xi`: $g^{-1}\dot g$ of the section frame, `(6,)`.
    """
    velocity = jnp.concatenate([xi, qdot])
    return 0.5 * velocity @ system.metric(q) @ velocity


@eqx.filter_jit
def locked_velocity(system: AbstractSystem, q, xi, qdot) -> Float[Array, "6"]:
    r"""The locked velocity $U = \xi + A(q)\dot q$ (the body form of $\boldsymbol\omega(\dot s)$)."""
    return xi + connection(system, q) @ qdot
