"""Equations of motion: Chevallier's (2.6)–(2.7) term by term, and the reference (Hamel) form.

Everything is written in the section frame of a local trivialization $s = g\\cdot r(q)$
(seed 004, §2): $U = \\operatorname{Ad}_{g^{-1}}\\mathbf V$ is the locked velocity, $\\xi = U - A\\dot q$
the body velocity of the section frame, $I_r$ the locked inertia, $A$ the connection,
$\\mathcal J_{\\text{def}}$ the shape metric and $\\Omega$ the curvature (see `bundledyn.curvature`).
Forces are generalized forces in the variables $(\\xi, \\dot q)$: a wrench $F_b$ on the section
frame (angular first, section axes) and a shape force $Q_H$; in the variables $(U, \\dot q)$
they become $F_b$ and $Q = Q_H - A^T F_b$ (virtual work $F_b\\cdot\\delta\\xi + Q_H\\cdot\\delta q$
with $\\delta\\xi = \\delta U - A\\,\\delta q$).
"""

from typing import NamedTuple

import jax.numpy as jnp
from jaxtyping import Array, Float

from . import lie
from ._geometry import curvature_from_connection
from ._systems._base import AbstractSystem


class BundleGeometry(NamedTuple):
    """The metric's blocks and the derived geometry at one shape, with $q$-derivatives.

    Index conventions: `dX[k]` $= \\partial X / \\partial q_k$ (derivative index first: the
    contractions are batched matrix products, which XLA's CPU backend runs far faster than
    general einsums); `A[:, j]` is the connection applied to $e_j$; `Omega[:, j, k]`
    $= \\Omega(e_j, e_k)$.
    """

    G: Float[Array, "6+d 6+d"]
    dG: Float[Array, "d 6+d 6+d"]
    I_r: Float[Array, "6 6"]
    dI_r: Float[Array, "d 6 6"]
    A: Float[Array, "6 d"]
    dA: Float[Array, "d 6 d"]
    J_def: Float[Array, "d d"]
    dJ_def: Float[Array, "d d d"]
    Omega: Float[Array, "6 d d"]


def bundle_geometry(system: AbstractSystem, q: Float[Array, " d"]) -> BundleGeometry:
    """Locked inertia, connection, shape metric, curvature and their derivatives at $q$.

    One evaluation of `system.metric_and_derivative` feeds every term of (2.6)–(2.7):
    $\\partial_k A = I_r^{-1}(\\partial_k B - \\partial_k I_r\\,A)$ and
    $\\partial_k \\mathcal J_{\\text{def}} = \\partial_k M - \\partial_k B^T A - B^T \\partial_k A$.

    **Arguments:**

    - `system`: any system; `q`: shape, `(d,)`.

    **Returns:**

    A `BundleGeometry`.
    """
    if q.shape[0] == 0:  # a rigid body: no shape block to build
        G = system.metric(q)
        empty = jnp.zeros((6, 0, 0), G.dtype)
        return BundleGeometry(
            G,
            G[..., None][..., :0],
            G,
            G[..., None][..., :0],
            G[:, :0],
            empty,
            empty[0],
            empty,
            empty,
        )
    G, dG = system.metric_and_derivative(q)
    I_r, B, M = G[:6, :6], G[:6, 6:], G[6:, 6:]
    dI_r, dB, dM = dG[:, :6, :6], dG[:, :6, 6:], dG[:, 6:, 6:]
    # XLA's CPU triangular solve slows down sharply with many right-hand sides; the 6×6
    # locked inertia is SPD and well conditioned, so invert it once and multiply.
    I_inv = jnp.linalg.solve(I_r, jnp.eye(6, dtype=G.dtype))
    A = I_inv @ B
    dA = I_inv @ (dB - dI_r @ A)
    J_def = M - B.T @ A
    dJ_def = dM - jnp.swapaxes(dB, 1, 2) @ A - B.T @ dA
    Omega = curvature_from_connection(A, dA)
    return BundleGeometry(G, dG, I_r, dI_r, A, dA, J_def, dJ_def, Omega)


