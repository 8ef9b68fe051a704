"""`CentreOfMassMode`: a floating body integrated about its centre of mass takes the steps it
takes at rest at any uniform velocity, and follows an orbit in the Earth's gravity gradient as
Euler's and Newton's equations integrated by SciPy's DOP853 do."""

import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

import bundledyn as bd

MU_EARTH = 3.986004418e14  # m³/s²
MASS, INERTIA = 2.0, np.diag([0.1, 0.2, 0.3])
SPIN = np.array([0.3, 1.5, 0.2])
ORBIT_RADIUS, ORBIT_SPEED = 7e6, 7546.0  # a circular orbit's speed at that radius
BOX = bd.RigidBody(MASS, jnp.zeros(3), jnp.asarray(INERTIA))


def _start(speed):
    """The spinning box at the orbit's radius moving at `speed` along y."""
    g = jnp.eye(4).at[0, 3].set(ORBIT_RADIUS)
    return bd.State(g, xi=jnp.concatenate([jnp.asarray(SPIN), jnp.array([0.0, speed, 0.0])]))


def _attitude_difference(R, R_ref):
    return float(
        np.linalg.norm(Rotation.from_matrix(np.asarray(R_ref).T @ np.asarray(R)).as_rotvec())
    )


def test_a_free_body_takes_the_same_steps_and_turns_the_same_at_any_uniform_velocity():
    """At 0, 100 and 7546 m/s the free box takes the same steps (the starting step given:
    Hairer's estimate of it reads the size of the state, the position and velocity
    included) and ends at the same attitude to rounding, its centre of mass where the
    uniform motion puts it."""
    scene = bd.Scene(BOX, mode=bd.CentreOfMassMode())
    runs = {
        speed: bd.simulate(scene, _start(speed), 10.0, rtol=1e-10, atol=1e-12, dt0=0.05)
        for speed in (0.0, 100.0, ORBIT_SPEED)
    }
    rest = runs[0.0]
    for speed, traj in runs.items():
        assert int(traj.stats["num_steps"]) == int(rest.stats["num_steps"])
        assert _attitude_difference(traj.g[-1, :3, :3], rest.g[-1, :3, :3]) < 1e-14
        np.testing.assert_allclose(
            traj.g[-1, :3, 3], [ORBIT_RADIUS, 10.0 * speed, 0.0], rtol=1e-15, atol=1e-9
        )
        # The body-frame velocity is the rest body's plus the uniform one seen in its axes.
        boost = traj.g[-1, :3, :3].T @ jnp.array([0.0, speed, 0.0])
        np.testing.assert_allclose(traj.xi[-1, 3:], rest.xi[-1, 3:] + boost, atol=1e-9)


def _euler_and_newton(t, y):
    r"""The box in the central field with MacCullagh's gravity gradient, in the inertial
    frame: $m\ddot r = -\nabla\Pi$, $\dot R = R\hat\omega$, $J\dot\omega + \omega\times J\omega =
    3\mu\,r_b\times J r_b/\rho^5$ with $r_b = R^T r$."""
    r, v, R, w = y[:3], y[3:6], y[6:15].reshape(3, 3), y[15:]
    rho = np.linalg.norm(r)
    l = R @ INERTIA @ R.T
    # ∇ of the quadrupole term -μ/(2ρ³)(tr l − 3 r·l r/ρ²) of the potential.
    quadrupole = (
        0.5
        * MU_EARTH
        * (3.0 * np.trace(l) * r / rho**5 + 6.0 * l @ r / rho**5 - 15.0 * (r @ l @ r) * r / rho**7)
    )
    acceleration = -MU_EARTH * r / rho**3 - quadrupole / MASS
    r_b = R.T @ r
    torque = 3.0 * MU_EARTH / rho**5 * np.cross(r_b, INERTIA @ r_b)
    w_dot = np.linalg.solve(INERTIA, torque - np.cross(w, INERTIA @ w))
    w_hat = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    return np.concatenate([v, acceleration, (R @ w_hat).ravel(), w_dot])


def test_a_spinning_box_in_orbit_turns_as_euler_and_newtons_equations_turn_it():
    """100 s of a spinning box on a circular orbit in the Earth's gravity gradient against
    SciPy's DOP853 at rtol 1e-13 on Euler's and Newton's equations: 1e-9 rad in attitude."""
    y0 = np.concatenate(
        [[ORBIT_RADIUS, 0.0, 0.0], [0.0, ORBIT_SPEED, 0.0], np.eye(3).ravel(), SPIN]
    )
    reference = solve_ivp(
        _euler_and_newton, (0.0, 100.0), y0, method="DOP853", rtol=1e-13, atol=1e-13
    )
    R_ref, r_ref = reference.y[6:15, -1].reshape(3, 3), reference.y[:3, -1]
    scene = bd.Scene(BOX, [bd.GravityGradient(MU_EARTH)], mode=bd.CentreOfMassMode())
    traj = bd.simulate(scene, _start(ORBIT_SPEED), 100.0, rtol=1e-12, atol=1e-12)
    assert _attitude_difference(traj.g[-1, :3, :3], R_ref) < 1e-9
    np.testing.assert_allclose(traj.g[-1, :3, 3], r_ref, rtol=1e-14, atol=1e-7)


def test_the_mode_refuses_a_moving_frame():
    with pytest.raises(ValueError, match="Galilean frame"):
        bd.Scene(BOX, frame=bd.FreeFalling(9.81), mode=bd.CentreOfMassMode())
