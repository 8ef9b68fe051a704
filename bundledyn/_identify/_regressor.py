r"""The warm start: equation error on momentum and energy, linear in the inertial parameters.

The metric is linear in the bodies' pseudo-inertias $P_b$ (and the armature), so with the
measured states $(g, q, \xi, \dot q)$ at the samples, the spatial momentum in the Galilean
frame $\mu = \operatorname{Ad}^*_g G(q)_{\xi\cdot}[\xi; \dot q]$ and the energy
$E = T + \Pi$ are affine in the unknowns $\pi$ (the entries of the free $P_b$, the free
joint constants). Their balances over the record,

$$\mu_k - \int_{t_0}^{t_k} \operatorname{Ad}^*_g F_b\,dt = \bar\mu,\qquad
  E_k - \int_{t_0}^{t_k} (F_b\cdot\xi + Q_H\cdot\dot q)_{\text{non-conservative}}\,dt = \bar E,$$

(seed 004, (2.6)–(2.7) with the scene's forces: the wrench of every effect moves the
momentum, the work of the non-conservative ones the energy) are linear in
$(\pi, \bar\mu, \bar E)$ with the unknown constants $\bar\mu, \bar E$: a convex least-squares
problem (the momentum regressor of a free-floating system). On a prescribed base the
shape equation itself is linear in $\pi$ (the torque regressor of a robot arm):
$Q_H$ required by the measured motion (`driven_shape_force`, $\ddot q$ the slope of local
quadratic fits to the measured $\dot q$: differences would amplify its noise) equals the
effects' $Q_H$, inputs included. Either is solved with the gauge's
pseudo-measurements and the integrals by the trapezoidal rule. Its solution is projected
onto physical bodies (each $P_b$'s eigenvalues floored at a small fraction of its largest)
and returned as log-Cholesky coordinates. Directions the balances determine weakly or not
at all stay near their nominal values (a ridge on the change of $\pi$): it is a start,
which the output-error fit refines.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .. import lie
from .._dynamics import driven_shape_force
from .._effects import AbstractPotential, Kinematics
from .._geometry import kinetic_energy
from .._modes import PrescribedBase
from .._state import State
from .._systems._pseudo_inertia import log_cholesky_from_pseudo_inertia
from ._data import Inputs, Measurements
from ._gauge import AbstractGauge
from ._parameters import Parameters

__all__ = ["warm_start"]

_ENTRIES = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2), (0, 3), (1, 3), (2, 3), (3, 3))
_FLOOR = 1e-6  # smallest eigenvalue of a projected pseudo-inertia, relative to its largest
# The ridge's weight against the balances' columns (each scaled to norm 1): faint when known
# inputs do work (their work makes the balances inhomogeneous and fixes every scale they
# excite), strong without (the balances are then homogeneous in π, and least squares on
# noisy data drives them toward their trivial solution: the rotational inertia of a
# torque-free body, whose scale no balance fixes, shrinks toward zero as the noise grows).
_RIDGE = {True: 1e-2, False: 1e-1}


def _entries(P):
    return jnp.stack([P[..., i, j] for i, j in _ENTRIES], axis=-1)


def _matrix(entries):
    P = jnp.zeros((*entries.shape[:-1], 4, 4), entries.dtype)
    for k, (i, j) in enumerate(_ENTRIES):
        P = P.at[..., i, j].set(entries[..., k]).at[..., j, i].set(entries[..., k])
    return P


def _project(P, fixed_centre: bool):
    """The nearest positive definite pseudo-inertia (eigenvalues floored), centre kept at 0
    for a fixed centre."""
    if fixed_centre:
        P = P.at[..., :3, 3].set(0.0).at[..., 3, :3].set(0.0)
    w, V = jnp.linalg.eigh(P)
    w = jnp.maximum(w, _FLOOR * jnp.max(w, axis=-1, keepdims=True))
    return (V * w[..., None, :]) @ jnp.swapaxes(V, -1, -2)


_SMOOTHING = 7  # samples on each side of the local fits that estimate accelerations


def smoothed_derivative(ts, values, half_width: int = _SMOOTHING):
    """The time derivative of sampled `values` `(n, ...)` (NumPy): at each sample, the slope
    of the least-squares quadratic through the `2 half_width + 1` samples around it (fewer
    near the ends; Savitzky & Golay 1964), so that measurement noise is not amplified by
    1/dt as differences would amplify it."""
    ts, values = np.asarray(ts), np.asarray(values)
    n = values.shape[0]
    weights = np.zeros((n, n))
    for i in range(n):
        lo, hi = max(0, i - half_width), min(n, i + half_width + 1)
        tau = ts[lo:hi] - ts[i]
        weights[i, lo:hi] = np.linalg.pinv(np.stack([np.ones_like(tau), tau, tau * tau], 1))[1]
    return np.tensordot(weights, values, axes=1)


def _cumulative_trapezoid(ts, values):
    increments = 0.5 * (values[1:] + values[:-1]) * jnp.diff(ts)[:, None]
    return jnp.concatenate([jnp.zeros_like(values[:1]), jnp.cumsum(increments, axis=0)])


class _Linear(eqx.Module):
    """The scene as an affine function of the linear unknowns π (free P entries, constants)."""

    parameters: Parameters
    extra_effects: list

    def scene(self, pi):
        params = self.parameters
        k = len(params.bodies)
        P = (
            params.system.pseudo_inertias()
            .at[np.array(params.bodies, int)]
            .set(_matrix(pi[: 10 * k].reshape(k, 10)))
        )
        scene = eqx.tree_at(lambda s: s.system, params.scene, params.system.with_pseudo_inertias(P))
        offset = 10 * k
        theta = params.initial()
        for name, nominal in params.joint_constant_values(theta).items():
            size = int(np.size(nominal))
            value = pi[offset : offset + size].reshape(jnp.shape(nominal))
            scene = params.with_joint_constant(scene, name, value)
            offset += size
        return eqx.tree_at(lambda s: s.effects, scene, [*scene.effects, *self.extra_effects])

    def driven_balance(self, pi, t, g, q, xi, xi_dot, qdot, qddot):
        """The shape force the motion requires minus the effects' (inputs included)."""
        scene = self.scene(pi)
        required = driven_shape_force(scene.system, q, xi, xi_dot, qdot, qddot)
        return required - scene.forces(Kinematics(t, g, q, xi, qdot))[1]

    def balances(self, pi, t, g, q, xi, qdot):
        """Momentum (Galilean frame), energy, momentum rate and non-conservative power at one sample."""
        scene = self.scene(pi)
        system = scene.system
        velocity = jnp.concatenate([xi, qdot])
        momentum = lie.coAd(g) @ (system.metric(q)[:6] @ velocity)
        energy = kinetic_energy(system, q, xi, qdot)
        kin = Kinematics(t, g, q, xi, qdot)
        rate, power = jnp.zeros(6, g.dtype), jnp.zeros((), g.dtype)
        for effect in scene.effects:
            F, Q = effect.generalized_force(system, kin)
            rate = rate + lie.coAd(g) @ F
            if isinstance(effect, AbstractPotential):
                energy = energy + effect.potential(system, t, g, q)
            else:
                power = power + F @ xi + Q @ qdot
        return momentum, energy, rate, power


