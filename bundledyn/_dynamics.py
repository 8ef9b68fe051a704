r"""Equations of motion: Chevallier's (2.6)–(2.7) term by term, and the reference (Hamel) form.

Everything is written in the section frame of a local trivialization $s = g\cdot r(q)$
(seed 004, §2): $U = \operatorname{Ad}_{g^{-1}}\mathbf V$ is the locked velocity, $\xi = U - A\dot q$
the body velocity of the section frame, $I_r$ the locked inertia, $A$ the connection,
$\mathcal J_{\text{def}}$ the shape metric and $\Omega$ the curvature (see `bundledyn.curvature`).
Forces are generalized forces in the variables $(\xi, \dot q)$: a wrench $F_b$ on the section
frame (angular first, section axes) and a shape force $Q_H$; in the variables $(U, \dot q)$
they become $F_b$ and $Q = Q_H - A^T F_b$ (virtual work $F_b\cdot\delta\xi + Q_H\cdot\delta q$
with $\delta\xi = \delta U - A\,\delta q$).
"""

from typing import NamedTuple

import jax.numpy as jnp
from jaxtyping import Array, Float

from . import lie
from ._linalg import matmul, spd_inverse_6x6, spd_solve
from ._systems._base import AbstractSystem


class BundleGeometry(NamedTuple):
    r"""The metric's blocks at one state and what (2.6)–(2.7) need of their derivatives.

    Derivatives are along the shape velocity, $\partial_{\dot q} X = \sum_k \dot q_k\,
    \partial X/\partial q_k$, and every one enters the equations applied to a velocity, so only
    those products are kept: `dI_r_U` $= (\partial_{\dot q} I_r)U$, `dA_qdot` $=
    (\partial_{\dot q} A)\dot q$, `momentum_dA` $= (I_r U)^T\partial_{\dot q} A$ and `dJ_def_qdot`
    $= (\partial_{\dot q}\mathcal J_{\text{def}})\dot q$. The covectors are the three $q$-gradients
    (2.6) uses, at fixed velocities: `kinetic_gradient` $= \tfrac12 U^T \partial_k I_r U$,
    `transport_gradient` $= (I_r U)\cdot(\partial_k A)\dot q$ and `shape_gradient` $= \dot q^T
    \partial_k \mathcal J_{\text{def}}\dot q$. `A[:, j]` is the connection applied to $e_j$.
    """

    U: Float[Array, "6"]
    qdot: Float[Array, " d"]
    I_r: Float[Array, "6 6"]
    I_r_inv: Float[Array, "6 6"]
    A: Float[Array, "6 d"]
    J_def: Float[Array, "d d"]
    dI_r_U: Float[Array, "6"]
    dA_qdot: Float[Array, "6"]
    momentum_dA: Float[Array, " d"]
    dJ_def_qdot: Float[Array, " d"]
    kinetic_gradient: Float[Array, " d"]
    transport_gradient: Float[Array, " d"]
    shape_gradient: Float[Array, " d"]


