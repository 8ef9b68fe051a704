"""Part 3, bundledyn's side: `jax.vmap`ped batches of 1 s rollouts of the 5-body chain,
each method at the setting where it is as accurate as MuJoCo RK4 on the batch, timed in
alternation with MuJoCo's `rollout` and MJX."""

import time

from benchmarks._errors import setting_at_error, state_error
from benchmarks._models import chain_scene, initial_state, mujoco_model
from benchmarks._mujoco import rollout_final_state
from benchmarks._rollouts import batch_rollouts, with_twist
from benchmarks._timing import interleaved
from benchmarks.speed.config import BATCH, METHODS, MUJOCO_DT, rollout_fn, simulate_options
from benchmarks.speed.mujoco_batch import mjx_batch, mjx_calibration, mujoco_batch


def batch_twists(state, batch):
    """Part 3's initial base twists: `state.xi` plus noise of 0.05, for `batch` rollouts."""
    import jax

    return state.xi + 0.05 * jax.random.normal(jax.random.key(0), (batch, 6))


def batch_rollout(method, setting, t1, batch):
    """`(run, xi)`: a jitted `jax.vmap` of 5-body chain rollouts with `method` (a name in
    `METHODS`) at `setting`, returning final poses and step counts, and its input, `batch`
    base twists."""
    scene = chain_scene(5)
    s = initial_state(scene)
    run = batch_rollouts(scene, s, t1, **simulate_options(*METHODS[method], setting))
    return run, batch_twists(s, batch)


def batch_calibration(t1, quick, members=16):
    """Part 3's settings: per method the loosest setting whose largest final-state error
    over `members` rollouts of the batch is at most MuJoCo RK4's with dt = 1e-2 on the same
    rollouts (errors against RKMK87 at rtol 1e-13), with the sweeps behind them."""
    scene = chain_scene(5)
    s = initial_state(scene)
    states = [with_twist(s, x) for x in batch_twists(s, BATCH)[:: BATCH // members]]
    reference = rollout_fn(scene, t1, "RKMK87")
    refs = [reference(state, 1e-13)[0] for state in states]

    def largest_error(final_of):
        return max(state_error(final_of(st), ref) for st, ref in zip(states, refs, strict=True))

    model = mujoco_model(5, MUJOCO_DT)
    mujoco = largest_error(lambda st: rollout_final_state(model, t1, scene.system, st)[0])
    # MJX's RK4 on the same rollouts, from MuJoCo's step down to a hundredth of it.
    mjx = mjx_calibration(t1, scene, states, refs, mujoco)
    steps = range(2, 6) if quick else range(3, 16)
    # Tolerances at 1, 2 and 5 per decade: RKMK87's steps go as rtol^(-1/8), so 2-2.5x in
    # rtol is ~10 % in steps, as fine as the fixed steps' grid. With whole decades it ran
    # 3.3x more accurate than MuJoCo on the batch (rtol 1e-7), and its time with it.
    rtols = [float(f"{m}e-{k}") for k in range(5, 11) for m in (10, 5, 2)]
    sweeps = {"adaptive": rtols, "fixed": [t1 / n for n in steps]}
    out = {"members": members, "mujoco_error": mujoco, "mjx": mjx, "methods": {}}
    for method, (solver, control) in METHODS.items():
        run = rollout_fn(scene, t1, solver, control)
        points = [
            {"setting": x, "error": largest_error(lambda st, run=run, x=x: run(st, x)[0])}
            for x in sweeps[control]
        ]
        out["methods"][method] = {"setting": setting_at_error(points, mujoco), "points": points}
    return out


def batch_sampler(method, setting, t1, batch=BATCH, threads=1):
    """`(sampler, mean steps, first call s)` of `batch_rollout`, the batch split into
    `threads` equal parts run concurrently from Python threads (JAX releases the GIL while
    XLA runs, and XLA's CPU runtime runs one program mostly on one core)."""
    from concurrent.futures import ThreadPoolExecutor

    import jax
    import jax.numpy as jnp

    run, xi = batch_rollout(method, setting, t1, batch)
    parts = jnp.split(xi, threads)
    pool = ThreadPoolExecutor(threads)

    def outputs():
        return list(pool.map(lambda x: jax.block_until_ready(run(x)), parts))

    def sample():
        outputs()

    start = time.perf_counter()
    steps = jnp.concatenate([s for _, s in outputs()])
    return sample, float(steps.mean()), time.perf_counter() - start


def batch_throughput(
    batch_settings, t1, repeats, batch=BATCH, threads=(2,), split=(1,), with_mjx=False
):
    """Each method's batch at its setting, split over each number of Python threads in
    `split` (`batch_sampler`), `mujoco.rollout`'s on each number of `threads` and,
    `with_mjx`, MJX's, timed in alternation: `(bundledyn's by name, [MuJoCo's by threads],
    MJX's or None)`."""
    samplers, settings, first, mujoco = {}, {}, {}, {}
    mjx = mjx_batch(5, batch, t1, MUJOCO_DT) if with_mjx else None
    if mjx is not None:
        samplers["MJX"], mjx = mjx
    for method, setting in batch_settings.items():
        for k in split:
            name = method if k == 1 else f"{method}, {k} threads"
            samplers[name], steps, first[name] = batch_sampler(method, setting, t1, batch, k)
            settings[name] = dict(method=method, threads=k, setting=setting, mean_steps=steps)
    for k in threads:
        samplers[f"MuJoCo {k}"], mujoco[k] = mujoco_batch(5, batch, t1, MUJOCO_DT, k)
    timings = interleaved(samplers, repeats)

    def throughput(info, runs):  # a MuJoCo-side batch of `info["steps"]` steps per rollout
        return info | {
            "time": runs,
            "instance_steps_per_second": batch * info["steps"] / runs["median"],
            "rollouts_per_second": batch / runs["median"],
        }

    for k, info in mujoco.items():
        info |= throughput(info, timings.pop(f"MuJoCo {k}")[1])
    if mjx is not None:
        runs, first_call = timings.pop("MJX")[1], mjx.pop("first_call")
        mjx = throughput(mjx, runs) | {"compile": max(first_call - runs["median"], 0.0)}
    batches = {
        name: settings[name]
        | {
            "time": runs,
            "compile": max(first[name] - runs["median"], 0.0),
            "rollouts_per_second": batch / runs["median"],
        }
        for name, (_, runs) in timings.items()
    }
    return batches, list(mujoco.values()), mjx
