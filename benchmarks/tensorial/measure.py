"""What the tensorial benchmark measures, member by member: one field evaluation in each
formulation beside the `Multibody`'s and `mj_forward`, and a rollout of each beside MuJoCo's
RK4 at the step that reaches the same error."""

import numpy as np

from benchmarks._timing import blocking, interleaved, loop_sampler, summary
from benchmarks.tensorial.members import chain, start

RTOL = 1e-10
REFERENCE_RTOL = 1e-13
ERROR_TIME = 1.0  # where the errors are compared: before the motion's sensitivity dominates
MUJOCO_STEPS = (2e-3, 1e-3, 5e-4, 2e-4, 1e-4, 5e-5, 2e-5)
FIELD_CALLS = 2000


def _sides(member):
    """The member's three formulations' systems and starts, its Multibody scene and state,
    and its MuJoCo model with the start."""
    import mujoco

    import bundledyn as bd

    gyroscopes = chain(member)
    X, V = start(member)
    reference = np.array([0.9, 0.3, 0.2]) / np.linalg.norm([0.9, 0.3, 0.2])
    xml = gyroscopes.to_mjcf()
    tree = bd.Multibody.from_mjcf(xml)
    qpos, qvel = gyroscopes.mujoco_state(X, V)
    scene = bd.Scene(tree, (bd.Gravity(float(gyroscopes.gravity)),), base=bd.PrescribedBase.fixed())
    return {
        "rotations": (gyroscopes.in_rotations(), (X, V)),
        "axes": (gyroscopes.in_axes(reference), gyroscopes.axes_state(X, V, reference)),
        "tree": (scene, bd.state_from_mujoco(tree, qpos, qvel, free_root=False)),
        "mujoco": (mujoco.MjModel.from_xml_string(xml), qpos, qvel),
    }


def _field_samplers(sides):
    import mujoco

    import bundledyn as bd

    samplers = {}
    for name in ("rotations", "axes"):
        system, y0 = sides[name]
        term = bd.TensorialTerm(system)
        samplers[name] = loop_sampler(
            lambda i, y, term=term: term.vf(1e-6 * i, y, None), y0, FIELD_CALLS
        )
    scene, state = sides["tree"]
    term = bd.SceneTerm(scene)
    samplers["tree"] = loop_sampler(
        lambda i, y: term.vf(1e-6 * i, y, None), term.encode(0.0, state), FIELD_CALLS
    )
    model, qpos, qvel = sides["mujoco"]
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = qpos, qvel

    def forward():
        import time

        begin = time.perf_counter()
        for _ in range(FIELD_CALLS):
            mujoco.mj_forward(model, data)
        return (time.perf_counter() - begin) / FIELD_CALLS

    samplers["mj_forward"] = forward
    return samplers


def _tensor_rollout(system, y0, ts, rtol):
    import diffrax
    import equinox as eqx

    import bundledyn as bd

    @eqx.filter_jit
    def run(y0):
        return diffrax.diffeqsolve(
            bd.TensorialTerm(system), bd.TensorialRKMK87(), ts[0], ts[-1], None, y0,
            saveat=diffrax.SaveAt(ts=ts),
            stepsize_controller=diffrax.PIDController(rtol=rtol, atol=rtol, step_ts=ts),
            max_steps=1_000_000,
        ).ys[0]  # fmt: skip

    return lambda: run(y0)


def _axes_of(name, sides, X):
    """The bodies' axes `(times, n, 3)` of a solution in formulation `name`."""
    if name == "axes":
        return np.asarray(X.unit_vectors)
    return np.asarray(X.rotations[..., :, 2])


def _tree_rollout(sides, ts):
    import diffrax

    import bundledyn as bd

    scene, state = sides["tree"]
    tree = scene.system

    def run():
        traj = bd.simulate(
            scene, state, float(ts[-1]), rtol=RTOL, atol=RTOL, saveat=diffrax.SaveAt(ts=ts)
        )  # the default solver, RKMK87
        return traj.q

    def axes(q):
        import jax

        return np.asarray(jax.vmap(tree.body_poses)(q)[:, 1:, :3, 2])

    return run, axes


def _mujoco_rollout(sides, dt, t1):
    """`(sampler, axes at ERROR_TIME and at t1)` of MuJoCo's RK4 at step `dt`."""
    import mujoco
    from mujoco import rollout

    model, qpos, qvel = sides["mujoco"]
    model.opt.integrator, model.opt.timestep = mujoco.mjtIntegrator.mjINT_RK4, dt
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = qpos, qvel
    mujoco.mj_forward(model, data)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    initial = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, initial, spec)
    nstep = round(t1 / dt)
    states = rollout.rollout(model, data, initial[None], nstep=nstep)[0][0]

    def axes_at(step):
        data.qpos[:] = states[step - 1, 1 : 1 + model.nq]
        mujoco.mj_kinematics(model, data)
        return data.xmat[2:].reshape(-1, 3, 3)[:, :, 2].copy()

    def sample():
        rollout.rollout(model, data, initial[None], nstep=nstep)

    return sample, axes_at(round(ERROR_TIME / dt)), axes_at(nstep)


def _mujoco_at_equal_error(sides, target, horizon, reference):
    """`(sampler, errors at ERROR_TIME and the horizon, dt)` of MuJoCo's RK4 at the largest
    of `MUJOCO_STEPS` whose error at ERROR_TIME is at most `target` (the smallest if none)."""
    for dt in MUJOCO_STEPS:
        sample, at_error_time, at_end = _mujoco_rollout(sides, dt, horizon)
        errors = [
            float(np.abs(at_error_time - reference[1]).max()),
            float(np.abs(at_end - reference[2]).max()),
        ]
        if errors[0] <= target or dt == MUJOCO_STEPS[-1]:
            return sample, errors, dt
    raise AssertionError("unreachable: the last step returns")


def member_run(member, horizon, repeats):
    """The member's field costs and rollouts, each side timed in alternation with the others."""
    import jax.numpy as jnp

    sides = _sides(member)
    fields = interleaved(_field_samplers(sides), repeats)
    ts = jnp.array([0.0, ERROR_TIME, horizon])
    reference = _axes_of(
        "rotations", sides, _tensor_rollout(*sides["rotations"], ts, REFERENCE_RTOL)()
    )
    samplers, errors = {}, {}
    for name in ("rotations", "axes"):
        run = _tensor_rollout(*sides[name], ts, RTOL)
        axes = _axes_of(name, sides, run())
        samplers[name] = blocking(run)
        errors[name] = np.abs(axes - reference).max(axis=(1, 2))[1:].tolist()
    run, axes_of_q = _tree_rollout(sides, ts)
    samplers["tree"] = blocking(run)
    errors["tree"] = np.abs(axes_of_q(run()) - reference).max(axis=(1, 2))[1:].tolist()
    sample, errors["mujoco_rk4"], dt = _mujoco_at_equal_error(
        sides, errors["rotations"][0], horizon, reference
    )
    samplers["mujoco_rk4"] = sample
    rollouts = interleaved(samplers, repeats)
    return {
        "label": member["label"],
        "field": {name: timing for name, (_, timing) in fields.items()},
        "rollout": {name: timing for name, (_, timing) in rollouts.items()},
        "first_rollout": {name: first for name, (first, _) in rollouts.items()},
        "errors": errors,
        "mujoco_dt": dt,
    }


def ratio_summary(members, numerator, denominator, part):
    """`summary` of numerator/denominator medians over the members, for `part`."""
    ratios = [m[part][numerator]["median"] / m[part][denominator]["median"] for m in members]
    return summary(ratios)
