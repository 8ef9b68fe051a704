"""The starting step of adaptive solves (Hairer, Nørsett & Wanner, Solving ODEs I, §II.4)."""

import diffrax
import jax
import jax.numpy as jnp
import numpy as np

import bundledyn as bd
from bundledyn import lie

# A homogeneous ball: with the angular and linear velocity parallel its twist is constant
# (Euler–Poincaré: Jω × ω = 0, m v × ω = 0), so f(t1, y1) = f(t0, y0) and the algorithm
# reduces to h = min(100 h0, (0.01 / d1)^(1/p)), computed by hand below.
BALL = bd.Scene(bd.RigidBody(1.5, [0.0, 0.0, 0.0], 0.4 * np.eye(3)))
G0 = lie.se3_exp(jnp.array([0.3, -0.2, 0.5, 1.0, 2.0, -1.0]))
RTOL, ATOL, T1 = 1e-9, 1e-11, 3.0
ORDER = 8  # RKMK87's error order


def steps(xi):
    return bd.simulate(
        BALL, bd.State(G0, xi=xi), T1, rtol=RTOL, atol=ATOL, saveat=diffrax.SaveAt(steps=True)
    )


def by_hand(xi):
    """Hairer's starting step for the ball, whose twist is constant: f1 = f0, d2 = 0."""
    g0, xi = np.asarray(G0), np.asarray(xi)

    def rms(*pairs):  # (value, the state entries that scale it)
        ratios = [(v / (ATOL + RTOL * np.abs(y))).ravel() for v, y in pairs]
        return np.sqrt(np.mean(np.concatenate(ratios) ** 2))

    d0 = rms((g0, g0), (xi, xi))
    d1 = rms((np.asarray(lie.hat(xi)), g0), (np.zeros(6), xi))
    h0 = 0.01 * d0 / d1
    return min(100 * h0, (0.01 / d1) ** (1 / ORDER))


def test_first_step_is_hairers_starting_step():
    """The first step of a default solve is the starting step computed by hand, not
    diffrax's 0.01, and the step is accepted (the motion is integrated exactly)."""
    omega = jnp.array([0.2, -0.1, 0.3])
    for speed in (1.0, 30.0):
        xi = speed * jnp.concatenate([omega, 2.0 * omega])
        traj = steps(xi)
        h = by_hand(xi)
        assert abs(h - 0.01) > 0.01
        np.testing.assert_allclose(traj.ts[0], h, rtol=1e-12)
        assert int(traj.stats["num_rejected_steps"]) == 0


def test_starting_step_at_rest_is_finite_and_not_differentiated():
    """At rest d1 = 0, the algorithm's singular point: the step is its 1e-6 fallback, and
    gradients through the solve are finite and correct (the step is not differentiated):
    the ball's final position is T1 v, so d(Σ position)/dξ = (0, 0, 0, T1, T1, T1)."""
    traj = steps(jnp.zeros(6))
    np.testing.assert_allclose(traj.ts[0], 1e-6, rtol=1e-12)

    def position_sum(xi):
        traj = bd.simulate(BALL, bd.State(jnp.eye(4), xi=xi), T1, rtol=RTOL, atol=ATOL)
        return jnp.sum(traj.g[-1, :3, 3])

    grad = jax.grad(position_sum)(jnp.zeros(6))
    np.testing.assert_allclose(grad, [0.0, 0.0, 0.0, T1, T1, T1], atol=1e-9)
