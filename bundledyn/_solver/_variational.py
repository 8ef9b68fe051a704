"""A Lie-group variational integrator: discrete Euler–Poincaré–Lagrange equations on SE(3) × R^d."""

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
from diffrax import RESULTS

from .. import lie
from .._modes import FreeShapeMode, RigidBodyMode
from .._term import AbstractSceneTerm
from ._base import AbstractLieGroupSolver
from ._chart import body_term, checked_start
from ._interpolation import LieLocalInterpolation


def _scene_term(terms) -> AbstractSceneTerm:
    """The scene term that `terms` is, or that diffrax's wrapper around it holds."""
    term, _ = body_term(terms)
    if not isinstance(term, AbstractSceneTerm):
        raise ValueError("VariationalMidpoint integrates a scene's term (`SceneTerm`).")
    return term


class VariationalMidpoint(AbstractLieGroupSolver):
    r"""A Lie-group variational integrator (fixed step): symplectic and momentum-preserving.

    The discrete Lagrangian of one step $h$ takes the midpoint shape and the exponential
    increment $g_{k+1} = g_k\exp\hat\Omega_k$ (cf. seed 004, (2.1)):
    $\ell_d(\Omega, q_k, q_{k+1}) = \tfrac h2 v^T G(\bar q) v$, $v = [\Omega/h; (q_{k+1}-q_k)/h]$,
    $\bar q = (q_k + q_{k+1})/2$. Varying $g_k = g_k\exp\hat\eta_k$ and $q_k$ (discrete
    Lagrange–d'Alembert with the scene's forces $F_b, Q_H$ applied at the nodes) gives,
    with $\mu_k = \operatorname{dexp}^{-1}(\Omega_k)^T\partial_\Omega\ell_d$,

    $$\operatorname{dexp}^{-1}(-\Omega_k)^T \partial_\Omega\ell_d = m_k + hF_k,\qquad
      D_1\ell_d + \pi_k + hQ_k = 0,$$
    $$m_{k+1} = \mu_k,\qquad \pi_{k+1} = D_2\ell_d,$$

    the discrete analogue of $\dot p = \operatorname{ad}_\xi^T p + F_b$ and of the shape
    equation. With no forces the spatial momentum $\operatorname{Ad}^*_{g_k} m_k$ is conserved
    exactly and the map is symplectic, so the energy error stays bounded instead of
    drifting. Each step solves for $(\Omega_k, q_{k+1})$ by a simplified Newton iteration
    whose Jacobian is $h^{-1}\operatorname{diag}(1, -1)\,G(\bar q)$ (exact to $O(h)$, so
    each iteration gains a factor $O(h)$). Second order.

    Scenes in the Galilean frame with a free shape (or a single rigid body) and a floating
    base; any effects.

    **Arguments:**

    - `iterations`: Newton iterations per step (static; default 8).
    - `tolerance`: a step whose final residual (relative to the momenta) exceeds this
      reports `RESULTS.nonlinear_divergence`.
    """

    iterations: int = eqx.field(static=True, default=8)
    tolerance: float = eqx.field(static=True, default=1e-10)

    term_structure: ClassVar = AbstractSceneTerm
    interpolation_cls: ClassVar = LieLocalInterpolation

    def order(self, terms):
        return 2

    def init(self, terms, t0, t1, y0, args):
        scene = _scene_term(terms).scene
        if scene.frame is not None or not isinstance(scene.mode, FreeShapeMode | RigidBodyMode):
            raise ValueError(
                "VariationalMidpoint integrates scenes in the Galilean frame with a free shape "
                "and a floating base; use RKMK87 (the default) for moving frames, prescribed "
                "shapes or prescribed bases."
            )
        return None

    def func(self, terms, t0, y0, args):
        return terms.vf(t0, y0, args)

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        term = _scene_term(terms)
        y0 = term.recharted(t0, y0)
        h = t1 - t0
        g0, q0, U0, qdot0 = term.unpack(t0, y0)
        d = q0.shape[0]
        G0 = term.metric(q0)
        xi0 = U0 - jnp.linalg.solve(G0[:6, :6], G0[:6, 6:]) @ qdot0 if d else U0
        p0 = G0 @ jnp.concatenate([xi0, qdot0])
        F0, Q0 = term.forces(t0, g0, q0, xi0, qdot0)
        m_target = p0[:6] + h * F0
        pi_target = p0[6:] + h * Q0

        def parts(z):  # z = (Ω, q_{k+1} - q_k) = h v
            Omega, v = z[:6], z / h
            if d:
                G, dG = term.metric_and_derivative(q0 + 0.5 * z[6:])
                curvature_force = 0.25 * h * (dG @ v) @ v
            else:
                G, curvature_force = term.metric(q0), jnp.zeros(0, q0.dtype)
            Gv = G @ v
            return Omega, Gv, curvature_force

        def residual(z):
            Omega, Gv, curvature_force = parts(z)
            R1 = lie.se3_dexp_inv(-Omega).T @ Gv[:6] - m_target
            R2 = curvature_force - Gv[6:] + pi_target
            return jnp.concatenate([R1, R2])

        z0 = h * jnp.concatenate([xi0, qdot0])
        jacobian = jnp.concatenate([G0[:6], -G0[6:]]) / h  # Newton matrix at the guess

        def newton(_, z):
            return z - jnp.linalg.solve(jacobian, residual(z))

        z = jax.lax.fori_loop(0, self.iterations, newton, z0)
        Omega, Gv, curvature_force = parts(z)
        m1 = lie.se3_dexp_inv(Omega).T @ Gv[:6]
        pi1 = curvature_force + Gv[6:]
        q1 = z[6:] + q0
        # Velocities at the new node from its momenta: [ξ; q̇] = G(q1)⁻¹ [m; π].
        G1 = term.metric(q1)
        v1 = jnp.linalg.solve(G1, jnp.concatenate([m1, pi1]))
        U1 = jnp.linalg.solve(G1[:6, :6], m1)
        y1 = term.pack(t1, g0 @ lie.se3_exp(Omega), q1, U1, v1[6:])
        y1 = checked_start(y1, t0, t1, y0, (p0, F0, Q0))
        error = jnp.max(jnp.abs(residual(z))) / (jnp.max(jnp.abs(p0)) + jnp.finfo(p0.dtype).tiny)
        # Equinox's enumerations inherit their parent's items (`nonlinear_divergence` is
        # Optimistix's): at run time it is diffrax's `RESULTS`, pyright sees Optimistix's.
        result = RESULTS.where(
            error < self.tolerance,
            RESULTS.successful,
            RESULTS.nonlinear_divergence,  # pyright: ignore[reportArgumentType]
        )
        dense_info = dict(y0=y0, coeffs=(Omega[None], (y1[1] - y0[1])[None]))
        return y1, None, dense_info, None, result
