r"""The reverse pass of (2.6)–(2.7): the field's VJP in closed form, through the metric jet.

Autodiff transposes the field's forward pass kernel by kernel, and the reverse of a tree's
many small fused products is several times the field (every broadcast's transpose is a
reduction that ends a fusion). The VJP written out here needs no transpose of the field:
only the metric jet's forward contractions (`forms`, `along_applied`) and the derivative of
`forms` along a shape velocity (`forms_along`, in closed form for trees).

In the Hamel variables $v = [\xi; \dot q]$ the accelerations $a = [\dot\xi; \ddot q]$ solve
the reference form (architecture §3) $G a = h(q, v) + \tau$ with
$h = [\operatorname{ad}_\xi^T p;\ \tfrac12 v^T\partial_q G\,v] - (\partial_{\dot q} G)v$, $p = (Gv)_\xi$,
$\tau = [F_b; Q_H]$; the field's outputs are $\xi = U - A\dot q$, $\dot U = \dot\xi +
(\partial_{\dot q}A)\dot q + A\ddot q$ and $\ddot q$. By the implicit function theorem, a
cotangent $\bar a$ on $a$ becomes $\mu = G^{-1}\bar a$ on $\tau$ and the gradient of
$S = \mu\cdot(h + \tau - G a)$ on $(q, v)$ at fixed $a$. Every $q$-derivative of a term that
already holds one derivative of $G$ is turned into a directional derivative by the symmetry of
second derivatives: $\nabla_q\,\big(x^T(\partial_u G)y\big) = \partial_u\,
\big(k\mapsto x^T\partial_k G\,y\big)$ for $x, y, u$ independent of $q$.
"""

from collections.abc import Callable

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from . import lie
from ._linalg import matmul, spd_inverse_6x6, spd_solve
from ._systems._base import AbstractSystem

__all__ = ["body_field_vjp", "driven_field_vjp"]


def _blocks(system: AbstractSystem, q):
    """The metric jet at `q`, $I_r^{-1}$ and the connection $A = I_r^{-1}B$."""
    jet = system.metric_jet(q)
    I_inv = spd_inverse_6x6(jet.metric[:6, :6])
    return jet, I_inv, matmul(I_inv, jet.metric[:6, 6:])


def _lift(A, u):
    r"""$[-Au; u]$: the horizontal lift of a shape velocity $u$."""
    return jnp.concatenate([-matmul(A, u), u])


def _locked(x, d):
    r"""$[x; 0]$: a twist as a velocity of the whole system, shape at rest."""
    return jnp.concatenate([x, jnp.zeros(d, x.dtype)])


def body_field_vjp(
    system: AbstractSystem,
    q: Float[Array, " d"],
    U: Float[Array, "6"],
    qdot: Float[Array, " d"],
    Udot: Float[Array, "6"],
    qddot: Float[Array, " d"],
    cotangents,
    forces_vjp: Callable,
):
    r"""The VJP of the field $(q, U, \dot q)\mapsto(\xi, \dot U, \ddot q)$ of (2.6)–(2.7)
    (seed 004), written out (module docstring).

    **Arguments:**

    - `system`: a system with a shape, $d > 0$.
    - `q`, `U`, `qdot`: the state; `Udot`, `qddot`: the field's accelerations there.
    - `cotangents`: $(\bar\xi, \bar{\dot U}, \bar{\ddot q})$ on the outputs.
    - `forces_vjp`: the forces' reverse pass: given the cotangent $(\mu_\xi, \mu_q)$ of
      $(F_b, Q_H)$, returns their inputs' cotangents $(\bar q, \bar\xi, \bar{\dot q})$ and
      anything else (`rest`, e.g. the pose's), which is handed back.

    **Returns:**

    $(\bar q, \bar U, \bar{\dot q}, \text{rest})$.
    """
    xi_bar, Udot_bar, qddot_bar = cotangents
    d = q.shape[0]
    jet, I_inv, A = _blocks(system, q)

    def jet_along(u):  # traced only by a jet without closed-form second derivatives
        return jax.jvp(system.metric_jet, (q,), (u,))[1]

    G = jet.metric
    B = G[:6, 6:]
    xi = U - matmul(A, qdot)
    v = jnp.concatenate([xi, qdot])
    w = _lift(A, qdot)
    z = _locked(matmul(I_inv, Udot_bar), d)
    # μ = G⁻¹ā with ā = (Ū̇, q̈̄ + AᵀŪ̇), by the Schur complement J_def = M - BᵀA.
    mu_q = spd_solve(G[6:, 6:] - matmul(B.T, A), qddot_bar)
    mu_xi = matmul(I_inv, Udot_bar - matmul(B, mu_q))
    mu = jnp.concatenate([mu_xi, mu_q])
    along_qdot, T = jet.along_both(qdot, jnp.stack([z, w, mu, v]), jet_along)
    dG_z, dG_w, dG_mu = along_qdot[:3]
    along_mu, T_mu = jet.along_both(mu_q, v[None], jet_along)
    a = jnp.concatenate([Udot - matmul(I_inv, dG_w[:6]) - matmul(A, qddot), qddot])
    e = _locked(lie.bracket(xi, mu_xi), d)  # μ_ξ·ad_ξᵀp = eᵀGv
    p = matmul(G[:6], v)
    v_bar = matmul(G, e) + _locked(-matmul(lie.ad(mu_xi).T, p), d) + along_mu[0] - dG_mu
    q_forces, xi_forces, qdot_forces, rest = forces_vjp(mu_xi, mu_q)
    xi_total = xi_bar + v_bar[:6] + xi_forces
    z_xi = _locked(matmul(I_inv, xi_total), d)
    # z and w move with q through I_r⁻¹ and A: ∂_q̇z = [-I_r⁻¹((∂_q̇G)z)_ξ; 0], ∂_q̇w likewise.
    z_rate = _locked(-matmul(I_inv, dG_z[:6]), d)
    w_rate = _locked(-matmul(I_inv, dG_w[:6]), d)
    F = jet.forms(jnp.stack([z, w, mu, v, e, a, z_xi, _lift(A, qddot), z_rate, w_rate]))
    q_bar = (
        q_forces
        + T[0, 1]
        + F[8, 1]
        + F[0, 9]  # Ū̇·(∂_q̇A)q̇
        - T[2, 3]  # μᵀ(∂_q̇G)v
        + 0.5 * T_mu[0, 0]  # ½vᵀ(∂_{μ_q}G)v
        + F[0, 7]  # Ū̇·(∂A)q̈
        + F[4, 3]  # eᵀGv
        - F[2, 5]  # μᵀGa
        - F[6, 1]  # ξ̄·(∂A)q̇
    )
    qdot_bar = (
        v_bar[6:]
        + qdot_forces
        - F[2, 3]
        + F[0, 1]
        + dG_z[6:]
        - matmul(A.T, dG_z[:6])
        - matmul(A.T, xi_total)
    )
    return q_bar, xi_total, qdot_bar, rest


