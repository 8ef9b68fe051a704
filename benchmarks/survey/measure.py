"""One model of the survey: imported as a MuJoCo user would (`Scene.from_mjcf` with the
model's passive forces and gravity), its metric against MuJoCo's mass matrix and its
motion against MuJoCo's RK4 at dt = 1e-4, with what bundledyn leaves out turned off in
MuJoCo (contacts, limits, actuators, and whatever the import's warning lists); its solve's
time at RK4's error (`solves`) and its gradient's over the forward solve (`gradient`)."""

import time
import warnings

import jax
import jax.numpy as jnp
import numpy as np

import bundledyn as bd
from benchmarks._timing import interleaved
from benchmarks.speed.field import data_forward_sampler, scene_field_sampler
from benchmarks.survey.gradient import gradient_cost
from benchmarks.survey.solves import SURVEYED, TOLERANCES, timed_sweep, tolerance_run

DT = 1e-4
FINE_DT = DT / 8  # RK4's error 8^4 = 4096 times smaller: below the goal on every model
METRIC_GOAL, ROLLOUT_GOAL = 1e-12, 1e-9  # the issue's: relative, and absolute in qpos/qvel
_FREE, _BALL, _HINGE = 0, 1, 3


def comparable(model):
    """`model` (changed in place) with what bundledyn's import leaves out turned off, and
    RK4 at `DT`: `(model, what was turned off)`. Springs, dampers and gravity stay as the
    model has them."""
    import mujoco

    off = mujoco.mjtDisableBit
    model.opt.disableflags |= (
        off.mjDSBL_CONTACT | off.mjDSBL_LIMIT | off.mjDSBL_ACTUATION
        | off.mjDSBL_FRICTIONLOSS | off.mjDSBL_EQUALITY
    )  # fmt: skip
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    model.opt.timestep = DT
    extra = []
    if model.opt.density or model.opt.viscosity:
        model.opt.density, model.opt.viscosity = 0.0, 0.0
        extra.append("fluid forces")
    if np.any(model.body_gravcomp):
        model.body_gravcomp[:] = 0.0
        extra.append("gravity compensation")
    spherical = [j for j in range(model.njnt) if int(model.jnt_type[j]) in (_FREE, _BALL)]
    dofs = [
        int(model.jnt_dofadr[j]) + k
        for j in spherical
        for k in range(3 if int(model.jnt_type[j]) == _BALL else 6)
    ]
    if (
        np.any(model.dof_damping[dofs])
        or np.any(model.dof_armature[dofs])
        or np.any(model.jnt_stiffness[spherical])
    ):
        model.dof_damping[dofs], model.dof_armature[dofs] = 0.0, 0.0
        model.jnt_stiffness[spherical] = 0.0
        extra.append("ball and free joints' damping, armature and stiffness")
    return model, extra


def start(model, seed):
    """A state near the model's home pose: hinges turned by up to 0.3 rad, slides moved by
    about 5 cm, balls and free joints turned by 0.3 rad about random axes, speeds of about
    0.5 rad/s or m/s."""
    rng = np.random.default_rng(seed)
    qpos = model.qpos0.copy()
    for j in range(model.njnt):
        a, kind = int(model.jnt_qposadr[j]), int(model.jnt_type[j])
        if kind == _HINGE:
            qpos[a] += rng.uniform(-0.3, 0.3)
        elif kind in (_FREE, _BALL):
            q = a + (3 if kind == _FREE else 0)
            if kind == _FREE:
                qpos[a : a + 3] += 0.1 * rng.normal(size=3)
            axis = rng.normal(size=3)
            turn = np.concatenate([[np.cos(0.15)], np.sin(0.15) * axis / np.linalg.norm(axis)])
            qpos[q : q + 4] = _quaternion_product(qpos[q : q + 4], turn)
        else:
            qpos[a] += 0.05 * rng.normal()
    return qpos, 0.5 * rng.normal(size=model.nv)


