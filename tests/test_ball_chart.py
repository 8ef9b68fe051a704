"""A ball joint turning through any number of revolutions (`recharted_shape`).

The rotation-vector chart of a `Spherical` joint degenerates at |φ| = 2π; the solvers
switch to the equivalent coordinates with |φ| ≤ π at the start of each step.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import bundledyn as bd
from bundledyn import lie
from bundledyn._systems._ball_chart import (
    ball_columns,
    recharted_shape,
    shape_difference,
    shape_velocity_difference,
)

mujoco = pytest.importorskip("mujoco")

# A free base carrying a wheel on a ball joint (MuJoCo's names, as in an MJCF model).
WHEEL = """<mujoco><option gravity="0 0 0" integrator="RK4" timestep="1e-4"/>
<worldbody><body name="base"><freejoint/>
<inertial pos="0 0 0" mass="3" diaginertia="0.3 0.4 0.5"/>
<body name="wheel" pos="0.2 0.1 0"><joint name="ball" type="ball"/>
<inertial pos="0.05 0 0.02" mass="1" diaginertia="0.02 0.03 0.04"/></body></body>
</worldbody></mujoco>"""


def _ball_system():
    body = bd.RigidBody(1.0, jnp.array([0.05, 0.0, 0.02]), jnp.diag(jnp.array([0.02, 0.03, 0.04])))
    link = bd.Link(body, bd.Spherical([0.0, 0.0, 0.0]), 0, jnp.eye(4))
    return bd.Multibody(body, [link, bd.Link(body, bd.Revolute([0, 0, 1]), 1, jnp.eye(4))])


@pytest.mark.parametrize("theta", [0.0, 1e-9, 0.5, 3.0, np.pi + 1e-9, 4.0, 6.0, 2 * np.pi - 1e-3])
def test_the_recharted_coordinates_are_the_same_rotation_and_angular_velocity(theta):
    """Past |φ| = π the rotation vector moves to φ(1 − 2π/|φ|): the same rotation and
    the same angular velocity dexp(φ)φ̇, to rounding; inside the ball nothing changes."""
    system = _ball_system()
    axis = jnp.array([0.3, -0.5, 0.8]) / jnp.linalg.norm(jnp.array([0.3, -0.5, 0.8]))
    q = jnp.concatenate([theta * axis, jnp.array([0.7])])
    qdot = jnp.array([0.4, -1.1, 2.0, 0.3])
    q2, qdot2 = recharted_shape(system, q, qdot)
    assert float(jnp.linalg.norm(q2[:3])) <= np.pi + 1e-12
    np.testing.assert_allclose(lie.so3_exp(q2[:3]), lie.so3_exp(q[:3]), atol=1e-14)
    omega = lie.so3_dexp(q[:3]) @ qdot[:3]
    np.testing.assert_allclose(lie.so3_dexp(q2[:3]) @ qdot2[:3], omega, atol=1e-12)
    np.testing.assert_array_equal(q2[3:], q[3:])
    if theta <= np.pi:
        np.testing.assert_array_equal(q2, q)
        np.testing.assert_array_equal(qdot2, qdot)


@pytest.mark.parametrize("theta", [0.0, 4.0])
def test_recharting_has_finite_correct_derivatives(theta):
    """At φ = 0 (where a careless `where` gives NaN through the unused branch) the map is
    the identity with identity Jacobian; past π its Jacobian equals central differences."""
    system = _ball_system()
    q = jnp.concatenate([theta * jnp.array([0.6, 0.0, 0.8]), jnp.array([0.2])])
    qdot = jnp.array([0.4, -1.1, 2.0, 0.3])

    def f(x):
        q2, qdot2 = recharted_shape(system, x[:4], x[4:])
        return jnp.concatenate([q2, qdot2])

    x = jnp.concatenate([q, qdot])
    J_rev = jax.jacrev(f)(x)
    assert np.all(np.isfinite(J_rev))
    if theta == 0.0:
        np.testing.assert_allclose(J_rev, np.eye(8), atol=1e-15)
    else:
        h = 1e-6
        fd = np.stack([(f(x + h * e) - f(x - h * e)) / (2 * h) for e in np.eye(8)], axis=1)
        np.testing.assert_allclose(J_rev, fd, atol=1e-8)


@pytest.mark.parametrize("theta", [0.5, 3.0, np.pi + 1e-9, 4.0, 6.0])
def test_two_charts_of_one_state_differ_by_nothing(theta):
    """A ball joint's coordinates and their recharted ones (2π apart along the axis) are
    one rotation and one angular velocity: their differences are zero to rounding, while
    the hinge's part stays the plain difference."""
    system = _ball_system()
    columns = ball_columns(system)
    axis = jnp.array([0.3, -0.5, 0.8]) / jnp.linalg.norm(jnp.array([0.3, -0.5, 0.8]))
    q = jnp.concatenate([theta * axis, jnp.array([0.7])])
    qdot = jnp.array([0.4, -1.1, 2.0, 0.3])
    other = q * (1.0 - 2.0 * np.pi / theta)  # the other chart of the same turn
    other_rates = lie.so3_dexp_inv(other[:3]) @ lie.so3_dexp(q[:3]) @ qdot[:3]
    other, other_qdot = other.at[3].set(0.2), jnp.concatenate([other_rates, jnp.array([0.1])])
    np.testing.assert_allclose(shape_difference(columns, q, other), [0, 0, 0, 0.5], atol=1e-13)
    np.testing.assert_allclose(
        shape_velocity_difference(columns, q, qdot, other, other_qdot), [0, 0, 0, 0.2], atol=1e-12
    )
    plain = np.asarray(q - other)
    assert np.linalg.norm(plain[:3]) > 6.0  # what comparing coordinates would have said