def driven_field_vjp(
    system: AbstractSystem,
    q: Float[Array, " d"],
    xi: Float[Array, "6"],
    xi_dot: Float[Array, "6"],
    qdot: Float[Array, " d"],
    qddot: Float[Array, " d"],
    qddot_bar: Float[Array, " d"],
    forces_vjp: Callable,
):
    r"""The VJP of the driven shape equation $(q, \dot q)\mapsto\ddot q$ when the section
    frame's motion $(\xi, \dot\xi)$ is given (a fixed or moving base), written out as
    `body_field_vjp` is: the shape rows of the reference form (seed 004, (2.7) with the base's
    motion known), $M\ddot q + B^T\dot\xi = \tfrac12 v^T\partial_q G\,v -
    ((\partial_{\dot q}G)v)_q + Q_H$ with $v = [\xi; \dot q]$.

    By the implicit function theorem the cotangent $\bar{\ddot q}$ becomes
    $\mu = M^{-1}\bar{\ddot q}$ on $Q_H$ and the gradient of
    $S = \tfrac12 v^T(\partial_\mu G)v - m^T(\partial_{\dot q}G)v - m^TGa + \mu\cdot Q_H$
    on $(q, \dot q)$ at fixed $a = [\dot\xi; \ddot q]$, where $m = [0; \mu]$.

    **Arguments:**

    - `system`: a system with a shape, $d > 0$.
    - `q`, `qdot`: the shape and its velocity; `xi`, `xi_dot`: the frame's given twist and
      its rate (a uniform field's acceleration taken off $\dot\xi$, Theorem 3.4, where
      `forces_vjp` leaves it out); `qddot`: the equation's solution there.
    - `qddot_bar`: the cotangent on $\ddot q$.
    - `forces_vjp`: the forces' reverse pass: given the cotangent $\mu$ of $Q_H$, returns
      the cotangents $(\bar q, \bar{\dot q})$ of its inputs.

    **Returns:**

    $(\bar q, \bar{\dot q})$.
    """
    jet = system.metric_jet(q)

    def jet_along(u):  # traced only by a jet without closed-form second derivatives
        return jax.jvp(system.metric_jet, (q,), (u,))[1]

    mu = spd_solve(jet.metric[6:, 6:], qddot_bar)
    m = jnp.concatenate([jnp.zeros(6, mu.dtype), mu])
    v = jnp.concatenate([xi, qdot])
    a = jnp.concatenate([xi_dot, qddot])
    along_qdot, T = jet.along_both(qdot, jnp.stack([m, v]), jet_along)
    along_mu, T_mu = jet.along_both(mu, v[None], jet_along)
    F = jet.forms(jnp.stack([m, v, a]))
    q_forces, qdot_forces = forces_vjp(mu)
    q_bar = q_forces + 0.5 * T_mu[0, 0] - T[0, 1] - F[0, 2]
    qdot_bar = qdot_forces + along_mu[0, 6:] - along_qdot[0, 6:] - F[0, 1]
    return q_bar, qdot_bar
