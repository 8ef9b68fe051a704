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
from ._systems._base import AbstractSystem


class BundleGeometry(NamedTuple):
    """The metric's blocks at one state and their derivatives along its motion.

    Derivatives are along the shape velocity, $\\partial_{\\dot q} X = \\sum_k \\dot q_k\\,
    \\partial X/\\partial q_k$; the covectors are the three $q$-gradients (2.6) uses, at fixed
    velocities: `kinetic_gradient` $= \\tfrac12 U^T \\partial_k I_r U$, `transport_gradient`
    $= (I_r U)\\cdot(\\partial_k A)\\dot q$ and `shape_gradient` $= \\dot q^T \\partial_k
    \\mathcal J_{\\text{def}}\\dot q$. `A[:, j]` is the connection applied to $e_j$. `I_r_inv` is
    `None` for a rigid body ($d = 0$), whose one solve costs less than an inverse.
    """

    U: Float[Array, "6"]
    qdot: Float[Array, " d"]
    I_r: Float[Array, "6 6"]
    I_r_inv: Float[Array, "6 6"] | None
    A: Float[Array, "6 d"]
    J_def: Float[Array, "d d"]
    dI_r: Float[Array, "6 6"]
    dA: Float[Array, "6 d"]
    dJ_def: Float[Array, "d d"]
    kinetic_gradient: Float[Array, " d"]
    transport_gradient: Float[Array, " d"]
    shape_gradient: Float[Array, " d"]


def bundle_geometry(system: AbstractSystem, q, U, qdot) -> BundleGeometry:
    """Locked inertia, connection and shape metric at $q$, and what (2.6)–(2.7) need of
    their derivatives along the motion $(U, \\dot q)$.

    One `system.metric_jet` feeds every term: with $\\partial = \\partial_{\\dot q}$ or $\\partial_k$,
    $\\partial A = I_r^{-1}(\\partial B - \\partial I_r\\,A)$ and
    $\\partial \\mathcal J_{\\text{def}} = \\partial M - \\partial B^T A - B^T \\partial A$; the three
    gradients are the forms $x^T\\partial_k G\\,y$ with $x = [U; 0]$ and $w = [-A\\dot q; \\dot q]$
    (the horizontal lift of $\\dot q$): $\\tfrac12 x^T\\partial_k G x$, $x^T\\partial_k G w$ and
    $w^T\\partial_k G w$. No derivative of a matrix in all $d$ directions is formed.

    **Arguments:**

    - `system`: any system; `q`: shape, `(d,)`; `U`: locked velocity, `(6,)`; `qdot`: `(d,)`.

    **Returns:**

    A `BundleGeometry`.
    """
    if q.shape[0] == 0:  # a rigid body: no shape block to build
        G = system.metric(q)
        zero, none = jnp.zeros((6, 6), G.dtype), jnp.zeros((0,), G.dtype)
        return BundleGeometry(
            U, qdot, G, None, G[:, :0], G[:0, :0], zero, G[:, :0], G[:0, :0], none, none, none
        )
    jet = system.metric_jet(q)
    G, dG = jet.metric, jet.along(qdot)
    I_r, B, M = G[:6, :6], G[:6, 6:], G[6:, 6:]
    dI_r, dB, dM = dG[:6, :6], dG[:6, 6:], dG[6:, 6:]
    # XLA's CPU triangular solve slows down sharply with many right-hand sides; the 6×6
    # locked inertia is SPD and well conditioned, so invert it once and multiply.
    I_inv = jnp.linalg.solve(I_r, jnp.eye(6, dtype=G.dtype))
    A = I_inv @ B
    dA = I_inv @ (dB - dI_r @ A)
    x = jnp.concatenate([U, jnp.zeros_like(qdot)])
    w = jnp.concatenate([-A @ qdot, qdot])
    forms = jet.forms(jnp.stack([x, w]))
    return BundleGeometry(
        U,
        qdot,
        I_r,
        I_inv,
        A,
        M - B.T @ A,
        dI_r,
        dA,
        dM - dB.T @ A - B.T @ dA,
        0.5 * forms[0, 0],
        forms[0, 1],
        forms[1, 1],
    )


def inertia_covariant_derivative(geo: BundleGeometry) -> Float[Array, "6 6"]:
    """$\\nabla_x \\mathbf I(s)(\\dot x)$ in the section frame: the derivative of the locked inertia
    along the horizontal lift of the shape velocity $\\dot q$ (seed 004, (2.4), (2.7)).

    Along the horizontal lift $\\dot g = g\\,\\widehat{(-A\\dot q)}$, $\\mathbf I(s) = \\operatorname{Ad}^*_g I_r
    \\operatorname{Ad}_{g^{-1}}$ changes at the rate $\\operatorname{Ad}^*_g(\\partial_{\\dot q} I_r +
    \\operatorname{ad}_{A\\dot q}^T I_r + I_r \\operatorname{ad}_{A\\dot q})\\operatorname{Ad}_{g^{-1}}$.

    **Returns:**

    The 6×6 matrix $\\partial_{\\dot q} I_r + \\operatorname{ad}_{A\\dot q}^T I_r + I_r\\operatorname{ad}_{A\\dot q}$.
    """
    ad_Au = lie.ad(geo.A @ geo.qdot)
    return geo.dI_r + ad_Au.T @ geo.I_r + geo.I_r @ ad_Au


