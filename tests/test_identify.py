"""Identification from synthetic motion: what is recovered, to what accuracy, and what is not.

Data come from bundledyn's own simulation at rtol 1e-12 (noise-free recovery is a test of
the identification, not of the dynamics); `test_identify_mujoco.py` fits data that MuJoCo
generated. The regroupings a hinge and a universal joint allow (mass on the hinge's axis,
a point mass at the universal joint's centre) are built here from the chain's geometry,
independently of the library's own list.
"""

import functools

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from systems import chain

import bundledyn as bd
from bundledyn import identify

# Multibody fits: slow; test_identify_rigid.py is the everyday identification check.
# One worker for the file in `.ci/run`'s slow part (`--dist loadgroup`): its tests share fits.
pytestmark = [
    pytest.mark.usefixtures("optimized_compilation"),
    pytest.mark.slow,
    pytest.mark.xdist_group("identify"),
]

T1, RATE = 2.0, 100
STATE0 = bd.State(
    jnp.eye(4),
    jnp.array([0.2, -0.1, 0.3]),
    jnp.array([0.3, 0.2, -0.4, 0.1, 0.0, 0.2]),
    jnp.array([0.5, -0.4, 0.3]),
)


def _torques(t1, seed=0):
    ts = jnp.linspace(0.0, t1 + 0.2, int((t1 + 0.2) * RATE) + 1)
    phase = jax.random.uniform(jax.random.key(seed), (3,), maxval=2 * jnp.pi)
    tau = jnp.stack(
        [0.3 * jnp.sin(3 * ts + phase[0]), 0.2 * jnp.cos(2 * ts + phase[1]),
         0.1 * jnp.sin(5 * ts + phase[2])], axis=1,
    )  # fmt: skip
    return identify.Inputs(ts, joint_forces=tau)


def _record(system, inputs, state0, t1, noise):
    ts = jnp.linspace(0.0, t1, int(t1 * RATE) + 1)
    scene = bd.Scene(system, inputs.effects())
    traj = bd.simulate(scene, state0, t1, saveat=diffrax.SaveAt(ts=ts), rtol=1e-12, atol=1e-12)
    return ts, identify.Measurements.from_states(ts, traj, noise=noise)


def _regroupings(system):
    """δP of the chain's two joints, (4, 3, 4, 4): the hinge of body 1 (three moments of
    mass on its axis line) and the universal joint of body 2 (a point mass at its centre),
    each added to the child and taken from the parent in the parent's frame."""
    T = np.eye(4)
    T[0, 3] = 0.5  # every link's home placement
    anchor, axis = np.array([-0.25, 0.0, 0.0, 1.0]), np.array([0.0, np.cos(1), np.sin(1), 0.0])
    child = [
        (1, np.outer(anchor, anchor)),
        (1, np.outer(anchor, axis) + np.outer(axis, anchor)),
        (1, np.outer(axis, axis)),
        (2, np.outer(anchor, anchor)),
    ]
    directions = np.zeros((len(child), system.num_bodies, 4, 4))
    for k, (body, delta) in enumerate(child):
        directions[k, body] = delta
        directions[k, body - 1] = -T @ delta @ T.T
    return directions


def _unexplained(P_fit, P_true, directions):
    """The part of P_fit - P_true outside the span of the regroupings, relative to |P_true|."""
    A = directions.reshape(len(directions), -1).T
    difference = np.asarray(P_fit - P_true).reshape(-1)
    coefficients = np.linalg.lstsq(A, difference, rcond=None)[0]
    return np.linalg.norm(difference - A @ coefficients) / np.linalg.norm(np.asarray(P_true))


@functools.cache
def noise_free_fit():
    truth = chain(3)
    inputs = _torques(T1)
    _, data = _record(truth, inputs, STATE0, T1, identify.Noise(*(1e-3,) * 6))
    nominal = truth.with_pseudo_inertias(
        truth.pseudo_inertias() * jnp.array([1.15, 0.9, 1.2])[:, None, None]
    )
    parameters = identify.Parameters(bd.Scene(nominal))
    result = identify.fit(
        parameters, data, inputs=inputs, gauge=identify.MeasuredInputs(),
        windows=identify.Windows(count=4),
    )  # fmt: skip
    return truth, result