def bundle_geometry(system: AbstractSystem, q, U, qdot) -> BundleGeometry:
    r"""Locked inertia, connection and shape metric at $q$, and what (2.6)–(2.7) need of
    their derivatives along the motion $(U, \dot q)$.

    One `system.metric_jet` feeds every term, through the velocities $x = [U; 0]$ and
    $w = [-A\dot q; \dot q]$ (the horizontal lift of $\dot q$). With $\partial = \partial_{\dot q}$,
    $\partial A = I_r^{-1}(\partial B - \partial I_r\,A)$ and $\partial\mathcal J_{\text{def}} =
    \partial M - \partial B^T A - B^T\partial A$, so the applied derivatives are read off
    $\partial G\,x = [\partial I_r U; \partial B^T U]$ and $\partial G\,w$:
    $(I_r U)^T\partial A = (\partial G x)_q - A^T(\partial G x)_\xi$,
    $(\partial A)\dot q = I_r^{-1}(\partial G w)_\xi$ and
    $(\partial\mathcal J_{\text{def}})\dot q = (\partial G w)_q - A^T(\partial G w)_\xi$.
    The three gradients are the forms $\tfrac12 x^T\partial_k G x$, $x^T\partial_k G w$ and
    $w^T\partial_k G w$. No derivative of a matrix is formed.

    **Arguments:**

    - `system`: any system; `q`: shape, `(d,)`; `U`: locked velocity, `(6,)`; `qdot`: `(d,)`.

    **Returns:**

    A `BundleGeometry`.
    """
    if q.shape[0] == 0:  # a rigid body: no shape block to build
        G = system.metric(q)
        zero, none = jnp.zeros(6, G.dtype), jnp.zeros((0,), G.dtype)
        return BundleGeometry(
            U,
            qdot,
            G,
            spd_inverse_6x6(G),
            G[:, :0],
            G[:0, :0],
            zero,
            zero,
            none,
            none,
            none,
            none,
            none,
        )
    jet = system.metric_jet(q)
    G = jet.metric
    I_r, B, M = G[:6, :6], G[:6, 6:], G[6:, 6:]
    I_inv = spd_inverse_6x6(I_r)  # one inverse serves A, ∂A and U̇
    A = matmul(I_inv, B)
    x = jnp.concatenate([U, jnp.zeros_like(qdot)])
    w = jnp.concatenate([-matmul(A, qdot), qdot])
    xw = jnp.stack([x, w])
    dGx, dGw = jet.along_applied(qdot, xw)
    forms = jet.forms(xw)
    return BundleGeometry(
        U,
        qdot,
        I_r,
        I_inv,
        A,
        M - matmul(B.T, A),
        dGx[:6],
        matmul(I_inv, dGw[:6]),
        dGx[6:] - matmul(A.T, dGx[:6]),
        dGw[6:] - matmul(A.T, dGw[:6]),
        0.5 * forms[0, 0],
        forms[0, 1],
        forms[1, 1],
    )


def inertia_covariant_derivative(geo: BundleGeometry) -> Float[Array, "6"]:
    r"""$\nabla_x \mathbf I(s)(\dot x)\,\mathbf V$ in the section frame: the derivative of the
    locked inertia along the horizontal lift of the shape velocity $\dot q$, applied to the
    velocity (seed 004, (2.4), (2.7)).

    Along the horizontal lift $\dot g = g\,\widehat{(-A\dot q)}$, $\mathbf I(s) = \operatorname{Ad}^*_g I_r
    \operatorname{Ad}_{g^{-1}}$ changes at the rate $\operatorname{Ad}^*_g(\partial_{\dot q} I_r +
    \operatorname{ad}_{A\dot q}^T I_r + I_r \operatorname{ad}_{A\dot q})\operatorname{Ad}_{g^{-1}}$.

    **Returns:**

    $(\partial_{\dot q} I_r + \operatorname{ad}_{A\dot q}^T I_r + I_r\operatorname{ad}_{A\dot q})U$, shape `(6,)`.
    """
    Au = matmul(geo.A, geo.qdot)
    return (
        geo.dI_r_U
        - lie.coad_action(Au, matmul(geo.I_r, geo.U))
        + matmul(geo.I_r, lie.bracket(Au, geo.U))
    )


def coadjoint_term(geo: BundleGeometry) -> Float[Array, "6"]:
    r"""$\operatorname{ad}^*_{\mathbf V}\mathbf I(s)(\mathbf V)$ of (2.7) in the section frame:
    $\operatorname{ad}^*_U I_r U = -\operatorname{ad}_U^T I_r U$ (the seed's $\operatorname{ad}^* = -\operatorname{ad}^T$)."""
    return lie.coad_action(geo.U, matmul(geo.I_r, geo.U))


def frame_transport_term(geo: BundleGeometry) -> Float[Array, "6"]:
    r"""$I_r[A\dot q, U]$: the part of $\mathbf I(s)(\dot{\mathbf V})$ that comes from the section frame
    turning. With $\mathbf V = \operatorname{Ad}_g U$ and $\xi = U - A\dot q$,
    $\operatorname{Ad}_{g^{-1}}\dot{\mathbf V} = \dot U + [\xi, U] = \dot U - [A\dot q, U]$."""
    return matmul(geo.I_r, lie.bracket(matmul(geo.A, geo.qdot), geo.U))


