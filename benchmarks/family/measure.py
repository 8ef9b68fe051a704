"""One member of the family: its field against `mj_forward`, and its motion over its
predictable horizon with bundledyn's default solver and with MuJoCo RK4 over their
settings, timed in alternation.

Many members are chaotic: over 10 s two solvers at rtol 1e-13 end far apart, and a final
state's "error" would then measure nothing. Each member is therefore solved over the
longest of `HORIZONS` over which RKMK87 and diffrax's Dopri8 (on the 4×4 embedding), both
at rtol 1e-13, agree to `REFERENCE_AGREEMENT`: a reference good to a tenth of the finest
error compared."""

import warnings

import diffrax
import jax
import jax.numpy as jnp

import bundledyn as bd
from benchmarks._errors import final_state, state_error, time_at_error
from benchmarks._mujoco import physics_state, rollout_final_state
from benchmarks._timing import blocking, interleaved
from benchmarks.family.members import Member, initial_qpos_qvel, mujoco_model
from benchmarks.speed.config import MUJOCO_DT, simulate_options
from benchmarks.speed.field import data_forward_sampler, scene_field_sampler

FINE_ERROR = 1e-9  # the second accuracy: bundledyn at ≤ 0.5× MuJoCo's time there
REFERENCE_AGREEMENT = 1e-10
HORIZONS = (10.0, 5.0, 2.0, 1.0, 0.5)  # seconds, longest first


def adaptive_run(scene, solver, max_steps=200_000):
    """A jitted `(state, rtol, t1) -> (final state, steps)` of `bd.simulate` with `solver`
    (a name in bundledyn or diffrax) at rtol (atol = rtol / 100); rtol and t1 are traced,
    so that every setting and horizon share one compilation. A solve that fails (its step
    budget `max_steps` spent) ends in a NaN state, which is as far from any reference as
    can be."""

    @jax.jit
    def run(state, rtol, t1):
        options = simulate_options(solver, "adaptive", rtol)
        traj = bd.simulate(scene, state, t1, max_steps=max_steps, throw=False, **options)
        failed = traj.result != diffrax.RESULTS.successful
        final = jax.tree.map(lambda x: jnp.where(failed, jnp.nan, x), final_state(traj))
        return final, traj.stats["num_steps"]

    return run


def predictable_horizon(scene, state, horizons):
    """`(t1, reference, agreement)`: the longest horizon over which RKMK87 and Dopri8 at
    rtol 1e-13 agree to `REFERENCE_AGREEMENT`, RKMK87's final state there and the
    agreement; `(None, None, agreement at the shortest)` if none."""
    # Dopri8's budget is small: on the embedding, a ball joint's rotation-vector chart
    # degenerates as it turns (no rechart there), and a grinding check only shortens t1.
    ours, check = adaptive_run(scene, "RKMK87"), adaptive_run(scene, "Dopri8", 20_000)
    for t1 in horizons:
        reference, _ = ours(state, 1e-13, t1)
        agreement = state_error(reference, check(state, 1e-13, t1)[0])
        if agreement <= REFERENCE_AGREEMENT:
            return t1, reference, agreement
    return None, None, agreement


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


# bundledyn's solvers swept: the default first, then the alternative it is chosen over.
SOLVERS = ("RKMK87", "RKMK54")


def sweep_point(run, state, rtol, t1, reference):
    """One setting's error at t1 and steps, and a sampler of its time; a solve that raises
    (a field that is NaN at a step's start: steps far too long for the motion) is a point
    that reaches no error, and is not timed."""
    try:
        final, steps = jax.block_until_ready(run(state, rtol, t1))
    except Exception:  # eqx.error_if's runtime error: its type is JAX's, not public
        return {"setting": rtol, "error": float("inf"), "steps": None}, None
    point = {"setting": rtol, "error": state_error(final, reference), "steps": int(steps)}
    return point, blocking(run, state, rtol, t1)


