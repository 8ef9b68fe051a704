r"""Appell's equations (§60 of seed 001): the energy of accelerations, by autodiff of $T$."""

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .. import lie
from .._linalg import spd_solve
from ._body_motion import BodyMotion
from ._constraints import as_time, motion
from ._system import AbstractNonholonomicSystem


def _coefficients(system: AbstractNonholonomicSystem, q, e, t):
    r"""What $S$ is made of at $(q, e, t)$: $\eta$, $\dot q$, the part $c$ of $\ddot q$ free of
    $\dot e$, $M = \partial^2T/\partial\dot q^2$ and $h$ (`acceleration_energy`); none depends
    on $\dot e$, so they are computed once and $S$'s derivatives in $\dot e$ are cheap."""
    eta, qdot, drift = motion(system.constraints, q, e, t)
    T = system.kinetic_energy
    dp_dq, M, dp_dt = jax.jacfwd(jax.grad(T, argnums=1), argnums=(0, 1, 2))(q, qdot, t)
    h = dp_dq @ qdot + dp_dt - jax.grad(T, argnums=0)(q, qdot, t)
    return eta, qdot, drift, M, h


def _energy(coefficients, edot):
    eta, _, drift, M, h = coefficients
    qddot = eta @ edot + drift
    return 0.5 * qddot @ (M @ qddot) + h @ qddot


def acceleration_energy(
    system: AbstractNonholonomicSystem,
    q: Float[Array, " n"],
    e: Float[Array, " nu"],
    edot: Float[Array, " nu"],
    t,
) -> Float[Array, ""]:
    r"""The energy of accelerations $S = \tfrac12\sum_i m_i\,a_i\cdot a_i$ (§60), up to terms free of $\ddot q$.

    For $T = \tfrac12\sum_i m_i v_i\cdot v_i$ with $v_i = \sum_h \partial_{q_h}P_i\,\dot q_h +
    \partial_t P_i$ (33), the accelerations are $a_i = \sum_h \partial_{q_h}P_i\,\ddot q_h +
    \dots$ (95) with the omitted terms free of $\ddot q$, so

    $$ S = \tfrac12\,\ddot q^T M\,\ddot q + h^T\ddot q + (\text{terms free of } \ddot q), \qquad
       M = \frac{\partial^2 T}{\partial\dot q^2},\quad
       h = \frac{\partial^2 T}{\partial\dot q\,\partial q}\dot q
         + \frac{\partial^2 T}{\partial\dot q\,\partial t} - \frac{\partial T}{\partial q}, $$

    since $\partial S/\partial\ddot q_h = \sum_i m_i a_i\cdot\partial_{q_h}P_i = \tau_h$ (38):
    $S$ is the function whose gradient in $\ddot q$ is Lagrange's binomials. The terms free of
    $\ddot q$ are left out: they depend on $(q, e, t)$ only, and Appell's equations read
    $S$'s derivatives in $\dot e$. Here $\ddot q = \frac{d}{dt}(\eta e + \eta_0)$ along (77),
    and $M$ and $h$ come from the Jacobian of $\partial T/\partial\dot q$ in $(q, \dot q, t)$
    by autodiff (not the directional derivative Maggi's equations use).

    **Arguments:**

    - `system`: an `AbstractNonholonomicSystem`.
    - `q`: the coordinates, shape `(n,)`.
    - `e`, `edot`: the characteristics and their rates, shape `(nu,)`.
    - `t`: the time.

    **Returns:**

    $S$, a scalar, quadratic in `edot`.
    """
    return _energy(_coefficients(system, q, e, as_time(t, q)), edot)


