"""One member of the family: its field against `mj_forward`, and 10 s of it with
bundledyn's default solver and with MuJoCo RK4 over their settings, timed in alternation."""

import warnings

import jax

import bundledyn as bd
from benchmarks._errors import state_error, time_at_error
from benchmarks._mujoco import physics_state, rollout_final_state
from benchmarks._timing import blocking, interleaved
from benchmarks.family.members import Member, initial_qpos_qvel, mujoco_model
from benchmarks.speed.config import MUJOCO_DT, rollout_fn
from benchmarks.speed.field import data_forward_sampler, scene_field_sampler

FINE_ERROR = 1e-9  # the second accuracy: bundledyn at ≤ 0.5× MuJoCo's time there


def member_scene(member: Member) -> bd.Scene:
    """bundledyn's scene of `member`: its tree and nothing else (the import's list of what
    it leaves out, the humanoid's contacts and motors, is the point: not warned about)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return bd.Scene(bd.Multibody.from_mjcf(mujoco_model(member, MUJOCO_DT)))


def field_ratio(scene, state, model, repeats):
    """The field's time over `mj_forward`'s at the same state, in alternation."""
    data, _ = physics_state(model, scene.system, state)
    timed = interleaved(
        {
            "field": scene_field_sampler(scene, state),
            "mj_forward": data_forward_sampler(model, data),
        },
        repeats,
    )
    field, forward = (stats for _, stats in timed.values())
    return {"field": field, "mj_forward": forward, "ratio": field["median"] / forward["median"]}


def solves(scene, state, member, *, t1, rtols, dts, repeats):
    """bundledyn's default solver over `rtols` and MuJoCo RK4 over `dts` on `t1` seconds:
    each point's error at t1 against RKMK87 at rtol 1e-13, its steps and its time."""
    run = rollout_fn(scene, t1, "RKMK87")
    reference, _ = run(state, 1e-13)
    points, samplers = {}, {}
    for rtol in rtols:
        final, steps = jax.block_until_ready(run(state, rtol))
        points["RKMK87", rtol] = {"setting": rtol, "error": state_error(final, reference)}
        points["RKMK87", rtol]["steps"] = int(steps)
        samplers["RKMK87", rtol] = blocking(run, state, rtol)
    for dt in dts:
        model = mujoco_model(member, dt)
        final, samplers["MuJoCo RK4", dt] = rollout_final_state(model, t1, scene.system, state)
        points["MuJoCo RK4", dt] = {"setting": dt, "error": state_error(final, reference)}
        points["MuJoCo RK4", dt]["steps"] = round(t1 / dt)
    for key, (_, runs) in interleaved(samplers, repeats).items():
        points[key]["time"] = runs
    curves = {}
    for (method, _), point in points.items():
        curves.setdefault(method, []).append(point)
    return curves


def ratios(curves):
    """bundledyn's time over MuJoCo's at MuJoCo's error with dt = 1e-2 (`coarse`) and at
    `FINE_ERROR` (`fine`; None where a sweep does not reach it)."""
    ours, mujoco = curves["RKMK87"], curves["MuJoCo RK4"]
    coarse = mujoco[0]
    t_ours = time_at_error(ours, coarse["error"])
    t_fine, t_mj_fine = time_at_error(ours, FINE_ERROR), time_at_error(mujoco, FINE_ERROR)
    return {
        "coarse_error": coarse["error"],
        "coarse": None if t_ours is None else t_ours / coarse["time"]["median"],
        "fine": None if None in (t_fine, t_mj_fine) else t_fine / t_mj_fine,
    }


def measure_member(member: Member, seed: int, *, t1, rtols, dts, repeats):
    """Everything measured on one member."""
    scene = member_scene(member)
    model = mujoco_model(member, MUJOCO_DT)
    qpos, qvel = initial_qpos_qvel(model, member.rate, seed)
    state = bd.state_from_mujoco(scene.system, qpos, qvel, qpos0=model.qpos0)
    curves = solves(scene, state, member, t1=t1, rtols=rtols, dts=dts, repeats=repeats)
    return {
        "name": member.name,
        "bodies": member.bodies,
        "kind": member.kind,
        "rate": member.rate,
        "dofs": int(model.nv),
        "field": field_ratio(scene, state, model, repeats),
        "solves": curves,
        "ratios": ratios(curves),
    }
