"""MuJoCo's records of the data sets, with noise, in both fitters' layouts; the unseen
motion and how well a fitted model predicts it.

The torques are a log at 100 Hz (samples of a smooth signal); the motors follow the log
read linearly between its samples, each 0.2 ms step of MuJoCo's RK4 holding the value at
the step's middle (the same impulse as the linear signal over the step, to O(dt³)). So both
fitters pose the problem that made the record: bundledyn reads the log linearly
(`Inputs(interpolation="linear")`), mujoco.sysid is given the held value of every step.
MuJoCo records at 100 Hz; Gaussian noise of a given fraction of each channel's spread is
added in bundledyn's coordinates (the recipe of `tests/test_identify_mujoco.py`) and the
same noisy record is handed to mujoco.sysid in MuJoCo's layout.
"""

import dataclasses
import warnings

import numpy as np

from benchmarks.identification.cases import RATE, TIMESTEP, Case, initial_velocity, torque


def torque_log(case: Case, seed, t1):
    """The torque log of `seed` at 100 Hz, 0.2 s past `t1`: `(times, torques)`."""
    times = np.arange(int(round((t1 + 0.2) * RATE)) + 1) / RATE
    return times, torque(case, times, seed)


def joint_forces(case: Case, torques):
    """The motors' torques `(m, nu)` as bundledyn's shape forces `(m, d)`: each motor's
    column at its hinge's coordinate (MuJoCo's joint order, past a free root's six), zero on
    the undriven coordinates (a generated tree's ball joints)."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(case.mjcf)
    root = 6 if case.floating else 0
    placed = np.zeros((model.nu, model.nv - root))
    placed[np.arange(model.nu), model.jnt_dofadr[model.actuator_trnid[:, 0]] - root] = 1.0
    return np.asarray(torques) @ placed


def held_torques(case: Case, seed, t1, timestep):
    """What the motors hold over each MuJoCo step of `[0, t1]`: the log read linearly at
    the step's middle. `(step start times, torques)`."""
    times, log = torque_log(case, seed, t1)
    starts = np.arange(int(round(t1 / timestep)) + 1) * timestep
    held = np.zeros((len(starts), log.shape[1]))
    for i in range(log.shape[1]):
        held[:, i] = np.interp(starts + timestep / 2, times, log[:, i])
    return starts, held