def test_noise_free_data_determine_every_identifiable_combination_to_rounding():
    """From a start 10-20 % off: the fit converges, and the fitted pseudo-inertias equal the
    truth up to the joints' regroupings to 1e-8 (and nothing else is left undetermined)."""
    truth, result = noise_free_fit()
    assert result.stats["converged"], result.report()
    P_fit = result.scene.system.pseudo_inertias()
    directions = _regroupings(truth)
    assert _unexplained(P_fit, truth.pseudo_inertias(), directions) < 1e-8
    nominal = result.parameters.scene.system.pseudo_inertias()
    assert _unexplained(nominal, truth.pseudo_inertias(), directions) > 1e-2  # the start was off
    undetermined = result.identifiability.undetermined
    assert len(undetermined) == 4, undetermined
    assert sum("axis of the joint of body1" in u for u in undetermined) == 3
    assert sum("centre of the joint of body2" in u for u in undetermined) == 1
    for estimate in result.estimates():  # what is reported as determined is right
        if estimate.determined:
            name, quantity = estimate.name.split(".")
            body = int(name[-1])
            m, c, J = identify.inertial_from_pseudo_inertia(truth.pseudo_inertias()[body])
            true = dict(mass=m, com_x=c[0], com_y=c[1], com_z=c[2], I_xx=J[0, 0], I_yy=J[1, 1],
                        I_zz=J[2, 2], I_xy=J[0, 1], I_xz=J[0, 2], I_yz=J[1, 2])[quantity]  # fmt: skip
            assert abs(estimate.value - true) < 1e-8 * float(jnp.trace(J)), estimate


def test_every_iterate_is_a_physical_system():
    _, result = noise_free_fit()
    assert len(result.iterates) == result.stats["steps"] + 1 > 2
    for theta in result.iterates:
        m, _, J = identify.inertial_from_pseudo_inertia(result.parameters.pseudo_inertias(theta))
        moments = np.linalg.eigvalsh(J)
        assert np.all(m > 0) and np.all(moments[:, 0] > 0)
        assert np.all(moments[:, 0] + moments[:, 1] >= moments[:, 2] * (1 - 1e-12))


def test_the_reported_estimates_and_report_are_consistent():
    _, result = noise_free_fit()
    text = result.report()
    assert "gauge: measured inputs" in text and "The data do not determine:" in text
    assert result.costs[-1] < 1e-12 * max(result.costs)
    assert result.identifiability.noise_scale < 1e-4  # the data were noise-free


def test_rotor_inertia_and_damping_are_positive_parameters_of_the_scene():
    """`joint_constants=("damping", "armature")` appends their logarithms to θ; `to_scene`
    puts them back where they act (the damper, the metric's shape block), and the kinetic
    energy's gradient in a log-armature is its closed form ½ aⱼ q̇ⱼ². A rotor inertia of
    zero has no logarithm: refused with the fix."""
    armature = jnp.array([0.3, 0.2, 0.1, 0.4])
    bodies = chain(5).bodies()
    system = bd.Multibody(bodies[0], [
        bd.Link(body, bd.Revolute([0.0, np.cos(i), np.sin(i)], [-0.25, 0, 0]), i, np.eye(4))
        for i, body in enumerate(bodies[1:])
    ], armature=armature)  # fmt: skip
    scene = bd.Scene(system, [bd.ShapeDamper(jnp.array([0.5, 0.6, 0.7, 0.8]))])
    parameters = identify.Parameters(scene, bodies=(), joint_constants=("damping", "armature"))
    theta = parameters.initial()
    assert parameters.labels()[-1] == "log armature[3]" and theta.shape == (8,)
    np.testing.assert_allclose(jnp.exp(theta[4:]), armature, rtol=1e-15)
    moved = parameters.to_scene(theta.at[1].add(0.1).at[5].add(0.2))
    np.testing.assert_allclose(moved.effects[0].c[1], 0.6 * np.exp(0.1), rtol=1e-14)
    np.testing.assert_allclose(moved.system.armature[1], 0.2 * np.exp(0.2), rtol=1e-14)
    q, xi, qdot = jnp.full(4, 0.2), jnp.array([0.1, -0.2, 0.3, 0.4, 0.0, 0.1]), jnp.arange(1.0, 5)

    def energy(theta):
        return bd.kinetic_energy(parameters.to_scene(theta).system, q, xi, qdot)

    np.testing.assert_allclose(jax.grad(energy)(theta)[4:], 0.5 * armature * qdot**2, rtol=1e-12)
    zero = bd.Scene(eqx.tree_at(lambda s: s.armature, system, armature.at[0].set(0.0)))
    with pytest.raises(ValueError, match="armature must be positive"):
        identify.Parameters(zero, joint_constants=("armature",))