def kinetic_covariant_derivative(geo: BundleGeometry) -> Float[Array, " d"]:
    r"""The covector $\delta q\mapsto\nabla_x\mathbf K(s)(\delta q)(\mathbf V)$ of (2.6).

    Local form after (2.5): $\partial_q \mathbf K_r(q)(\delta q)(U) + \mathbf J_r(q)([\boldsymbol\omega_r(\delta q), U], U)$
    $= \tfrac12 U^T\partial_{\delta q} I_r U + (I_r U)\cdot[A\delta q, U]$.
    """
    brackets = lie.bracket(geo.A.T, geo.U)  # [A e_k, U], (d, 6)
    return geo.kinetic_gradient + matmul(brackets, matmul(geo.I_r, geo.U))


def curvature_term(geo: BundleGeometry) -> Float[Array, " d"]:
    r"""The covector $\delta q\mapsto\mathbf J(s)(\mathbf V, \Omega_\Gamma(\dot x, \delta x))$ of (2.6).

    Local form after (2.5): $\mathbf J_r(q)(U, \Omega_r(\dot q, \delta q)) = (I_r U)\cdot\Omega_r(\dot q, \delta q)$
    with $\Omega_r(u, w) = (\partial_u A)w - (\partial_w A)u - [Au, Aw]$, the curvature of
    `bundledyn.curvature`: $(I_r U)\cdot\big((\partial_{\dot q}A)e_k - [A\dot q, A e_k]\big)$ minus
    the transport gradient $(I_r U)\cdot(\partial_k A)\dot q$.
    """
    brackets = lie.bracket(matmul(geo.A, geo.qdot), geo.A.T)  # [A q̇, A e_k], (d, 6)
    return geo.momentum_dA - matmul(brackets, matmul(geo.I_r, geo.U)) - geo.transport_gradient


def levi_civita_term(geo: BundleGeometry) -> Float[Array, " d"]:
    r"""$\Gamma(\dot q, \dot q)$ lowered: $\mathcal J_{\text{def}}(\nabla^{\mathbb X}\dot x/dt, \cdot) =
    \mathcal J_{\text{def}}\ddot q + \Gamma(\dot q,\dot q)$ (seed 004, before Theorem 2.1).

    $\Gamma_k(\dot q,\dot q) = \sum_{ij}(\partial_i \mathcal J_{kj} - \tfrac12\partial_k \mathcal J_{ij})\dot q_i\dot q_j
    = (\partial_{\dot q}\mathcal J_{\text{def}}\,\dot q)_k - \tfrac12\dot q^T\partial_k\mathcal J_{\text{def}}\dot q$,
    the Christoffel symbols of the first kind of the shape metric.
    """
    return geo.dJ_def_qdot - 0.5 * geo.shape_gradient


def locked_acceleration(geo: BundleGeometry, wrench) -> Float[Array, "6"]:
    r"""$\dot U$ from the group equation (2.7) in the section frame.

    $I_r(\dot U - [A\dot q, U]) + \operatorname{ad}^*_U I_r U + \nabla_x \mathbf I(\dot q)\,U = F_b$.

    **Arguments:**

    - `geo`: the `BundleGeometry` of the state.
    - `wrench`: $F_b$, the total wrench on the section frame (section axes, angular first).
    """
    rhs = wrench - coadjoint_term(geo)
    if geo.qdot.shape[0]:  # the shape terms vanish identically for a rigid body
        rhs = rhs - inertia_covariant_derivative(geo) + frame_transport_term(geo)
    return matmul(geo.I_r_inv, rhs)


def shape_acceleration(geo: BundleGeometry, wrench, shape_force) -> Float[Array, " d"]:
    r"""$\ddot q$ from the shape equation (2.6) in local coordinates.

    $\mathcal J_{\text{def}}\ddot q + \Gamma(\dot q,\dot q) - \nabla_x\mathbf K(\cdot)(U)
    + \mathbf J(U, \Omega(\dot q, \cdot)) = Q_H - A^T F_b$.

    **Arguments:**

    - `geo`: the `BundleGeometry` of the state.
    - `wrench`: $F_b$; `shape_force`: $Q_H$ (both in the variables $(\xi, \dot q)$).
    """
    Q = shape_force - matmul(geo.A.T, wrench)
    rhs = Q - levi_civita_term(geo) + kinetic_covariant_derivative(geo) - curvature_term(geo)
    return spd_solve(geo.J_def, rhs)


