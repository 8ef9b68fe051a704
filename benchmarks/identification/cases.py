"""The identification benchmark's data sets: three systems written once as MJCF, how each
record is driven and started, and where both fits start.

- `chain`: the floating three-body chain of `tests/test_identify_mujoco.py`, driven at its
  two hinges (pose, twist, joint angles and rates measured; torques known);
- `arm`: the two-link arm of `tests/test_identify.py` on a base welded to the world, under
  gravity, driven at shoulder and elbow (angles and rates measured; torques known);
- `tumble`: one asymmetric body tumbling free of torques (pose and twist measured, mass
  known).
"""

import dataclasses

import numpy as np

import bundledyn as bd

RATE = 100  # Hz, the record's sample rate (and the torque log's)
TIMESTEP = 2e-4  # s, MuJoCo's step in every case's MJCF
FACTORS = (1.2, 0.8, 1.25)  # each fitted body's pseudo-inertia at the start, over the truth's

CHAIN = (bd.models / "floating_chain.xml").read_text()

ARM = """
<mujoco model="arm">
  <option integrator="RK4" timestep="2e-4"/>
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
  <actuator>
    <motor joint="shoulder" gear="1"/>
    <motor joint="elbow" gear="1"/>
  </actuator>
</mujoco>
"""

TUMBLE = """
<mujoco model="tumbling body">
  <option gravity="0 0 0" integrator="RK4" timestep="2e-4"/>
  <worldbody>
    <body name="body">
      <freejoint/>
      <inertial pos="0.05 -0.02 0.1" mass="2.0" fullinertia="0.30 0.45 0.6 0.01 -0.02 0.03"/>
    </body>
  </worldbody>
</mujoco>
"""


@dataclasses.dataclass(frozen=True)
class Case:
    """A data set: its MJCF, what is fitted, and how the record is driven."""

    name: str
    mjcf: str
    bodies: tuple[str, ...]  # the fitted bodies
    t1: float  # the record's length (s)
    held_out_t1: float  # the unseen motion's length (s)
    floating: bool  # a free root (pose and twist measured) or a welded one
    gauge: str  # "inputs" (measured torques) or "mass" (the total mass is known)
    description: str
    member: int | None = None  # the seed of a generated member (`family`), None if named
    factors: tuple[float, ...] = FACTORS  # each fitted body's start over the truth


CASES = {
    "chain": Case(
        "chain", CHAIN, ("base", "arm", "hand"), 4.0, 2.0, True, "inputs",
        "floating 3-body chain, 2 driven hinges, no gravity",
    ),
    "arm": Case(
        "arm", ARM, ("upper", "fore"), 4.0, 2.0, False, "inputs",
        "2-link arm on a welded base, gravity, driven shoulder and elbow",
    ),
    "tumble": Case(
        "tumble", TUMBLE, ("body",), 6.0, 4.0, True, "mass",
        "one asymmetric body tumbling torque-free, mass known",
    ),
}  # fmt: skip


# ------------------------------------------------------------------------------- signals


def torque(case: Case, t, seed):
    """The smooth torque signal of `seed` at times `t`, `(..., nu)` (none for `tumble`)."""
    t = np.asarray(t, dtype=float)
    rng = np.random.default_rng(seed)
    if case.member is not None:
        return _generated_torque(case, t, rng)
    if case.name == "chain":  # `_torque` of tests/test_identify_mujoco.py
        amplitude, frequency, phase = rng.uniform(0.5, 1.0, (3, 2, 3))
        terms = 0.4 * amplitude * np.sin((1 + 3 * frequency) * t[..., None, None] + 6.3 * phase)
        return np.sum(terms, -1)
    if case.name == "arm":  # the test's torques with random phases
        phase = rng.uniform(0.0, 2 * np.pi, 4)
        return np.stack(
            [4 * np.sin(1.3 * t + phase[0]) + 2 * np.sin(3.1 * t + phase[1]),
             np.cos(2.3 * t + phase[2]) + 0.5 * np.sin(4.3 * t + phase[3])], axis=-1,
        )  # fmt: skip
    return np.zeros((*t.shape, 0))