def _quaternion_product(a, b):
    w1, v1, w2, v2 = a[0], a[1:], b[0], b[1:]
    return np.concatenate([[w1 * w2 - v1 @ v2], w1 * v2 + w2 * v1 + np.cross(v1, v2)])


def aligned(model, reference, qpos):
    """`qpos` with each quaternion's sign that of `reference`'s (q and -q are one turn)."""
    out = np.array(qpos, copy=True)
    for j in range(model.njnt):
        kind, a = int(model.jnt_type[j]), int(model.jnt_qposadr[j])
        if kind in (_FREE, _BALL):
            s = slice(a + 3, a + 7) if kind == _FREE else slice(a, a + 4)
            if reference[s] @ out[s] < 0:
                out[s] = -out[s]
    return out


def imported(model):
    """`(scene, what the import leaves out)`, or a `ValueError` naming why it refuses."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the list of what is left out is recorded instead
        parts = bd.parts_from_mjcf(model, passive=True)
        return bd.Scene.from_mjcf(model, passive=True, gravity=True), list(parts.ignored)


def metric_error(model, data, scene, held):
    """`|P^T G P - M| / |M|` (Frobenius) at `data`'s state: G bundledyn's metric, M
    MuJoCo's mass matrix (`mj_fullM`), P the map from `qvel` to bundledyn's velocities."""
    import mujoco

    system = scene.system

    def velocities(qvel):
        state = bd.state_from_mujoco(system, data.qpos, qvel, qpos0=model.qpos0, free_root=not held)
        return state.qdot if held else jnp.concatenate([state.xi, state.qdot])

    P = np.asarray(jax.jacfwd(velocities)(jnp.asarray(data.qvel)))
    state = bd.state_from_mujoco(
        system, data.qpos, data.qvel, qpos0=model.qpos0, free_root=not held
    )
    G = np.asarray(system.metric(state.q))
    ours = P.T @ (G[6:, 6:] if held else G) @ P
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    return float(np.linalg.norm(ours - M) / np.linalg.norm(M)), state


def field_times(scene, state, model, data, repeats):
    """The scene's field (its default algorithm), the dense field where that is another,
    and `mj_forward`, per evaluation in alternation: `{"field", "mj_forward", "ratio"}`
    and, beside a default other than the dense field, `"dense"` and `"dense_ratio"`."""
    samplers = {
        "field": scene_field_sampler(scene, state),
        "mj_forward": data_forward_sampler(model, data),
    }
    if not isinstance(scene.algorithm, bd.DenseField):
        dense = bd.Scene(scene.system, scene.effects, base=scene.base, algorithm=bd.DenseField())
        samplers["dense"] = scene_field_sampler(dense, state)
    timed = {name: stats for name, (_, stats) in interleaved(samplers, repeats).items()}
    forward = timed["mj_forward"]["median"]
    times = timed | {"ratio": timed["field"]["median"] / forward}
    if "dense" in timed:
        times["dense_ratio"] = timed["dense"]["median"] / forward
        times["agreement"] = agreement(scene, dense, state)
    return times


def agreement(scene, dense, state):
    r"""How closely the scene's field and the dense one agree at `state`: the largest
    difference of their values, and of their VJPs at the cotangent $\sin$ of the dense
    values, each over the dense one's largest entry: `{"field", "vjp"}`."""

    def field(scene):
        term = bd.SceneTerm(scene)
        y = term.encode(0.0, state)

        @jax.jit
        def value_and_vjp(x):
            out, vjp = jax.vjp(lambda x: jnp.concatenate(term.body_vf(0.0, (y[0], x), None)), x)
            return out, vjp(jnp.sin(out))[0]

        return value_and_vjp(y[1])

    (ours, ours_vjp), (theirs, their_vjp) = field(scene), field(dense)
    return {
        "field": float(jnp.max(jnp.abs(ours - theirs)) / jnp.max(jnp.abs(theirs))),
        "vjp": float(jnp.max(jnp.abs(ours_vjp - their_vjp)) / jnp.max(jnp.abs(their_vjp))),
    }