def mujoco_record(case: Case, seed, t1, model=None):
    """MuJoCo's motion from the start of `seed` under its motors: `(ts, qpos, qvel)`."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(case.mjcf) if model is None else model
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = initial_velocity(case, model, seed)
    every, n = int(round(1 / (RATE * model.opt.timestep))), int(round(t1 * RATE)) + 1
    _, held = held_torques(case, seed, t1, model.opt.timestep)
    qpos, qvel = np.zeros((n, model.nq)), np.zeros((n, model.nv))
    step = 0
    for k in range(n):
        qpos[k], qvel[k] = data.qpos, data.qvel
        for _ in range(every if k < n - 1 else 0):
            if model.nu:
                data.ctrl[:] = held[step]
            mujoco.mj_step(model, data)
            step += 1
    return np.arange(n) / RATE, qpos, qvel


def truth_system(case: Case):
    """bundledyn's tree of the case's MJCF (MuJoCo's motors are not bundledyn's: the
    torques enter as known inputs)."""
    import bundledyn as bd

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return bd.Multibody.from_mjcf(case.mjcf)


def _spread(x):
    x = np.asarray(x)
    return float(np.sqrt(np.mean((x - x.mean(0)) ** 2)))


@dataclasses.dataclass
class Record:
    """One noisy record, in both layouts, with its known torques."""

    case: Case
    seed: int
    level: float
    measurements: object  # bundledyn's `identify.Measurements`
    inputs: object  # bundledyn's `identify.Inputs`, or None
    ts: np.ndarray
    qpos: np.ndarray  # the same noisy record in MuJoCo's layout
    qvel: np.ndarray
    torque_ts: np.ndarray  # the torque log (100 Hz): bundledyn reads it linearly
    torques: np.ndarray
    step_ts: np.ndarray  # what each MuJoCo step held: mujoco.sysid's controls
    step_torques: np.ndarray
    sigmas: dict  # each channel group's noise level (of the weights when level = 0)


def noisy_record(case: Case, seed: int, level: float) -> Record:
    """MuJoCo's record of `seed` with Gaussian noise of `level` times each channel's spread
    (the recipe of tests/test_identify_mujoco.py; noise seed `1000 + seed`). The weights of
    a noise-free record are those of a 0.1 % one."""
    import jax.numpy as jnp

    import bundledyn as bd
    from bundledyn import identify

    truth = truth_system(case)
    ts, qpos, qvel = mujoco_record(case, seed, case.t1)
    torque_ts, torques = torque_log(case, seed, case.t1)
    steps = held_torques(case, seed, case.t1, TIMESTEP)
    inputs = None
    if torques.shape[-1]:
        inputs = identify.Inputs(
            jnp.asarray(torque_ts),
            joint_forces=jnp.asarray(joint_forces(case, torques)),
            interpolation="linear",
        )
    rng = np.random.default_rng(1000 + seed)
    weight = level if level > 0 else 1e-3
    n = len(ts)
    if not case.floating:
        q, qdot = qpos, qvel
        sigmas = {"q": weight * _spread(q), "qdot": weight * _spread(qdot)}
        noise = identify.Noise(q=sigmas["q"], qdot=sigmas["qdot"])
        q = q + level * _spread(q) * rng.normal(size=q.shape)
        qdot = qdot + level * _spread(qdot) * rng.normal(size=qdot.shape)
        measurements = identify.Measurements(
            jnp.asarray(ts), q=jnp.asarray(q), qdot=jnp.asarray(qdot), noise=noise
        )
        return Record(case, seed, level, measurements, inputs, ts, q, qdot, torque_ts,
                      torques, *steps, sigmas)  # fmt: skip
    clean = identify.Measurements.from_mujoco(truth, ts, qpos, qvel, noise=identify.Noise())
    spreads = {
        "rotation": 1.0,
        "position": _spread(clean.pose[:, :3, 3]),
        "angular_velocity": _spread(clean.xi[:, :3]),
        "linear_velocity": _spread(clean.xi[:, 3:]),
    }
    d = clean.q.shape[1]
    if d:
        spreads |= {"q": _spread(clean.q), "qdot": _spread(clean.qdot)}
    sigmas = {k: weight * v for k, v in spreads.items()}
    noise = identify.Noise(**sigmas)
    drawn = {k: level * v for k, v in spreads.items()}
    turn = bd.lie.so3_exp(jnp.asarray(drawn["rotation"] * rng.normal(size=(n, 3))))
    pose = clean.pose.at[:, :3, :3].set(clean.pose[:, :3, :3] @ turn)
    pose = pose.at[:, :3, 3].add(drawn["position"] * rng.normal(size=(n, 3)))
    twist = np.array([drawn["angular_velocity"]] * 3 + [drawn["linear_velocity"]] * 3)
    xi = clean.xi + twist * rng.normal(size=clean.xi.shape)
    q, qdot = clean.q, clean.qdot
    if d:
        q = q + drawn["q"] * rng.normal(size=q.shape)
        qdot = qdot + drawn["qdot"] * rng.normal(size=qdot.shape)
    measurements = identify.Measurements(
        jnp.asarray(ts), pose=pose, q=q, xi=xi, qdot=qdot, noise=noise
    )
    states = measurements.states
    assert states is not None
    import jax

    to_mujoco = jax.vmap(lambda s: bd.state_to_mujoco(truth, s))
    noisy_qpos, noisy_qvel = (np.array(x) for x in to_mujoco(states))
    for first in _quaternions(case):  # each measured quaternion's sign follows the motion's
        part = slice(first, first + 4)  # (mujoco.sysid compares components)
        flip = np.sum(noisy_qpos[:, part] * qpos[:, part], axis=1) < 0
        noisy_qpos[flip, part] *= -1
    return Record(case, seed, level, measurements, inputs, ts, noisy_qpos, noisy_qvel,
                  torque_ts, torques, *steps, sigmas)  # fmt: skip


def _quaternions(case: Case):
    """Where each quaternion starts in `qpos`: the free root's and every ball joint's."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(case.mjcf)
    free, ball = int(mujoco.mjtJoint.mjJNT_FREE), int(mujoco.mjtJoint.mjJNT_BALL)
    kinds = [int(kind) for kind in model.jnt_type]  # (`in` does not match numpy and enum)
    return [
        int(model.jnt_qposadr[j]) + (3 if kind == free else 0)
        for j, kind in enumerate(kinds)
        if kind in (free, ball)
    ]


def held_out(case: Case, seed: int):
    """A motion neither fit saw: a new start and new torques (seed `100 + seed`)."""
    return 100 + seed, mujoco_record(case, 100 + seed, case.held_out_t1)


def prediction_error(case: Case, model, unseen):
    """MuJoCo's simulation of `model` along the unseen motion (same start, same torques)
    against the truth's: each channel group's RMS error over its spread in the unseen
    motion (rotation: the angle, over one radian)."""
    import mujoco

    seed, (ts, qpos, qvel) = unseen
    _, pred_qpos, pred_qvel = mujoco_record(case, seed, case.held_out_t1, model=model)
    rms = lambda x: float(np.sqrt(np.mean(np.square(x))))
    errors = {}
    if case.floating:
        angles = []
        for a, b in zip(pred_qpos[:, 3:7], qpos[:, 3:7], strict=True):
            difference = np.zeros(3)
            mujoco.mju_subQuat(difference, a, b)
            angles.append(np.linalg.norm(difference))
        errors["rotation"] = rms(angles)
        errors["position"] = rms(pred_qpos[:, :3] - qpos[:, :3]) / _spread(qpos[:, :3])
        errors["linear_velocity"] = rms(pred_qvel[:, :3] - qvel[:, :3]) / _spread(qvel[:, :3])
        errors["angular_velocity"] = rms(pred_qvel[:, 3:6] - qvel[:, 3:6]) / _spread(qvel[:, 3:6])
        shape_pos, shape_vel = slice(7, None), slice(6, None)
    else:
        shape_pos, shape_vel = slice(0, None), slice(0, None)
    if qpos[:, shape_pos].shape[1]:
        errors["q"] = rms(pred_qpos[:, shape_pos] - qpos[:, shape_pos]) / _spread(
            qpos[:, shape_pos]
        )
        errors["qdot"] = rms(pred_qvel[:, shape_vel] - qvel[:, shape_vel]) / _spread(
            qvel[:, shape_vel]
        )
    return errors