@functools.cache
def _nominal_start():
    """The noise-free fit's shooting problem, gauge, measured window states and decision
    vector at the nominal parameters."""
    from bundledyn._identify._fit import _window_starts
    from bundledyn._identify._shooting import ShootingProblem

    truth, result = noise_free_fit()
    parameters, gauge = result.parameters, identify.MeasuredInputs()
    inputs = _torques(T1)
    _, data = _record(truth, inputs, STATE0, T1, identify.Noise(*(1e-3,) * 6))
    windows = identify.Windows(count=4)
    references, states = _window_starts(windows, parameters, data, data.states)
    problem = ShootingProblem(parameters, inputs.effects(), data, windows, references)
    return problem, gauge, states, jnp.concatenate([parameters.initial(), states.reshape(-1)])


def test_a_continuation_stage_starts_from_the_last_stages_evaluation_reweighted():
    """The evaluation a stage of looser continuity ends with, reweighted (`_reweighted`),
    is the tighter stage's own evaluation at the same point, to rounding: the stage's first
    Jacobian need not be computed."""
    from bundledyn._identify._data import level
    from bundledyn._identify._fit import _evaluate, _reweighted

    problem, gauge, states, z = _nominal_start()
    looser = eqx.tree_at(lambda p: p.windows.continuity, problem, level(0.1))
    reweighted = _reweighted(_evaluate(looser, gauge, states, z), looser, problem)
    for mine, theirs in zip(reweighted, _evaluate(problem, gauge, states, z), strict=True):
        assert np.abs(theirs).max() > 0
        np.testing.assert_allclose(mine, theirs, rtol=1e-13, atol=1e-13 * np.abs(theirs).max())


def test_the_fits_gradient_is_finite_and_equals_finite_differences():
    """The exact forward-mode Jacobian the fit uses gives the merit's gradient JᵀR + CᵀC in
    every parameter (and window state), at the nominal start of the noise-free fit, equal to
    central differences of the merit to 1e-6 relative."""
    from bundledyn._identify._fit import _evaluate, _residuals

    problem, gauge, states, z = _nominal_start()
    parameters = problem.parameters
    r, J, c, C = _evaluate(problem, gauge, states, z)
    gradient = np.asarray(J.T @ r + C.T @ c)
    assert np.all(np.isfinite(gradient))

    def merit(z):
        r, c = _residuals(problem, gauge, states, z)
        return 0.5 * float(r @ r + c @ c)

    scale = np.abs(gradient).max()
    for k in list(range(parameters.size)) + [parameters.size + 3, len(z) - 1]:
        h = 1e-6 * max(1.0, abs(float(z[k])))
        step = jnp.zeros_like(z).at[k].set(h)
        difference = (merit(z + step) - merit(z - step)) / (2 * h)
        assert abs(difference - gradient[k]) < 1e-6 * scale, (k, difference, gradient[k])