def warm_start(
    parameters: Parameters,
    measurements: Measurements,
    inputs: Inputs | None,
    gauge: AbstractGauge,
    states: State,
):
    r"""The equation-error estimate of $\theta$ (see the module docstring).

    **Arguments:**

    - `parameters`, `measurements`, `inputs`, `gauge`: as in `fit`.
    - `states`: the measured states at the samples (for a prescribed base, its motion and
      the measured $q$, $\dot q$).

    **Returns:**

    $\theta$, projected onto physical bodies.
    """
    linear = _Linear(parameters, [] if inputs is None else inputs.effects())
    theta0 = parameters.initial()
    pi0 = jnp.concatenate(
        [
            _entries(parameters.pseudo_inertias(theta0)).reshape(-1),
            *[jnp.ravel(v) for v in parameters.joint_constant_values(theta0).values()],
        ]
    )
    accelerations = smoothed_derivative(measurements.ts, states.qdot)
    solution = _solve(linear, gauge, pi0, states, measurements.ts, accelerations)
    k = len(parameters.bodies)
    P = _project(_matrix(solution[: 10 * k].reshape(k, 10)), parameters.system.fixed_centres)
    theta = log_cholesky_from_pseudo_inertia(P)[:, : 7 if parameters.system.fixed_centres else 10]
    constants = jnp.log(jnp.maximum(solution[10 * k :], _FLOOR * jnp.abs(pi0[10 * k :])))
    return jnp.concatenate([theta.reshape(-1), constants])