def mujoco_rollout(model, qpos, qvel, t1, dt):
    """MuJoCo's `(qpos, qvel)` after `t1` seconds of RK4 steps of `dt` from `(qpos,
    qvel)`, and the time it took."""
    import mujoco

    model.opt.timestep = dt
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = qpos, qvel
    began = time.perf_counter()
    for _ in range(round(t1 / dt)):
        mujoco.mj_step(model, data)
    return data.qpos.copy(), data.qvel.copy(), time.perf_counter() - began


def difference(model, a, b):
    """The largest difference between two `(qpos, qvel)`, quaternions' signs aligned."""
    return float(
        max(np.max(np.abs(aligned(model, a[0], b[0]) - a[0])), np.max(np.abs(b[1] - a[1])))
    )


def survey(file, *, t1, seed, repeats):
    """The survey's entry for one model file."""
    import mujoco

    model = mujoco.MjModel.from_xml_path(str(file.path))
    entry = {"name": file.name, "nv": int(model.nv), "nbody": int(model.nbody) - 1}
    try:
        scene, ignored = imported(model)
    except ValueError as error:
        return entry | {"status": "refused", "reason": str(error)}
    held = isinstance(scene.mode, bd.PrescribedBaseMode)
    model, turned_off = comparable(model)
    entry |= {"status": "imported", "base": "held" if held else "floating", "ignored": ignored}
    entry["turned_off"] = ["contacts, limits, actuators, friction loss"] + turned_off
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = start(model, seed)
    mujoco.mj_forward(model, data)
    entry["metric_error"], state = metric_error(model, data, scene, held)
    entry["algorithm"] = type(scene.algorithm).__name__
    entry["field"] = field_times(scene, state, model, data, repeats)
    qpos, qvel = data.qpos.copy(), data.qvel.copy()
    rk4 = mujoco_rollout(model, qpos, qvel, t1, DT)
    fine = mujoco_rollout(model, qpos, qvel, t1, FINE_DT)
    entry["rk4_error"] = difference(model, fine, rk4)

    def to_mujoco(end):
        return tuple(
            np.asarray(x)
            for x in bd.state_to_mujoco(scene.system, end, qpos0=model.qpos0, free_root=not held)
        )

    run = tolerance_run(scene, t1)
    solves = timed_sweep(
        run,
        state,
        to_mujoco,
        lambda ours: difference(model, fine, ours),
        lambda: mujoco_rollout(model, qpos, qvel, t1, DT)[2],
        entry["rk4_error"],
        repeats,
    )
    entry["solves"], entry["mujoco_seconds"] = solves, solves["mujoco"]["time"]["median"]
    end, steps = run(state, SURVEYED)
    entry["steps"] = int(steps)
    surveyed = solves["points"][TOLERANCES.index(SURVEYED)]
    entry["seconds"] = [solves["first_call"], surveyed["time"]["median"]]
    ours = to_mujoco(end)
    entry["rollout_error"] = difference(model, rk4, ours)
    entry["fine_rollout_error"] = difference(model, fine, ours)
    # Where RK4 at dt = 1e-4 is itself further than the goal from the motion, the goal is
    # judged against RK4 at an eighth of the step (4096 times more accurate).
    agreement = min(entry["rollout_error"], entry["fine_rollout_error"])
    entry["passed"] = entry["metric_error"] <= METRIC_GOAL and agreement <= ROLLOUT_GOAL
    try:
        entry["gradient"] = gradient_cost(scene, state, t1, repeats)
    except Exception as error:  # noqa: BLE001 - a gradient that fails is a finding, recorded
        entry["gradient"] = {"error": f"{type(error).__name__}: {str(error).strip()[:200]}"}
    return entry