def reference_accelerations(system: AbstractSystem, q, xi, qdot, wrench, shape_force):
    r"""$(\dot\xi, \ddot q)$ from the reference (Hamel / Euler–Poincaré) form, architecture §3.

    $\tfrac{d}{dt}(I_r\xi + B\dot q) = \operatorname{ad}_\xi^T(I_r\xi + B\dot q) + F_b$ and
    $\tfrac{d}{dt}(B^T\xi + M\dot q) - \partial T/\partial q = Q_H$, i.e.
    $G\,[\dot\xi;\ddot q] = [\operatorname{ad}_\xi^T p;\ \tfrac12 v^T\partial_q G\, v] + [F_b; Q_H] - \dot G v$
    with $v = [\xi;\dot q]$. It shares nothing with (2.6)–(2.7) but the metric.
    """
    G, dG = system.metric_and_derivative(q)
    v = jnp.concatenate([xi, qdot])
    p = G[:6] @ v
    dT_dq = 0.5 * (dG @ v) @ v
    Gdot_v = jnp.tensordot(qdot, dG, 1) @ v
    rhs = jnp.concatenate([lie.ad(xi).T @ p + wrench, dT_dq + shape_force]) - Gdot_v
    acc = jnp.linalg.solve(G, rhs)
    return acc[:6], acc[6:]


def _shape_rows(system: AbstractSystem, q, xi, qdot):
    r"""$M$, $B^T$ and $\tfrac12 v^T\partial_q G\,v - (\partial_{\dot q}G\,v)_q$ at $v = [\xi; \dot q]$:
    the parts of the reference form's shape rows that do not involve the accelerations."""
    jet = system.metric_jet(q)
    G = jet.metric
    v = jnp.concatenate([xi, qdot])[None]
    dG_v = jet.along_applied(qdot, v)[0]
    return G[6:, 6:], G[6:, :6], 0.5 * jet.forms(v)[0, 0] - dG_v[6:]


def driven_shape_acceleration(system: AbstractSystem, q, xi, xi_dot, qdot, shape_force):
    r"""$\ddot q$ when the section frame's motion is given: a fixed or moving base.

    The shape rows of the reference form (architecture §3; seed 004's shape equation with the
    base's motion known, the dual of the prescribed shape of (2.7)):
    $\tfrac{d}{dt}(B^T\xi + M\dot q) - \partial T/\partial q = Q_H$, i.e.
    $M\ddot q = Q_H + \tfrac12 v^T\partial_q G\,v - (\partial_{\dot q}G\,v)_q - B^T\dot\xi$,
    $v = [\xi;\dot q]$, from the metric jet's contractions.

    **Arguments:**

    - `system`: any system; `q`, `qdot`: the shape and its velocity, `(d,)`.
    - `xi`, `xi_dot`: the section frame's given body velocity and its rate, `(6,)`.
    - `shape_force`: $Q_H$ of the scene's effects, `(d,)`.

    **Returns:**

    $\ddot q$, `(d,)`.
    """
    M, Bt, bias = _shape_rows(system, q, xi, qdot)
    return spd_solve(M, shape_force + bias - matmul(Bt, xi_dot))


def driven_shape_force(system: AbstractSystem, q, xi, xi_dot, qdot, qddot):
    r"""The shape force $Q_H$ that gives the motion $(q, \dot q, \ddot q)$ when the section
    frame moves with $(\xi, \dot\xi)$: the inverse of `driven_shape_acceleration`, e.g. the
    joint torques of an arm on a fixed or moving base.

    **Arguments:**

    - `system`, `q`, `xi`, `xi_dot`, `qdot`: as in `driven_shape_acceleration`.
    - `qddot`: the shape acceleration, `(d,)`.

    **Returns:**

    $Q_H = M\ddot q + B^T\dot\xi - \tfrac12 v^T\partial_q G\,v + (\partial_{\dot q}G\,v)_q$, `(d,)`.
    """
    M, Bt, bias = _shape_rows(system, q, xi, qdot)
    return matmul(M, qddot) + matmul(Bt, xi_dot) - bias