def inertia_covariant_derivative(geo: BundleGeometry, u: Float[Array, " d"]) -> Float[Array, "6 6"]:
    """$\\nabla_x \\mathbf I(s)(u)$ in the section frame: the derivative of the locked inertia along
    the horizontal lift of the shape velocity $u$ (seed 004, (2.4), (2.7)).

    Along the horizontal lift $\\dot g = g\\,\\widehat{(-Au)}$, $\\mathbf I(s) = \\operatorname{Ad}^*_g I_r
    \\operatorname{Ad}_{g^{-1}}$ changes at the rate $\\operatorname{Ad}^*_g(\\partial_u I_r +
    \\operatorname{ad}_{Au}^T I_r + I_r \\operatorname{ad}_{Au})\\operatorname{Ad}_{g^{-1}}$.

    **Returns:**

    The 6×6 matrix $\\partial_u I_r + \\operatorname{ad}_{Au}^T I_r + I_r\\operatorname{ad}_{Au}$.
    """
    ad_Au = lie.ad(geo.A @ u)
    return jnp.tensordot(u, geo.dI_r, 1) + ad_Au.T @ geo.I_r + geo.I_r @ ad_Au


def coadjoint_term(geo: BundleGeometry, U: Float[Array, "6"]) -> Float[Array, "6"]:
    """$\\operatorname{ad}^*_{\\mathbf V}\\mathbf I(s)(\\mathbf V)$ of (2.7) in the section frame:
    $\\operatorname{ad}^*_U I_r U = -\\operatorname{ad}_U^T I_r U$ (the seed's $\\operatorname{ad}^* = -\\operatorname{ad}^T$)."""
    return lie.coad(U) @ (geo.I_r @ U)


def frame_transport_term(geo: BundleGeometry, U, qdot) -> Float[Array, "6"]:
    """$I_r[A\\dot q, U]$: the part of $\\mathbf I(s)(\\dot{\\mathbf V})$ that comes from the section frame
    turning. With $\\mathbf V = \\operatorname{Ad}_g U$ and $\\xi = U - A\\dot q$,
    $\\operatorname{Ad}_{g^{-1}}\\dot{\\mathbf V} = \\dot U + [\\xi, U] = \\dot U - [A\\dot q, U]$."""
    return geo.I_r @ lie.bracket(geo.A @ qdot, U)


def kinetic_covariant_derivative(geo: BundleGeometry, U) -> Float[Array, " d"]:
    """The covector $\\delta q\\mapsto\\nabla_x\\mathbf K(s)(\\delta q)(\\mathbf V)$ of (2.6).

    Local form after (2.5): $\\partial_q \\mathbf K_r(q)(\\delta q)(U) + \\mathbf J_r(q)([\\boldsymbol\\omega_r(\\delta q), U], U)$
    $= \\tfrac12 U^T\\partial_{\\delta q} I_r U + (I_r U)\\cdot[A\\delta q, U]$.
    """
    brackets = lie.bracket(geo.A.T, U)  # [A e_k, U], (d, 6)
    return 0.5 * (geo.dI_r @ U) @ U + brackets @ (geo.I_r @ U)


def curvature_term(geo: BundleGeometry, U, qdot) -> Float[Array, " d"]:
    """The covector $\\delta q\\mapsto\\mathbf J(s)(\\mathbf V, \\Omega_\\Gamma(\\dot x, \\delta x))$ of (2.6).

    Local form after (2.5): $\\mathbf J_r(q)(U, \\Omega_r(\\dot q, \\delta q)) = (I_r U)\\cdot\\Omega_r(\\dot q, \\delta q)$,
    with $\\Omega_r$ the curvature of `bundledyn.curvature`.
    """
    return qdot @ jnp.tensordot(geo.I_r @ U, geo.Omega, 1)