ARM = """
<mujoco model="arm">
  <worldbody>
    <body name="base" pos="0 0 1">
      <inertial pos="0 0 0" mass="5" diaginertia="0.1 0.1 0.1"/>
      <body name="upper" pos="0 0 -0.05">
        <joint name="shoulder" type="hinge" axis="0 1 0.2"/>
        <inertial pos="0.02 0.01 -0.2" mass="1.3" fullinertia="0.02 0.021 0.004 0.001 -0.002 0.0005"/>
        <body name="fore" pos="0.01 0 -0.4">
          <joint name="elbow" type="hinge" axis="1 0.1 0" pos="0 0.01 0.02"/>
          <inertial pos="0 0.02 -0.15" mass="0.9" fullinertia="0.01 0.011 0.002 -0.0005 0.001 0.0004"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


_ARM_TIMES = jnp.linspace(0.0, 4.2, 211)
TRUE_INPUTS = identify.Inputs(
    _ARM_TIMES,
    joint_forces=jnp.stack(
        [4 * jnp.sin(1.3 * _ARM_TIMES) + 2 * jnp.sin(3.1 * _ARM_TIMES),
         jnp.cos(2.3 * _ARM_TIMES + 0.5) + 0.5 * jnp.sin(4.3 * _ARM_TIMES)], axis=1,
    ),
)  # fmt: skip


@functools.cache
def arm_fit():
    """An arm on a fixed base under gravity and joint damping, driven by torques: angles,
    joint rates and torques recorded with 1 % noise; masses, inertias and damping fitted."""
    truth = bd.Multibody.from_mjcf(ARM)
    base = bd.PrescribedBase.fixed()
    t1, rate = 4.0, 50
    ts = jnp.linspace(0.0, t1, int(t1 * rate) + 1)
    input_times, torque = TRUE_INPUTS.ts, TRUE_INPUTS.joint_forces
    damping = jnp.array([0.5, 0.2])
    scene = bd.Scene(
        truth, [bd.Gravity(), bd.ShapeDamper(damping), *TRUE_INPUTS.effects()], base=base
    )
    start = bd.State(jnp.eye(4), jnp.array([0.3, -0.2]), jnp.zeros(6), jnp.zeros(2))
    traj = bd.simulate(scene, start, t1, saveat=diffrax.SaveAt(ts=ts), rtol=1e-12, atol=1e-12)
    keys = jax.random.split(jax.random.key(3), 3)
    rms = lambda x: float(jnp.sqrt(jnp.mean(x**2)))
    noise = identify.Noise(q=0.01 * rms(traj.q), qdot=0.01 * rms(traj.qdot))
    torque_noise = 0.01 * jnp.sqrt(jnp.mean(torque**2, axis=0))
    measured_torque = torque + torque_noise[None, :] * jax.random.normal(keys[2], torque.shape)
    data = identify.Measurements(
        ts,
        q=traj.q + noise.q * jax.random.normal(keys[0], traj.q.shape),
        qdot=traj.qdot + noise.qdot * jax.random.normal(keys[1], traj.qdot.shape),
        noise=noise,
    )
    nominal = truth.with_pseudo_inertias(
        truth.pseudo_inertias() * jnp.array([1.0, 1.3, 0.8])[:, None, None]
    )
    nominal_scene = bd.Scene(
        nominal, [bd.Gravity(), bd.ShapeDamper(jnp.array([0.3, 0.3]))], base=base
    )
    parameters = identify.Parameters(
        nominal_scene, bodies=("upper", "fore"), joint_constants=("damping",)
    )
    result = identify.fit(
        parameters, data, inputs=identify.Inputs(input_times, joint_forces=measured_torque),
        gauge=identify.MeasuredInputs(),
    )  # fmt: skip
    return truth, traj, measured_torque, torque_noise, input_times, result


def _required_torques(scene, ts, states, accelerations):
    """The joint torques `scene` needs for the motion: its shape force minus its effects'."""

    def one(t, g, q, qdot, qddot):
        needed = bd.driven_shape_force(scene.system, q, jnp.zeros(6), jnp.zeros(6), qdot, qddot)
        return needed - scene.forces(bd.Kinematics(t, g, q, jnp.zeros(6), qdot))[1]

    return jax.vmap(one)(ts, states.g, states.q, states.qdot, accelerations)


def test_an_arm_on_a_fixed_base_is_identified_from_its_torques_and_angles():
    """Along the true motion, the torques the fitted arm needs differ from the measured ones
    by the torque noise (RMS 1.0-1.1 σ per joint, 1 for a perfect model), where the nominal
    arm's differ by many σ; the damping is found to 2 %; the regrouping across the elbow
    and what a fixed shoulder axis hides are reported undetermined."""
    truth, traj, measured, sigma, input_times, result = arm_fit()
    assert result.stats["converged"], result.report()
    assert 0.8 < result.identifiability.noise_scale < 1.2
    base = bd.PrescribedBase.fixed()
    true_scene = bd.Scene(
        truth, [bd.Gravity(), bd.ShapeDamper(jnp.array([0.5, 0.2])), *TRUE_INPUTS.effects()],
        base=base,
    )  # fmt: skip
    term = bd.SceneTerm(true_scene)
    accelerations = jax.vmap(lambda t, y: term.body_vf(t, y, None)[1][2:])(
        traj.ts,
        jax.vmap(lambda t, g, q, qdot: term.pack(t, g, q, None, qdot))(
            traj.ts, traj.g, traj.q, traj.qdot
        ),
    )
    at_samples = jnp.stack([jnp.interp(traj.ts, input_times, measured[:, i]) for i in range(2)], 1)
    for scene, low, high in ((result.scene, 0.9, 1.3), (result.parameters.scene, 5.0, np.inf)):
        needed = _required_torques(scene, traj.ts, traj, accelerations)
        rms = np.sqrt(np.mean((needed - at_samples) ** 2, axis=0)) / np.asarray(sigma)
        assert np.all((low < rms) & (rms < high)), rms
    np.testing.assert_allclose(result.scene.effects[1].c, [0.5, 0.2], rtol=0.02)
    undetermined = result.identifiability.undetermined
    assert (
        sum("axis of the joint of fore, shared by fore and upper" in u for u in undetermined) == 3
    )