def test_the_differences_of_nearby_states_have_finite_correct_derivatives():
    """At equal rotations (the log's singular point, where every residual of a good fit
    sits) the difference's Jacobian is finite and equals central differences; at the
    identity the shape's part is the plain difference's."""
    system = _ball_system()
    columns = ball_columns(system)
    qdot = jnp.array([0.4, -1.1, 2.0, 0.3])

    def f(x, q_b):
        return jnp.concatenate(
            [shape_difference(columns, x[:4], q_b),
             shape_velocity_difference(columns, x[:4], x[4:], q_b, qdot)]
        )  # fmt: skip

    for q_b in (jnp.zeros(4), jnp.array([1.2, -0.4, 2.1, 0.3])):
        x = jnp.concatenate([q_b, qdot])
        np.testing.assert_array_equal(f(x, q_b), np.zeros(8))
        J = jax.jacrev(f)(x, q_b)
        assert np.all(np.isfinite(J))
        h = 1e-6
        fd = np.stack([(f(x + h * e, q_b) - f(x - h * e, q_b)) / (2 * h) for e in np.eye(8)], 1)
        np.testing.assert_allclose(J, fd, atol=1e-8)
        if not np.any(q_b):  # the shape's part: the plain difference's Jacobian
            np.testing.assert_allclose(J[:4], np.eye(8)[:4], atol=1e-15)