def levi_civita_term(geo: BundleGeometry, qdot) -> Float[Array, " d"]:
    """$\\Gamma(\\dot q, \\dot q)$ lowered: $\\mathcal J_{\\text{def}}(\\nabla^{\\mathbb X}\\dot x/dt, \\cdot) =
    \\mathcal J_{\\text{def}}\\ddot q + \\Gamma(\\dot q,\\dot q)$ (seed 004, before Theorem 2.1).

    $\\Gamma_k(\\dot q,\\dot q) = \\sum_{ij}(\\partial_i \\mathcal J_{kj} - \\tfrac12\\partial_k \\mathcal J_{ij})\\dot q_i\\dot q_j$,
    the Christoffel symbols of the first kind of the shape metric.
    """
    return jnp.tensordot(qdot, geo.dJ_def, 1) @ qdot - 0.5 * (geo.dJ_def @ qdot) @ qdot


def locked_acceleration(geo: BundleGeometry, U, qdot, wrench) -> Float[Array, "6"]:
    """$\\dot U$ from the group equation (2.7) in the section frame.

    $I_r(\\dot U - [A\\dot q, U]) + \\operatorname{ad}^*_U I_r U + \\nabla_x \\mathbf I(\\dot q)\\,U = F_b$.

    **Arguments:**

    - `geo`: the `BundleGeometry` at $q$; `U`: locked velocity; `qdot`: shape velocity.
    - `wrench`: $F_b$, the total wrench on the section frame (section axes, angular first).
    """
    rhs = wrench - coadjoint_term(geo, U)
    if qdot.shape[0]:
        rhs = rhs - inertia_covariant_derivative(geo, qdot) @ U + frame_transport_term(geo, U, qdot)
    return jnp.linalg.solve(geo.I_r, rhs)


def shape_acceleration(geo: BundleGeometry, U, qdot, wrench, shape_force) -> Float[Array, " d"]:
    """$\\ddot q$ from the shape equation (2.6) in local coordinates.

    $\\mathcal J_{\\text{def}}\\ddot q + \\Gamma(\\dot q,\\dot q) - \\nabla_x\\mathbf K(\\cdot)(U)
    + \\mathbf J(U, \\Omega(\\dot q, \\cdot)) = Q_H - A^T F_b$.

    **Arguments:**

    - `wrench`: $F_b$; `shape_force`: $Q_H$ (both in the variables $(\\xi, \\dot q)$).
    """
    Q = shape_force - geo.A.T @ wrench
    rhs = (
        Q
        - levi_civita_term(geo, qdot)
        + kinetic_covariant_derivative(geo, U)
        - curvature_term(geo, U, qdot)
    )
    return jnp.linalg.solve(geo.J_def, rhs)


def reference_accelerations(system: AbstractSystem, q, xi, qdot, wrench, shape_force):
    """$(\\dot\\xi, \\ddot q)$ from the reference (Hamel / Euler–Poincaré) form, DESIGN §3.

    $\\tfrac{d}{dt}(I_r\\xi + B\\dot q) = \\operatorname{ad}_\\xi^T(I_r\\xi + B\\dot q) + F_b$ and
    $\\tfrac{d}{dt}(B^T\\xi + M\\dot q) - \\partial T/\\partial q = Q_H$, i.e.
    $G\\,[\\dot\\xi;\\ddot q] = [\\operatorname{ad}_\\xi^T p;\\ \\tfrac12 v^T\\partial_q G\\, v] + [F_b; Q_H] - \\dot G v$
    with $v = [\\xi;\\dot q]$. It shares nothing with (2.6)–(2.7) but the metric.
    """
    G, dG = system.metric_and_derivative(q)
    v = jnp.concatenate([xi, qdot])
    p = G[:6] @ v
    dT_dq = 0.5 * (dG @ v) @ v
    Gdot_v = jnp.tensordot(qdot, dG, 1) @ v
    rhs = jnp.concatenate([lie.ad(xi).T @ p + wrench, dT_dq + shape_force]) - Gdot_v
    acc = jnp.linalg.solve(G, rhs)
    return acc[:6], acc[6:]