def appell_accelerations(
    system: AbstractNonholonomicSystem, q: Float[Array, " n"], e: Float[Array, " nu"], t
) -> Float[Array, " nu"]:
    r"""The rates $\dot e$ that solve Appell's equations $\partial S/\partial\dot e_\alpha = \Phi_\alpha$ (§60).

    $S$ (`acceleration_energy`) is quadratic in $\dot e$, so its gradient at $\dot e = 0$ and
    its Hessian (both by autodiff in $\dot e$) give $\dot e = -(\partial^2S/\partial\dot e^2)^{-1}
    (\partial S/\partial\dot e|_0 - \Phi)$, by Cholesky; $\Phi_\alpha = \sum_h\eta_{h\alpha}Q_h$
    as (81). The same $\dot e$ as Maggi's equations (82), of which these are a rewriting.

    **Arguments:**

    - `system`: an `AbstractNonholonomicSystem`.
    - `q`: the coordinates, shape `(n,)`; `e`: the characteristics, shape `(nu,)`.
    - `t`: the time.

    **Returns:**

    $\dot e$, shape `(nu,)`.
    """
    t = as_time(t, q)
    coefficients = _coefficients(system, q, e, t)
    eta, qdot = coefficients[0], coefficients[1]

    def energy(edot):
        return _energy(coefficients, edot)

    zero = jnp.zeros_like(e)
    forces = eta.T @ system.generalized_forces(q, qdot, t)
    gradient = jax.grad(energy)(zero) - forces
    return spd_solve(jax.hessian(energy)(zero), -gradient)


def _pseudo_inertia(inertia):
    r"""The pseudo-inertia $P = \int\bar x\bar x^T dm$ ($\bar x = (x, 1)$) of a rigid body from
    its spatial inertia about the origin: $\int xx^T dm = \tfrac12\operatorname{tr}(I_o)1 - I_o$,
    the first moment $mc$ from the block $m\tilde c$, the mass."""
    rotational, mass = inertia[:3, :3], inertia[3, 3]
    moment = lie.so3_vee(inertia[:3, 3:])
    second = 0.5 * jnp.trace(rotational) * jnp.eye(3, dtype=inertia.dtype) - rotational
    top = jnp.concatenate([second, moment[:, None]], axis=1)
    return jnp.concatenate([top, jnp.concatenate([moment, mass[None]])[None]], axis=0)


def body_acceleration_energy(body: BodyMotion, edot: Float[Array, " nu"]) -> Float[Array, ""]:
    r"""The energy of accelerations $S = \tfrac12\int|a|^2dm$ (§60) of a rigid body whose body twist is $\xi = He$.

    From the material points' accelerations, not from the Euler equations: with the pose
    $g$ and $\dot g = g\hat\xi$, $\ddot g = g(\hat\xi\hat\xi + \hat{\dot\xi})$, the point at
    $\bar x = (x, 1)$ of the body accelerates by $R B\bar x$ with $B$ the top three rows of
    $\hat\xi\hat\xi + \hat{\dot\xi}$, so $S = \tfrac12\operatorname{tr}(BPB^T)$ with the
    pseudo-inertia $P = \int\bar x\bar x^T dm$; here $\dot\xi = H\dot e + \dot He$.

    **Arguments:**

    - `body`: a `BodyMotion` (its wrench is not read).
    - `edot`: the characteristics' rates, shape `(nu,)`.

    **Returns:**

    $S$, a scalar, quadratic in `edot`.
    """
    twist = lie.se3_hat(body.xi)
    B = (twist @ twist + lie.se3_hat(body.H @ edot + body.H_dot_e))[:3]
    return 0.5 * jnp.trace(B @ _pseudo_inertia(body.inertia) @ B.T)


def appell_body_rates(body: BodyMotion) -> Float[Array, " nu"]:
    r"""Appell's equations $\partial S/\partial\dot e_\alpha = \Phi_\alpha$ (§60) for a rigid body whose body twist is $\xi = He$.

    $S$ is `body_acceleration_energy`, quadratic in $\dot e$: its gradient at $\dot e = 0$
    and its Hessian by autodiff give $\dot e$ by Cholesky; the active forces along the
    characteristics are $\Phi = H^TF$ (81), the virtual work of the wrench $F$ on
    $\delta\xi = H\delta\varepsilon$. The same $\dot e$ as `maggi_body_rates`.

    **Arguments:**

    - `body`: a `BodyMotion` ($H$, $\dot He$, $\xi$, $I$, $F$).

    **Returns:**

    $\dot e$, shape `(nu,)`.
    """

    def energy(edot):
        return body_acceleration_energy(body, edot)

    zero = jnp.zeros(body.H.shape[1], body.H.dtype)
    gradient = jax.grad(energy)(zero) - body.H.T @ body.wrench
    return spd_solve(jax.hessian(energy)(zero), -gradient)