def test_a_ball_joint_turns_twenty_times_as_mujoco_turns_it():
    """A wheel on a ball joint spinning at 4π rad/s about a nearly fixed axis, with a
    sideways rate of 1e-5 of the spin, turns 20 times in 5 s in about 200 steps and ends
    where MuJoCo's RK4 at dt = 1e-4 (quaternions) ends, to within RK4's error (measured
    2.5e-12 in qpos, 2.6e-11 in qvel). Kept in the one chart, |φ| passes 2π, 4π, … where
    the sideways rates' coordinates blow up: 1348 steps and 1e-10 / 4e-10."""
    model = mujoco.MjModel.from_xml_string(WHEEL)
    system = bd.Multibody.from_mjcf(WHEEL)
    data = mujoco.MjData(model)
    spin = 4 * np.pi
    data.qvel[:] = [0.1, -0.2, 0.05, 0.02, 0.01, -0.03, 1e-5 * spin, 0.0, spin]
    start = bd.state_from_mujoco(system, data.qpos, data.qvel)
    for _ in range(50_000):
        mujoco.mj_step(model, data)
    traj = bd.simulate(bd.Scene(system), start, 5.0, rtol=1e-11, atol=1e-11)
    assert int(traj.stats["num_steps"]) < 400
    end = bd.State(traj.g[-1], traj.q[-1], traj.xi[-1], traj.qdot[-1])
    qpos, qvel = (np.array(x) for x in bd.state_to_mujoco(system, end))
    for block in (slice(3, 7), slice(7, 11)):  # q and -q are one rotation
        if qpos[block] @ data.qpos[block] < 0:
            qpos[block] *= -1
    np.testing.assert_allclose(qpos, data.qpos, atol=1e-10)
    np.testing.assert_allclose(qvel, data.qvel, atol=1e-10)


def _wheel_start(system, spin, side=1e-5):
    qvel = jnp.array([0.1, -0.2, 0.05, 0.02, 0.01, -0.03, side * spin, 0.0, spin])
    return bd.state_from_mujoco(system, jnp.array([0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0.0]), qvel)


def test_the_variational_integrator_keeps_momentum_through_the_chart_switches():
    """`VariationalMidpoint` over 5 turns: the spatial momentum is conserved to rounding
    and the energy error stays at the method's level across the switches."""
    import diffrax

    system = bd.Multibody.from_mjcf(WHEEL)
    traj = bd.simulate(
        bd.Scene(system), _wheel_start(system, 4 * np.pi, side=1e-3), 1.25,
        solver=bd.VariationalMidpoint(), dt0=2.5e-3, stepsize_controller=diffrax.ConstantStepSize(),
        saveat=diffrax.SaveAt(ts=jnp.linspace(0.0, 1.25, 26)),
    )  # fmt: skip
    assert float(jnp.max(jnp.linalg.norm(traj.q[:, :3], axis=1))) <= np.pi + 0.1
    momentum = traj.spatial_momentum()
    scale = float(jnp.abs(momentum).max())
    np.testing.assert_allclose(momentum - momentum[:1], 0.0, atol=1e-12 * scale)
    energy = traj.energy()
    assert float(jnp.max(jnp.abs(energy - energy[0]))) < 1e-4 * float(energy[0])


def test_a_window_charts_continuity_sees_no_jump_between_charts_of_one_state():
    """Identification joins shooting windows by the difference of the end state and the next
    start: a ball joint solved past |φ| = π and measured inside it are one state."""
    from bundledyn._modes import DrivenChart, FloatingChart
    from bundledyn._modes._charts import balls_of
    from bundledyn.identify import Noise

    system = _ball_system()
    axis = jnp.array([0.3, -0.5, 0.8]) / jnp.linalg.norm(jnp.array([0.3, -0.5, 0.8]))
    q = jnp.concatenate([4.0 * axis, jnp.array([0.7])])
    qdot = jnp.array([0.4, -1.1, 2.0, 0.3])
    inside_q, inside_qdot = recharted_shape(system, q, qdot)
    g, xi = jnp.eye(4), jnp.array([0.1, 0.2, 0.3, 0.0, 0.0, 0.1])
    noise = Noise(rotation=1e-3, position=1e-3, q=1e-3, angular_velocity=1e-2,
                  linear_velocity=1e-2, qdot=1e-2)  # fmt: skip
    for chart in (FloatingChart(4, balls_of(system)), DrivenChart(4, balls_of(system))):
        difference = chart.difference(
            bd.State(g, q, xi, qdot), bd.State(g, inside_q, xi, inside_qdot), noise
        )
        np.testing.assert_allclose(difference, 0.0, atol=1e-9)
        plain = type(chart)(4).difference(
            bd.State(g, q, xi, qdot), bd.State(g, inside_q, xi, inside_qdot), noise
        )
        assert float(jnp.max(jnp.abs(plain))) > 1e3  # coordinates alone: a 2π jump