def coadjoint_term(geo: BundleGeometry) -> Float[Array, "6"]:
    """$\\operatorname{ad}^*_{\\mathbf V}\\mathbf I(s)(\\mathbf V)$ of (2.7) in the section frame:
    $\\operatorname{ad}^*_U I_r U = -\\operatorname{ad}_U^T I_r U$ (the seed's $\\operatorname{ad}^* = -\\operatorname{ad}^T$)."""
    return lie.coad(geo.U) @ (geo.I_r @ geo.U)


def frame_transport_term(geo: BundleGeometry) -> Float[Array, "6"]:
    """$I_r[A\\dot q, U]$: the part of $\\mathbf I(s)(\\dot{\\mathbf V})$ that comes from the section frame
    turning. With $\\mathbf V = \\operatorname{Ad}_g U$ and $\\xi = U - A\\dot q$,
    $\\operatorname{Ad}_{g^{-1}}\\dot{\\mathbf V} = \\dot U + [\\xi, U] = \\dot U - [A\\dot q, U]$."""
    return geo.I_r @ lie.bracket(geo.A @ geo.qdot, geo.U)


def kinetic_covariant_derivative(geo: BundleGeometry) -> Float[Array, " d"]:
    """The covector $\\delta q\\mapsto\\nabla_x\\mathbf K(s)(\\delta q)(\\mathbf V)$ of (2.6).

    Local form after (2.5): $\\partial_q \\mathbf K_r(q)(\\delta q)(U) + \\mathbf J_r(q)([\\boldsymbol\\omega_r(\\delta q), U], U)$
    $= \\tfrac12 U^T\\partial_{\\delta q} I_r U + (I_r U)\\cdot[A\\delta q, U]$.
    """
    brackets = lie.bracket(geo.A.T, geo.U)  # [A e_k, U], (d, 6)
    return geo.kinetic_gradient + brackets @ (geo.I_r @ geo.U)


def curvature_term(geo: BundleGeometry) -> Float[Array, " d"]:
    """The covector $\\delta q\\mapsto\\mathbf J(s)(\\mathbf V, \\Omega_\\Gamma(\\dot x, \\delta x))$ of (2.6).

    Local form after (2.5): $\\mathbf J_r(q)(U, \\Omega_r(\\dot q, \\delta q)) = (I_r U)\\cdot\\Omega_r(\\dot q, \\delta q)$
    with $\\Omega_r(u, w) = (\\partial_u A)w - (\\partial_w A)u - [Au, Aw]$, the curvature of
    `bundledyn.curvature`: $(I_r U)\\cdot\\big((\\partial_{\\dot q}A)e_k - [A\\dot q, A e_k]\\big)$ minus
    the transport gradient $(I_r U)\\cdot(\\partial_k A)\\dot q$.
    """
    mu = geo.I_r @ geo.U
    brackets = lie.bracket(geo.A @ geo.qdot, geo.A.T)  # [A q̇, A e_k], (d, 6)
    return mu @ geo.dA - brackets @ mu - geo.transport_gradient


def levi_civita_term(geo: BundleGeometry) -> Float[Array, " d"]:
    """$\\Gamma(\\dot q, \\dot q)$ lowered: $\\mathcal J_{\\text{def}}(\\nabla^{\\mathbb X}\\dot x/dt, \\cdot) =
    \\mathcal J_{\\text{def}}\\ddot q + \\Gamma(\\dot q,\\dot q)$ (seed 004, before Theorem 2.1).

    $\\Gamma_k(\\dot q,\\dot q) = \\sum_{ij}(\\partial_i \\mathcal J_{kj} - \\tfrac12\\partial_k \\mathcal J_{ij})\\dot q_i\\dot q_j
    = (\\partial_{\\dot q}\\mathcal J_{\\text{def}}\\,\\dot q)_k - \\tfrac12\\dot q^T\\partial_k\\mathcal J_{\\text{def}}\\dot q$,
    the Christoffel symbols of the first kind of the shape metric.
    """
    return geo.dJ_def @ geo.qdot - 0.5 * geo.shape_gradient


def locked_acceleration(geo: BundleGeometry, wrench) -> Float[Array, "6"]:
    """$\\dot U$ from the group equation (2.7) in the section frame.

    $I_r(\\dot U - [A\\dot q, U]) + \\operatorname{ad}^*_U I_r U + \\nabla_x \\mathbf I(\\dot q)\\,U = F_b$.

    **Arguments:**

    - `geo`: the `BundleGeometry` of the state.
    - `wrench`: $F_b$, the total wrench on the section frame (section axes, angular first).
    """
    rhs = wrench - coadjoint_term(geo)
    if geo.I_r_inv is None:
        return jnp.linalg.solve(geo.I_r, rhs)
    rhs = rhs - inertia_covariant_derivative(geo) @ geo.U + frame_transport_term(geo)
    return geo.I_r_inv @ rhs


def shape_acceleration(geo: BundleGeometry, wrench, shape_force) -> Float[Array, " d"]:
    """$\\ddot q$ from the shape equation (2.6) in local coordinates.

    $\\mathcal J_{\\text{def}}\\ddot q + \\Gamma(\\dot q,\\dot q) - \\nabla_x\\mathbf K(\\cdot)(U)
    + \\mathbf J(U, \\Omega(\\dot q, \\cdot)) = Q_H - A^T F_b$.

    **Arguments:**

    - `geo`: the `BundleGeometry` of the state.
    - `wrench`: $F_b$; `shape_force`: $Q_H$ (both in the variables $(\\xi, \\dot q)$).
    """
    Q = shape_force - geo.A.T @ wrench
    rhs = Q - levi_civita_term(geo) + kinetic_covariant_derivative(geo) - curvature_term(geo)
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