def solves(scene, state, member, reference, *, t1, rtols, dts, repeats):
    """bundledyn's `SOLVERS` over `rtols` and MuJoCo RK4 over `dts` on `t1` seconds: each
    point's error at t1 against `reference`, its steps and its time."""
    points, samplers = {}, {}
    for solver in SOLVERS:
        run = adaptive_run(scene, solver)
        for rtol in rtols:
            points[solver, rtol], sampler = sweep_point(run, state, rtol, t1, reference)
            if sampler is not None:
                samplers[solver, rtol] = sampler
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


def time_to_reach(points, target):
    """The time a sweep takes to reach error `target`: interpolated log–log between the
    timed points that bracket it, the cheapest point's where every point is within it,
    None where none is."""
    points = [p for p in points if "time" in p]
    if not points:
        return None
    if all(p["error"] <= target for p in points):
        return min(p["time"]["median"] for p in points)
    return time_at_error(points, target)


def ratio_key(solver, part):
    """The key of `solver`'s ratio at the `coarse` or `fine` error: the part's name for
    the default solver, `"<solver> <part>"` for the others."""
    return part if solver == SOLVERS[0] else f"{solver} {part}"


def ratios(curves):
    """Each of bundledyn's `SOLVERS`' time over MuJoCo's at MuJoCo's error with dt = 1e-2
    (`coarse`) and at `FINE_ERROR` (`fine`), keyed by `ratio_key`, and that coarse error:
    infinite where the solver's sweep does not reach the error, None where MuJoCo's does
    not, or the solver was not swept, or nothing was solved."""
    keys = [ratio_key(solver, part) for solver in SOLVERS for part in ("coarse", "fine")]
    if not curves:
        return {"coarse_error": None} | dict.fromkeys(keys)
    coarse = curves["MuJoCo RK4"][0]
    t_mujoco = {"coarse": coarse["time"]["median"]}
    t_mujoco["fine"] = time_to_reach(curves["MuJoCo RK4"], FINE_ERROR)
    target = {"coarse": coarse["error"], "fine": FINE_ERROR}

    def ratio(solver, part):
        if t_mujoco[part] is None or solver not in curves:
            return None
        t_ours = time_to_reach(curves[solver], target[part])
        return float("inf") if t_ours is None else t_ours / t_mujoco[part]

    out = {ratio_key(s, part): ratio(s, part) for s in SOLVERS for part in ("coarse", "fine")}
    return {"coarse_error": coarse["error"]} | out


def member_start(member: Member, seed: int):
    """`(scene, MuJoCo model, state)`: `member` in both simulators at its tumbling start
    (drawn from `seed`)."""
    scene = member_scene(member)
    model = mujoco_model(member, MUJOCO_DT)
    qpos, qvel = initial_qpos_qvel(model, member.rate, seed)
    return scene, model, bd.state_from_mujoco(scene.system, qpos, qvel, qpos0=model.qpos0)


def describe(member: Member, model, horizon, agreement):
    """What every part records of a member: its structure and predictable horizon."""
    return {
        "name": member.name,
        "bodies": member.bodies,
        "kind": member.kind,
        "rate": member.rate,
        "dofs": int(model.nv),
        "horizon": horizon,
        "reference_agreement": agreement,
    }


def measure_member(member: Member, seed: int, *, horizons, rtols, dts, repeats):
    """Everything measured against MuJoCo on one member."""
    scene, model, state = member_start(member, seed)
    t1, reference, agreement = predictable_horizon(scene, state, horizons)
    curves = {}
    if t1 is not None:
        options = dict(t1=t1, rtols=rtols, dts=dts, repeats=repeats)
        curves = solves(scene, state, member, reference, **options)
    return {
        **describe(member, model, t1, agreement),
        "field": field_ratio(scene, state, model, repeats),
        "solves": curves,
        "ratios": ratios(curves),
    }