def _floating_equations(linear: _Linear, gauge: AbstractGauge, pi0, states, ts, accelerations):
    r"""The momentum and energy balances of a floating system, with the unknowns
    $(\pi, \bar\mu, \bar E)$: the weighted residual function and its starting point."""

    def balances(pi):
        return jax.vmap(linear.balances, (None, 0, 0, 0, 0, 0))(
            pi, ts, states.g, states.q, states.xi, states.qdot
        )

    momentum0, energy0, _, _ = balances(pi0)
    unknowns0 = jnp.concatenate([pi0, jnp.mean(momentum0, axis=0), jnp.mean(energy0)[None]])
    momentum_scale = jnp.sqrt(jnp.mean(momentum0**2)) + jnp.finfo(pi0.dtype).tiny
    energy_scale = jnp.sqrt(jnp.mean(energy0**2)) + jnp.finfo(pi0.dtype).tiny

    def weighted(unknowns):
        pi, mu_bar, energy_bar = unknowns[:-7], unknowns[-7:-1], unknowns[-1]
        momentum, energy, rate, power = balances(pi)
        momentum_error = momentum - _cumulative_trapezoid(ts, rate) - mu_bar[None, :]
        energy_error = energy - _cumulative_trapezoid(ts, power[:, None])[:, 0] - energy_bar
        return jnp.concatenate(
            [
                momentum_error.reshape(-1) / momentum_scale,
                energy_error / energy_scale,
                _gauge_rows(linear.parameters, gauge, pi),
            ]
        )

    return weighted, unknowns0


def _driven_equations(linear: _Linear, gauge: AbstractGauge, pi0, states, ts, accelerations):
    r"""The shape equation of a prescribed base, $Q_H$ required by the measured motion minus
    the effects' (inputs included), linear in $\pi$; $\ddot q$ by central differences of the
    measured $\dot q$."""
    base = linear.parameters.scene.base
    assert isinstance(base, PrescribedBase)  # the torque regressor is for a prescribed base
    _, _, xi_dot = jax.vmap(base.at)(ts)
    qddot = accelerations

    def balance(pi):
        return jax.vmap(linear.driven_balance, (None, 0, 0, 0, 0, 0, 0, 0))(
            pi, ts, states.g, states.q, states.xi, xi_dot, states.qdot, qddot
        )

    scale = jnp.sqrt(jnp.mean(balance(pi0) ** 2)) + jnp.finfo(pi0.dtype).tiny

    def weighted(pi):
        rows = balance(pi).reshape(-1) / scale
        return jnp.concatenate([rows, _gauge_rows(linear.parameters, gauge, pi)])

    return weighted, pi0


def _gauge_rows(parameters: Parameters, gauge: AbstractGauge, pi) -> jax.Array:
    k = len(parameters.bodies)
    return gauge.mass_rows(parameters, pi[: 10 * k].reshape(k, 10)[:, 9])  # P_44, linear in π


@eqx.filter_jit
def _solve(linear: _Linear, gauge: AbstractGauge, pi0, states, ts, accelerations):
    """The least-squares π of the balances (`_floating_equations` or `_driven_equations`)."""
    driven = isinstance(linear.parameters.scene.base, PrescribedBase)
    equations = _driven_equations if driven else _floating_equations
    weighted, unknowns0 = equations(linear, gauge, pi0, states, ts, accelerations)
    e0 = weighted(unknowns0)
    E = jax.jacfwd(weighted)(unknowns0)
    # Columns scaled to their norms, and a ridge on the change of π (see `_RIDGE`).
    norms = jnp.linalg.norm(E, axis=0)
    scale = jnp.maximum(norms, 1e-8 * jnp.max(norms))  # columns the balances barely see stay put
    weight = _RIDGE[bool(linear.extra_effects)]
    ridge = weight * (jnp.arange(unknowns0.shape[0]) < pi0.shape[0]).astype(unknowns0.dtype)
    A = jnp.concatenate([E / scale[None, :], jnp.diag(ridge)])
    step = jnp.linalg.lstsq(A, jnp.concatenate([-e0, jnp.zeros_like(ridge)]))[0] / scale
    return (unknowns0 + step)[: pi0.shape[0]]