def _generated_torque(case: Case, t, rng):
    """A generated member's torques: on each motor three sines of 1–4 rad/s, each scaled
    to accelerate its joint by some 4 rad/s² at the home pose (the torque over the diagonal
    of $M^{-1}$, which counts what the joint's push moves on both sides, a floating base's
    recoil included), so that light and heavy joints move alike."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(case.mjcf)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    dofs = model.jnt_dofadr[model.actuator_trnid[:, 0]]
    scale = 4.0 / np.diag(np.linalg.inv(M))[dofs]
    amplitude, frequency, phase = rng.uniform(0.5, 1.0, (3, model.nu, 3))
    waves = amplitude * np.sin((1 + 3 * frequency) * t[..., None, None] + 6.3 * phase)
    return scale * np.sum(waves, -1) / 3


def initial_velocity(case: Case, model, seed):
    """`(qpos, qvel)` at the start of the record of `seed`."""
    rng = np.random.default_rng(seed)
    if case.member is not None:
        return _generated_start(model, rng)
    qpos = model.qpos0.copy()
    if case.name == "chain":  # as `_mujoco_record`
        qvel = rng.normal(size=model.nv) * np.array([0.1, 0.1, 0.1, 0.5, 0.5, 0.5, 1.0, 1.0])
    elif case.name == "arm":
        qpos[:] = rng.uniform(-0.4, 0.4, 2)
        qvel = rng.normal(size=2) * 0.3
    else:  # a nutating tumble: (v_world, ω_body), ω well away from a principal axis
        omega = np.array([0.6, 0.4, 1.2]) * rng.uniform(0.7, 1.3, 3) * rng.choice([-1, 1], 3)
        qvel = np.concatenate([rng.normal(size=3) * 0.1, omega])
    return qpos, qvel


def _generated_start(model, rng):
    """A generated member's start: hinges within ±0.4 rad, balls turned up to 0.3 rad, and
    rates as the chain's (0.1 m/s and 0.5 rad/s for a free root, 1 rad/s per joint
    coordinate); an arm's rates 0.3 rad/s."""
    import mujoco

    qpos, qvel = model.qpos0.copy(), np.zeros(model.nv)
    for j in range(model.njnt):
        kind, a, v = model.jnt_type[j], model.jnt_qposadr[j], model.jnt_dofadr[j]
        if kind == mujoco.mjtJoint.mjJNT_FREE:
            qvel[v : v + 6] = rng.normal(size=6) * np.array([0.1, 0.1, 0.1, 0.5, 0.5, 0.5])
        elif kind == mujoco.mjtJoint.mjJNT_BALL:
            quat = np.zeros(4)
            axis = rng.normal(size=3)
            mujoco.mju_axisAngle2Quat(quat, axis / np.linalg.norm(axis), rng.uniform(-0.3, 0.3))
            qpos[a : a + 4], qvel[v : v + 3] = quat, rng.normal(size=3)
        else:
            qpos[a], qvel[v] = rng.uniform(-0.4, 0.4), rng.normal()
    if model.jnt_type[0] != mujoco.mjtJoint.mjJNT_FREE:
        qvel *= 0.3
    return qpos, qvel


def nominal_spec(case: Case):
    """The case's MJCF with each fitted body's inertial at the start of both fits: the
    truth's pseudo-inertia times the case's `factors` (chain, arm, generated members); for the tumbling body (whose mass
    is known and whose pseudo-inertia scaled would differ from the truth only along what
    free motion hides) the true mass, the centre at the origin and an isotropic inertia
    (0.4, as in tests/test_identify.py)."""
    import mujoco

    spec = mujoco.MjSpec.from_string(case.mjcf)
    if case.name == "tumble":
        body = spec.body("body")
        body.ipos, body.fullinertia = [0.0, 0.0, 0.0], [0.4, 0.4, 0.4, 0.0, 0.0, 0.0]
        return spec
    for name, factor in zip(case.bodies, case.factors, strict=False):
        body = spec.body(name)
        body.mass = body.mass * factor
        body.fullinertia = np.asarray(body.fullinertia) * factor
    return spec
