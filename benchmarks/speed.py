"""Speed against MuJoCo, measured in one run on the same MJCF model.

Systems: free-floating chains of n boxes joined by hinges with alternating axes, no gravity
and no forces, written once as MJCF (`chain_mjcf`) and loaded by both MuJoCo and bundledyn
(`bd.Multibody.from_mjcf`). float64 on the CPU. Every time is the median, min and max over
`--repeats` runs (≥ 5 for the published results).

1. **Vector field**: one evaluation of `scene.vector_field` inside a compiled `fori_loop`
   (no dispatch), against MuJoCo's `mj_forward` (Python loop over the C call) and one RK4
   step (`mujoco.rollout`, a C loop), for n = 1, 5, 10, 20.
2. **10 s of the 5-body chain**: bundledyn's default solver (RKMK87) and its fifth-order
   RKMK54 swept over tolerances, RKMK87 with fixed steps (`diffrax.ConstantStepSize`) over
   the step, and MuJoCo RK4 over time steps, errors against a reference (RKMK87 at rtol
   1e-13, checked against diffrax's Dopri8); wall time interpolated (log–log) at the error
   of MuJoCo RK4 with dt = 1e-2 and at 1e-10.
3. **Batches**: `jax.vmap` of 1 s rollouts over 1024 initial states, each method at the
   loosest tolerance (1, 2, 5 per decade) or longest step whose largest error over 16
   rollouts of the batch is at most MuJoCo RK4's with dt = 1e-2 on them, against
   `mujoco.rollout` on 2 threads and, when `mujoco.mjx` is installed, MJX: timed at
   dt = 1e-2 and compared at the step where its error on those rollouts is MuJoCo's.
4. **Compile times** of `simulate` (n = 5, 20) and of its `jax.grad` (n = 20).
5. **Gradients**: `jax.grad` of a loss on the 10 s rollout over the forward solve, timed in
   alternation with a profile of where its time goes (the field, a step and their VJPs)
   and with baselines, diffrax's `Dopri8` on fields of the same size whose VJP is cheap (a
   linear one, and a network about as costly as the chain's field); peak memory of the
   gradient of a 10⁵-step rollout (RKMK4, fixed step, checkpointed).

Parts 1, 3 and 4 run twice, in fresh worker processes: with XLA's defaults and with
`bundledyn.CPU_XLA_FLAGS` (XLA reads its flags when the backend starts).

Every comparison is timed in alternation (`interleaved`): each repeat runs bundledyn and
MuJoCo once each, in turn, so that both see the same load. On a shared machine whole
seconds run 1.5–2× slower, pinned to one core or not; timed one after the other, the two
sides of a ratio could fall in different phases.

Usage, from the repository root (needs the `bench` extra for MuJoCo)::

    python -m benchmarks.speed                 # full run; writes results/speed.{md,json}
    python -m benchmarks.speed --quick         # small sizes, 2 repeats, prints only
    python -m benchmarks.speed --report-only   # redraw the markdown from the JSON
    python -m benchmarks.speed --device-batch  # part 3 on a GPU: results/speed_gpu.{md,json}

`--device-batch` runs on JAX's default device at the settings of the committed CPU run,
with MuJoCo on the host's CPU, for 1024 to 65536 rollouts, and reruns the first 64 on the
host's CPU to show that the device computes the same trajectories.
"""

import argparse
import datetime
import json
import math
import os
import pathlib
import platform
import resource
import statistics
import subprocess
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
T_CHAIN = 10.0
MUJOCO_DT = 1e-2
TARGET_ERROR = 1e-10
LOOP_EVALS = 1000
BATCH = 1024
MEMORY_STEPS = 100_000
DEVICE_BATCHES = (1024, 8192, 65536)  # `--device-batch`
BASELINE_DEPTHS = (1, 32)  # part 5a: the linear ODE and a network about as costly as the chain
FIXED_STEPS = (40, 50, 60, 70, 80, 100, 120, 160, 200, 250)  # steps over 10 s, part 2
# bundledyn's methods in parts 2 and 3, the first the default: name -> (solver, step control).
# Adaptive ones are swept over rtol, fixed-step ones over the step.
METHODS = {
    "RKMK87": ("RKMK87", "adaptive"),
    "RKMK54": ("RKMK54", "adaptive"),
    "RKMK87, fixed step": ("RKMK87", "fixed"),
}
# Parts 1, 3 and 4 run under each: the key of `report["settings"]` -> its label.
XLA_SETTINGS = {"bundledyn": "CPU_XLA_FLAGS", "xla_defaults": "XLA defaults"}


# ------------------------------------------------------------------------------- models


def chain_mjcf(n: int) -> str:
    """MJCF of a free chain of n boxes (hinges alternate y and z), gravity off."""
    bodies = ""
    for i in reversed(range(n)):
        mass, b = 1.0 + 0.3 * i, 0.1 + 0.02 * i
        a, c = 0.5, 0.08
        inertia = [
            mass / 12 * (b * b + c * c),
            mass / 12 * (a * a + c * c),
            mass / 12 * (a * a + b * b),
        ]
        joint = (
            '<freejoint name="root"/>'
            if i == 0
            else f'<joint type="hinge" axis="{"0 0 1" if i % 2 else "0 1 0"}" pos="-0.25 0 0"/>'
        )
        inner = bodies
        bodies = (
            f'<body name="b{i}" pos="{0.5 if i else 0.0} 0 0">{joint}'
            f'<inertial pos="{0.02 * i} 0.01 0" mass="{mass}" '
            f'diaginertia="{inertia[0]} {inertia[1]} {inertia[2]}"/>{inner}</body>'
        )
    return (
        '<mujoco><option gravity="0 0 0" timestep="0.01" integrator="RK4"/>'
        f"<worldbody>{bodies}</worldbody></mujoco>"
    )


def chain_scene(n: int):
    """The bundledyn scene of `chain_mjcf(n)`."""
    import bundledyn as bd

    return bd.Scene(bd.Multibody.from_mjcf(chain_mjcf(n)))


def initial_state(scene):
    """A tumbling state: bent shape, base twist and joint rates all non-zero."""
    import jax.numpy as jnp

    import bundledyn as bd

    k = jnp.arange(scene.system.shape_dim, dtype=float)
    xi = jnp.array([0.3, -0.2, 0.5, 0.1, 0.0, -0.1])
    return bd.State(jnp.eye(4), 0.3 * jnp.sin(k + 1.0), xi, 0.5 * jnp.cos(k))


# ------------------------------------------------------------------------------- timing


def summary(samples):
    return {"median": statistics.median(samples), "min": min(samples), "max": max(samples)}


def timed(fn, *args, repeats):
    """`(output, compile s, summary of run s)`; compile = first call minus the median run."""
    import jax

    start = time.perf_counter()
    out = jax.block_until_ready(fn(*args))
    first = time.perf_counter() - start
    runs = []
    for _ in range(repeats):
        start = time.perf_counter()
        out = jax.block_until_ready(fn(*args))
        runs.append(time.perf_counter() - start)
    return out, max(first - statistics.median(runs), 0.0), summary(runs)


def interleaved(samplers, repeats):
    """Time zero-argument callables in alternation: `{name: (first call s, summary of runs)}`.

    Each of `repeats` rounds calls every sampler once, in reverse order every other round.
    A sampler returns its own measurement in seconds (per unit of work), or None to be
    timed here.
    """

    def sample(fn):
        start = time.perf_counter()
        seconds = fn()
        return time.perf_counter() - start if seconds is None else seconds

    first = {name: sample(fn) for name, fn in samplers.items()}
    runs = {name: [] for name in samplers}
    names = list(samplers)
    for r in range(repeats):
        for name in names if r % 2 == 0 else names[::-1]:
            runs[name].append(sample(samplers[name]))
    return {name: (first[name], summary(runs[name])) for name in names}


def blocking(fn, *args):
    """A sampler of `fn(*args)` that waits for JAX's result."""
    import jax

    def sample():
        jax.block_until_ready(fn(*args))

    return sample


# ------------------------------------------------------------------------------- MuJoCo


def mujoco_model(n, dt=MUJOCO_DT):
    import mujoco

    model = mujoco.MjModel.from_xml_string(chain_mjcf(n))
    model.opt.timestep = dt
    return model


def mujoco_initial(model, scene, state):
    """MuJoCo's full physics state for bundledyn's `state` (same model, same motion)."""
    import mujoco
    import numpy as np

    import bundledyn as bd

    qpos, qvel = bd.state_to_mujoco(scene.system, state, qpos0=model.qpos0)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = np.asarray(qpos), np.asarray(qvel)
    mujoco.mj_forward(model, data)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    initial = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, initial, spec)
    return data, initial


def mj_forward_sampler(n, calls=2000):
    """A sampler of seconds per `mj_forward` (a Python loop over the C call)."""
    import mujoco

    scene = chain_scene(n)
    model = mujoco_model(n)
    data, _ = mujoco_initial(model, scene, initial_state(scene))

    def sample():
        start = time.perf_counter()
        for _ in range(calls):
            mujoco.mj_forward(model, data)
        return (time.perf_counter() - start) / calls

    return sample


def mujoco_rk4_step(n, repeats, calls=2000):
    """Seconds per MuJoCo RK4 step (`mujoco.rollout`, a C loop)."""
    from mujoco import rollout

    scene = chain_scene(n)
    model = mujoco_model(n)
    data, initial = mujoco_initial(model, scene, initial_state(scene))

    def sample():
        start = time.perf_counter()
        rollout.rollout(model, data, initial[None], nstep=calls)
        return (time.perf_counter() - start) / calls

    return {"rk4_step": interleaved({"rk4": sample}, repeats)["rk4"][1]}


def mujoco_final_state(n, dt, t1, scene, state):
    """MuJoCo RK4 from `state` to `t1` with step `dt`: `(final state in bundledyn's
    variables, sampler of the rollout)`."""
    from mujoco import rollout

    from bundledyn import state_from_mujoco

    model = mujoco_model(n, dt)
    data, initial = mujoco_initial(model, scene, state)
    nstep = round(t1 / dt)

    def run():
        return rollout.rollout(model, data, initial[None], nstep=nstep)[0]

    end = run()[0, -1]
    qpos, qvel = end[1 : 1 + model.nq], end[1 + model.nq : 1 + model.nq + model.nv]
    final = state_from_mujoco(scene.system, qpos, qvel, qpos0=model.qpos0)

    def sample():
        run()

    return final, sample


def mujoco_batch_initials(model, n, batch):
    """MuJoCo's full physics states of part 3's batch: the n-body chain's initial state with
    noise of 0.05 on the base velocity, `(batch, state size)`."""
    import numpy as np

    scene = chain_scene(n)
    _, initial = mujoco_initial(model, scene, initial_state(scene))
    rng = np.random.default_rng(0)
    initials = np.repeat(initial[None], batch, axis=0)
    vel = slice(1 + model.nq, 1 + model.nq + 6)
    initials[:, vel] += 0.05 * rng.standard_normal((batch, 6))
    return initials


def mujoco_batch(n, batch, t1, dt, threads=2):
    """`(sampler, info)` of `mujoco.rollout` over `batch` states on `threads` threads."""
    import mujoco
    from mujoco import rollout

    model = mujoco_model(n, dt)
    initials = mujoco_batch_initials(model, n, batch)
    datas = [mujoco.MjData(model) for _ in range(threads)]
    nstep = round(t1 / dt)

    def sample():
        rollout.rollout(model, datas, initials, nstep=nstep, persistent_pool=True)

    return sample, {"threads": threads, "steps": nstep}


def mjx_rollout(model):
    """MJX (MuJoCo in JAX) from MuJoCo's `model`: a jitted `jax.vmap` of `nstep` steps of
    `dt` from batches of `(qpos, qvel)` to the final `(qpos, qvel)`, `run(qpos, qvel, dt,
    nstep)` (one compile for every step); None without `mujoco.mjx`."""
    try:
        from mujoco import mjx
    except ImportError:
        return None
    import jax

    mjx_model = mjx.put_model(model)

    @jax.jit
    def run(qpos, qvel, dt, nstep):
        m = mjx_model.tree_replace({"opt.timestep": dt})

        def one(qpos, qvel):
            data = mjx.make_data(m).replace(qpos=qpos, qvel=qvel)
            data = jax.lax.fori_loop(0, nstep, lambda _, d: mjx.step(m, d), data)
            return data.qpos, data.qvel

        return jax.vmap(one)(qpos, qvel)

    return run


def mjx_batch(n, batch, t1, dt):
    """`(sampler, info)` of MJX on the batch of `mujoco_batch` (its initial states, RK4 and
    dt), or None without `mujoco.mjx`; `info["first_call"]` is the first call's seconds."""
    import jax.numpy as jnp

    model = mujoco_model(n, dt)
    run = mjx_rollout(model)
    if run is None:
        return None
    initials = mujoco_batch_initials(model, n, batch)
    qpos = jnp.asarray(initials[:, 1 : 1 + model.nq])
    qvel = jnp.asarray(initials[:, 1 + model.nq : 1 + model.nq + model.nv])
    nstep = round(t1 / dt)
    sample = blocking(run, qpos, qvel, dt, nstep)
    start = time.perf_counter()
    sample()
    return sample, {"steps": nstep, "first_call": time.perf_counter() - start}


def mjx_calibration(t1, scene, states, refs, target, divisions=(1, 2, 5, 10, 20, 50, 100)):
    """MJX's RK4 on part 3's calibration rollouts, at MuJoCo's step divided by each of
    `divisions`: the largest final-state error over the rollouts (against `refs`) at each
    step, and the longest step whose error is at most `target`; None without `mujoco.mjx`."""
    import numpy as np

    from bundledyn import state_from_mujoco

    model = mujoco_model(5, MUJOCO_DT)
    run = mjx_rollout(model)
    if run is None:
        return None
    datas = [mujoco_initial(model, scene, state)[0] for state in states]
    qpos0, qvel0 = np.stack([d.qpos for d in datas]), np.stack([d.qvel for d in datas])
    points = []
    for k in divisions:
        steps = round(k * t1 / MUJOCO_DT)
        qpos, qvel = run(qpos0, qvel0, MUJOCO_DT / k, steps)
        error = max(
            state_error(state_from_mujoco(scene.system, p, v, qpos0=model.qpos0), r)
            for p, v, r in zip(qpos, qvel, refs, strict=True)
        )
        points.append({"dt": MUJOCO_DT / k, "steps": steps, "error": error})
    matched = next((p for p in points if p["error"] <= target), None)
    return {"points": points, "at_target": matched}


# ------------------------------------------------------------------------------- bundledyn


def loop_sampler(fn, y, calls):
    """A sampler of seconds per call of `fn(i, y)` (a pytree shaped as `y`) inside a
    compiled `fori_loop`, each call depending on the last (no dispatch)."""
    import jax

    def body(i, y):
        return jax.tree.map(lambda a, b: a + 1e-6 * b, y, fn(i, y))

    run = blocking(jax.jit(lambda y: jax.lax.fori_loop(0, calls, body, y)), y)

    def sample():
        start = time.perf_counter()
        run()
        return (time.perf_counter() - start) / calls

    return sample


def field_sampler(n):
    """A sampler of seconds per vector-field evaluation of the n-body chain (`loop_sampler`)."""
    import bundledyn as bd

    scene = chain_scene(n)
    term = bd.SceneTerm(scene)
    y = term.encode(0.0, initial_state(scene))
    return loop_sampler(lambda i, y: term.vf(1e-6 * i, y, None), y, LOOP_EVALS)


def field_cost(n, repeats):
    """Part 1 in a worker: the field's cost and `mj_forward`'s, timed in alternation."""
    (first, field), (_, forward) = interleaved(
        {"field": field_sampler(n), "mj_forward": mj_forward_sampler(n)}, repeats
    ).values()
    return {
        "per_evaluation": field,
        "mj_forward": forward,
        "compile": LOOP_EVALS * max(first - field["median"], 0.0),
    }


def simulate_options(solver, control, setting):
    """`bd.simulate`'s keywords for `solver` (a name in bundledyn or diffrax) at `setting`:
    rtol (atol = rtol / 100) for `control = "adaptive"`, the step for `"fixed"`."""
    import diffrax

    import bundledyn as bd

    options = {"solver": (getattr(bd, solver, None) or getattr(diffrax, solver))()}
    if control == "fixed":
        return options | {"dt0": setting, "stepsize_controller": diffrax.ConstantStepSize()}
    return options | {"rtol": setting, "atol": setting * 1e-2}


def rollout_fn(scene, t1, solver, control="adaptive"):
    """A jitted `(state, setting) -> (final state, steps)` of `bd.simulate` (see
    `simulate_options`); the setting is traced, so a sweep compiles once."""
    import jax

    import bundledyn as bd

    @jax.jit
    def run(state, setting):
        options = simulate_options(solver, control, setting)
        traj = bd.simulate(scene, state, t1, max_steps=200_000, **options)
        return (traj.g[-1], traj.q[-1], traj.xi[-1], traj.qdot[-1]), traj.stats["num_steps"]

    return run


def state_error(a, b):
    import jax.numpy as jnp

    from bundledyn import lie

    g, *rest = a
    g_ref, *rest_ref = b
    parts = [jnp.max(jnp.abs(lie.se3_log(lie.se3_inv(g_ref) @ g)))]
    parts += [jnp.max(jnp.abs(x - y), initial=0.0) for x, y in zip(rest, rest_ref, strict=True)]
    return float(jnp.max(jnp.stack(parts)))


def time_at_error(points, target):
    """Log–log interpolated time at `target` error over (error, time) points; None outside."""
    import numpy as np

    pts = sorted(
        ((p["error"], p["time"]["median"]) for p in points if p["error"] > 0), key=lambda x: -x[0]
    )
    for (e0, t0), (e1, t1) in zip(pts, pts[1:], strict=False):
        if e1 <= target <= e0:
            w = np.log(target / e0) / np.log(e1 / e0) if e1 != e0 else 0.0
            return float(np.exp(np.log(t0) + w * np.log(t1 / t0)))
    return None


def setting_at_error(points, target):
    """The loosest sweep setting whose error is at most `target` (the most accurate if none)."""
    ok = [p for p in points if p["error"] <= target] or [min(points, key=lambda p: p["error"])]
    return max(ok, key=lambda p: p["error"])["setting"]


def setting_label(method, setting):
    """`rtol 1e-07` for an adaptive method of `METHODS`, else (fixed step, MuJoCo) `dt 0.167`."""
    adaptive = METHODS.get(method, (None, "fixed"))[1] == "adaptive"
    return f"rtol {setting:.0e}" if adaptive else f"dt {setting:.3g}"


def chain_ten_seconds(repeats, quick):
    """Part 2: bundledyn's solvers and MuJoCo RK4 on 10 s of the 5-body chain, errors vs a reference."""
    import jax

    scene = chain_scene(5)
    state = initial_state(scene)
    t1 = 2.0 if quick else T_CHAIN
    ref, _ = rollout_fn(scene, t1, "RKMK87")(state, 1e-13)
    check, _ = rollout_fn(scene, t1, "Dopri8")(state, 1e-13)
    rows = {"t1": t1, "reference_agreement": state_error(ref, check)}
    sweeps = {
        "adaptive": (1e-4, 1e-7, 1e-10) if quick else tuple(10.0**-k for k in range(3, 13)),
        "fixed": tuple(t1 / n for n in ((10, 20, 40) if quick else FIXED_STEPS)),
    }
    dts = (1e-2, 2.5e-3) if quick else tuple(MUJOCO_DT / 2**k for k in range(6))
    points, samplers = {}, {}
    for method, (solver, control) in METHODS.items():
        run = rollout_fn(scene, t1, solver, control)
        for setting in sweeps[control]:
            final, steps = jax.block_until_ready(run(state, setting))
            points[method, setting] = {"setting": setting, "error": state_error(final, ref)}
            points[method, setting]["steps"] = int(steps)
            samplers[method, setting] = blocking(run, state, setting)
    for dt in dts:
        final, samplers["MuJoCo RK4", dt] = mujoco_final_state(5, dt, t1, scene, state)
        points["MuJoCo RK4", dt] = {"setting": dt, "error": state_error(final, ref)}
        points["MuJoCo RK4", dt]["steps"] = round(t1 / dt)
    for key, (_, runs) in interleaved(samplers, repeats).items():
        points[key]["time"] = runs
    for (method, setting), p in points.items():
        rows.setdefault(method, []).append(p)
        print(
            f"  {method} {setting:.1e}: error={p['error']:.1e} time={p['time']['median'] * 1e3:.1f} ms",
            flush=True,
        )
    return rows


def batch_rollout(method, setting, t1, batch):
    """Part 3: `(run, xi)`: a jitted `jax.vmap` of 5-body chain rollouts with `method` (a
    name in `METHODS`) at `setting`, returning final poses and step counts, and its input,
    `batch` base twists."""
    import jax

    import bundledyn as bd

    scene = chain_scene(5)
    s = initial_state(scene)

    @jax.jit
    def run(xi):
        def one(x):
            options = simulate_options(*METHODS[method], setting)
            traj = bd.simulate(scene, bd.State(s.g, s.q, x, s.qdot), t1, **options)
            return traj.g[-1], traj.stats["num_steps"]

        return jax.vmap(one)(xi)

    return run, batch_twists(s, batch)


def batch_twists(state, batch):
    """Part 3's initial base twists: `state.xi` plus noise of 0.05, for `batch` rollouts."""
    import jax

    return state.xi + 0.05 * jax.random.normal(jax.random.key(0), (batch, 6))


def batch_calibration(t1, quick, members=16):
    """Part 3's settings: per method the loosest setting whose largest final-state error
    over `members` rollouts of the batch is at most MuJoCo RK4's with dt = 1e-2 on the same
    rollouts (errors against RKMK87 at rtol 1e-13), with the sweeps behind them."""
    import bundledyn as bd

    scene = chain_scene(5)
    s = initial_state(scene)
    twists = batch_twists(s, BATCH)[:: BATCH // members]
    states = [bd.State(s.g, s.q, x, s.qdot) for x in twists]
    reference = rollout_fn(scene, t1, "RKMK87")
    refs = [reference(state, 1e-13)[0] for state in states]

    def largest_error(final_of):
        return max(state_error(final_of(st), ref) for st, ref in zip(states, refs, strict=True))

    mujoco = largest_error(lambda st: mujoco_final_state(5, MUJOCO_DT, t1, scene, st)[0])
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
    """Part 3: `(sampler, mean steps, first call s)` of `batch_rollout`, the batch split into
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


def device_agreement(batch_settings, t1, batch=64):
    """The same batch on JAX's default device and on the CPU: the largest difference of the
    final poses, and whether every rollout took the same number of steps."""
    import jax
    import numpy as np

    out = {}
    for method, setting in batch_settings.items():
        run, xi = batch_rollout(method, setting, t1, batch)
        g, steps = run(xi)
        with jax.default_device(jax.devices("cpu")[0]):
            run_cpu, xi_cpu = batch_rollout(method, setting, t1, batch)
            g_cpu, steps_cpu = run_cpu(xi_cpu)
        out[method] = {
            "batch": batch,
            "max_pose_difference": float(np.max(np.abs(np.asarray(g) - np.asarray(g_cpu)))),
            "same_steps": bool(np.array_equal(steps, steps_cpu)),
        }
    return out


def batch_throughput(
    batch_settings, t1, repeats, batch=BATCH, threads=(2,), split=(1,), with_mjx=False
):
    """Part 3: each method's batch at its setting, split over each number of Python
    threads in `split` (`batch_sampler`), `mujoco.rollout`'s on each number of `threads`
    and, `with_mjx`, MJX's, timed in alternation: `(bundledyn's by name, [MuJoCo's by
    threads], MJX's or None)`."""
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


def device_batches(sizes, batch_settings, t1, repeats):
    """Part 3 on JAX's default device (a GPU where there is one) over growing batches.

    MuJoCo runs on this machine's CPU beside the first size only, on 2 threads and on all
    cores: `mujoco.rollout`'s throughput does not grow with the batch once its threads are
    busy, and the larger batches would take minutes per repeat on 2 threads. MJX, where
    installed, runs on the device beside every size.
    """
    import jax

    cores = len(os.sched_getaffinity(0))
    rows = []
    for i, batch in enumerate(sizes):
        threads = tuple(dict.fromkeys((2, cores))) if i == 0 else ()
        bundledyn, mujoco, mjx = batch_throughput(
            batch_settings, t1, repeats, batch, threads, with_mjx=True
        )
        rows.append({"batch": batch, "bundledyn": bundledyn, "mujoco": mujoco, "mjx": mjx})
        print(f"  batch {batch}: {bundledyn}", file=sys.stderr, flush=True)
    device = jax.devices()[0]
    return {
        "device": f"{device.platform}: {device.device_kind}",
        "rows": rows,
        "agreement_with_cpu": device_agreement(batch_settings, t1),
    }


def compile_costs(ns, t1=1.0):
    """Part 4: tracing + XLA compile time of `simulate` (and `jax.grad` for the last n)."""
    import jax
    import jax.numpy as jnp

    import bundledyn as bd

    rows = {}
    for n in ns:
        scene = chain_scene(n)
        state = initial_state(scene)

        def loss(xi, scene=scene, state=state):
            s = state
            traj = bd.simulate(scene, bd.State(s.g, s.q, xi, s.qdot), t1, rtol=1e-6, atol=1e-8)
            return jnp.sum(traj.g[-1, :3, 3] ** 2)

        rows[str(n)] = {"simulate": _compile_seconds(jax.jit(loss), state.xi)}
        if n == ns[-1]:
            rows[str(n)]["grad"] = _compile_seconds(jax.jit(jax.grad(loss)), state.xi)
        print(f"  compile n={n}: {rows[str(n)]}", flush=True)
    return rows


def _compile_seconds(jitted, *args):
    start = time.perf_counter()
    lowered = jitted.lower(*args)
    traced = time.perf_counter() - start
    lowered.compile()
    return {
        "trace_and_lower": traced,
        "xla": time.perf_counter() - start - traced,
        "total": time.perf_counter() - start,
    }


def gradient_cost(repeats, t1, rtol=1e-6):
    """Part 5a: `jax.grad` of a loss on the rollout over the forward solve (checkpointed),
    timed in alternation with the units of `gradient_units`."""
    import jax
    import jax.numpy as jnp

    import bundledyn as bd

    scene = chain_scene(5)
    s = initial_state(scene)

    def loss(xi):
        state = bd.State(s.g, s.q, xi, s.qdot)
        traj = bd.simulate(scene, state, t1, **simulate_options("RKMK87", "adaptive", rtol))
        return jnp.sum(traj.g[-1, :3, 3] ** 2) + jnp.sum(traj.q[-1] ** 2)

    units, profile = gradient_units(scene, s, t1, rtol)
    baselines = baseline_samplers(t1, rtol)
    samplers = {
        "forward": blocking(jax.jit(loss), s.xi),
        "grad": blocking(jax.jit(jax.grad(loss)), s.xi),
    }
    timings = interleaved(samplers | units | baselines, repeats)
    (_, forward), (first, grad) = timings["forward"], timings["grad"]
    return {
        "forward": forward,
        "grad": grad,
        "grad_compile": max(first - grad["median"], 0.0),
        "ratio": grad["median"] / forward["median"],
        "baselines": {
            str(depth): {
                unit: timings[f"baseline_{depth}_{unit}"][1]
                for unit in ("forward", "grad", "field", "field_vjp")
            }
            for depth in BASELINE_DEPTHS
        },
        "profile": profile | {k: timings[k][1] for k in units},
    }


def skew_network_ode(depth, dim=30):
    """Part 5a's baselines: the field $f(y) = K_L\\tanh(K_{L-1}\\cdots\\tanh(K_1 y))$ of
    `depth` $= L$ fixed skew-symmetric `dim`×`dim` matrices (as many numbers as the
    5-body chain's state), linear for $L = 1$, and an initial state. Its VJP costs little
    more than the field: what diffrax's adjoint loop costs with a field of a given price and
    an inexpensive reverse pass. Returns `(field, y0)`, `field(t, y, args)`."""
    import jax.numpy as jnp
    import numpy as np

    rng = np.random.default_rng(0)
    K = rng.normal(size=(depth, dim, dim)) / np.sqrt(dim)
    K = jnp.asarray(K - np.swapaxes(K, 1, 2))

    def field(t, y, args):
        for k in K[:-1]:
            y = jnp.tanh(k @ y)
        return K[-1] @ y

    return field, jnp.asarray(rng.normal(size=dim))


def baseline_loss(field, t1, rtol):
    """A loss on diffrax's own `Dopri8` solving `field` over `t1` at `rtol`
    (`RecursiveCheckpointAdjoint`, diffrax's default): $|y(t_1)|^2$."""
    import diffrax
    import jax.numpy as jnp

    term = diffrax.ODETerm(field)
    controller = diffrax.PIDController(rtol=rtol, atol=rtol)

    def loss(y0):
        sol = diffrax.diffeqsolve(
            term, diffrax.Dopri8(), 0.0, t1, 0.1, y0, stepsize_controller=controller
        )
        return jnp.sum(sol.ys[-1] ** 2)

    return loss


def baseline_samplers(t1, rtol):
    """Part 5a's baselines (`skew_network_ode`, depths `BASELINE_DEPTHS`): their forward
    solve, its `jax.grad`, and the field and its VJP in compiled loops."""
    import jax

    samplers = {}
    for depth in BASELINE_DEPTHS:
        field, y0 = skew_network_ode(depth)
        loss = baseline_loss(field, t1, rtol)
        samplers |= {
            f"baseline_{depth}_forward": blocking(jax.jit(loss), y0),
            f"baseline_{depth}_grad": blocking(jax.jit(jax.grad(loss)), y0),
            f"baseline_{depth}_field": loop_sampler(
                lambda i, y, f=field: f(0.0, y, None), y0, LOOP_EVALS
            ),
            f"baseline_{depth}_field_vjp": loop_sampler(
                vjp_unit(lambda i, y, f=field: f(0.0, y, None)), y0, LOOP_EVALS
            ),
        }
    return samplers


def vjp_unit(fn):
    """The VJP of a loop unit `fn(i, y)` at `y`, pulling back `y` itself (shaped as `y`)."""
    import jax

    return lambda i, y: jax.vjp(lambda y: fn(i, y), y)[1](y)[0]


def gradient_units(scene, state, t1, rtol):
    """Part 5c: samplers of where the gradient's time goes, per call in compiled loops
    (`loop_sampler`): the body field the RKMK stages evaluate, one `RKMK87` step at the
    forward solve's mean step, and their VJPs; with the solve's steps (accepted and
    rejected)."""

    import bundledyn as bd

    options = simulate_options("RKMK87", "adaptive", rtol)
    steps = int(bd.simulate(scene, state, t1, **options).stats["num_steps"])
    term, solver = bd.SceneTerm(scene), bd.RKMK87(dense_output=False)
    y = term.encode(0.0, state)

    def field(i, y):  # the twist as a 4×4 matrix, so that the loop can feed it back as y
        xi, xdot = term.body_vf(0.0, y, None)
        return bd.lie.se3_hat(xi), xdot

    def step(i, y):
        return solver.step(term, 0.0, t1 / steps, y, None, None, False)[0]

    units = {
        "field": field,
        "field_vjp": vjp_unit(field),
        "step": step,
        "step_vjp": vjp_unit(step),
    }
    calls = {"field": LOOP_EVALS, "step": LOOP_EVALS // 10}
    samplers = {k: loop_sampler(fn, y, calls[k.split("_")[0]]) for k, fn in units.items()}
    return samplers, {
        "steps": steps,
        "stages": solver.tableau.step_stages,
        "field_unit": "body field (`Scene.body_field`)",
    }


def gradient_memory(steps):
    """Part 5b (own process): peak memory of `jax.grad` through a `steps`-step rollout."""
    import diffrax
    import jax
    import jax.numpy as jnp

    import bundledyn as bd

    scene = chain_scene(5)
    s = initial_state(scene)
    dt = 1e-4

    def loss(xi):
        traj = bd.simulate(
            scene,
            bd.State(s.g, s.q, xi, s.qdot),
            steps * dt,
            dt0=dt,
            solver=bd.RKMK4(),
            max_steps=steps,
            adjoint=diffrax.RecursiveCheckpointAdjoint(),
        )
        return jnp.sum(traj.g[-1, :3, 3] ** 2) + jnp.sum(traj.q[-1] ** 2)

    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    compiled = jax.jit(jax.grad(loss)).lower(s.xi).compile()
    analysis = compiled.memory_analysis()
    start = time.perf_counter()
    grad = jax.block_until_ready(compiled(s.xi))
    seconds = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    return {
        "steps": steps,
        "xla_temp_bytes": getattr(analysis, "temp_size_in_bytes", None),
        "peak_rss_bytes": peak,
        "rss_before_bytes": before,
        "seconds": seconds,
        "grad_finite": bool(jnp.all(jnp.isfinite(grad))),
    }


# ------------------------------------------------------------------------------- workers


def worker(ns, repeats, batch_settings, batch_t1):
    """Parts 1, 3 and 4 under this process's XLA flags (`batch_settings`: method → setting), with
    MuJoCo's side of parts 1 and 3 timed in alternation with bundledyn's."""
    import bundledyn as bd

    bd.enable_x64()
    out = {"xla_flags": os.environ.get("XLA_FLAGS", ""), "field": {}}
    for n in ns:
        out["field"][str(n)] = field_cost(n, repeats)
        print(
            f"  field n={n}: {out['field'][str(n)]['per_evaluation']['median'] * 1e6:.1f} us",
            file=sys.stderr,
            flush=True,
        )
    out["batch"], (out["mujoco_batch"],), out["mjx_batch"] = batch_throughput(
        batch_settings, batch_t1, repeats, split=(1, 2), with_mjx=True
    )
    out["compile"] = compile_costs(tuple(dict.fromkeys((5, ns[-1]))))
    return out


def run_worker(mode, args, flags):
    env = dict(os.environ, XLA_FLAGS=" ".join(flags))
    command = [sys.executable, "-m", "benchmarks.speed", f"--{mode}", *args]
    done = subprocess.run(command, env=env, cwd=ROOT, stdout=subprocess.PIPE, check=True, text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def environment():
    import importlib.metadata as md

    versions = {}
    packages = ("bundledyn", "jax", "jaxlib", "diffrax", "equinox", "numpy", "mujoco", "mujoco-mjx")
    for package in packages:
        try:
            versions[package] = md.version(package)
        except md.PackageNotFoundError:
            versions[package] = None
    cpu = platform.processor() or platform.machine()
    try:
        lines = pathlib.Path("/proc/cpuinfo").read_text().splitlines()
        cpu = next(line.split(":", 1)[1].strip() for line in lines if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return {
        "date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": f"{cpu}, {len(os.sched_getaffinity(0))} cores",
        "loadavg": os.getloadavg(),
        "python": platform.python_version(),
        "versions": versions,
    }


# ------------------------------------------------------------------------------- report


def targets(report):
    """Each target of the speed issue: (what, measured, limit, met)."""
    ours = report["settings"]["bundledyn"]
    fields = ours["field"]
    rows = []
    for n in fields:
        ratio = fields[n]["per_evaluation"]["median"] / fields[n]["mj_forward"]["median"]
        rows.append((f"vector field / mj_forward, n = {n}", ratio, 5.0))
    ns = list(fields)
    growth = fields[ns[-1]]["per_evaluation"]["median"] / fields[ns[1]]["per_evaluation"]["median"]
    rows.append((f"field cost growth n = {ns[1]} → {ns[-1]}", growth, int(ns[-1]) / int(ns[1])))
    chain = report["chain"]
    mj_coarse = chain["MuJoCo RK4"][0]
    t_mj = time_at_error(chain["MuJoCo RK4"], TARGET_ERROR)
    for method in METHODS:
        label = f"{method} (default)" if method == next(iter(METHODS)) else method
        t_bd = time_at_error(chain[method], mj_coarse["error"])
        if t_bd is not None:
            rows.append(
                (
                    f"10 s chain at MuJoCo RK4 dt = 1e-2 error ({mj_coarse['error']:.1e}): "
                    f"{label} / MuJoCo time",
                    t_bd / mj_coarse["time"]["median"],
                    1.0,
                )
            )
        t_bd = time_at_error(chain[method], TARGET_ERROR)
        if t_bd is not None and t_mj is not None:
            rows.append((f"10 s chain at error 1e-10: {label} / MuJoCo RK4 time", t_bd / t_mj, 0.5))
    mjb, mjx = ours["mujoco_batch"], fastest_mjx(report)
    for method, batch in ours["batch"].items():
        rows.append(
            (
                f"batch {BATCH}: MuJoCo rollout (2 threads) / bundledyn vmap ({method}) rollouts per s",
                mjb["rollouts_per_second"] / batch["rollouts_per_second"],
                1.0,
            )
        )
        if mjx is not None:
            rows.append(
                (
                    f"batch {BATCH} at equal accuracy: 10 × MJX ({mjx['label']}, dt = "
                    f"{mjx['dt']:.1e}) / bundledyn vmap ({method}) rollouts per s",
                    10 * mjx["rollouts_per_second"] / batch["rollouts_per_second"],
                    1.0,
                )
            )
    last = ns[-1]
    rows.append(
        (f"compile simulate, n = {last} [s]", ours["compile"][last]["simulate"]["total"], 10.0)
    )
    rows.append(
        (
            f"compile jax.grad(simulate), n = {last} [s]",
            ours["compile"][last]["grad"]["total"],
            30.0,
        )
    )
    rows.append(("jax.grad / forward, 10 s rollout", report["gradient"]["ratio"], 4.0))
    memory = report["memory"]
    rows.append(
        (f"gradient memory, {memory['steps']:.0e} steps [GB]", memory["peak_rss_bytes"] / 1e9, 2.0)
    )
    return [(what, value, limit, value <= limit) for what, value, limit in rows]


def fastest_mjx(report):
    """MJX's batch at equal accuracy under the XLA flags where it ran fastest: its
    `rollouts_per_second` at the step `dt` of part 3's calibration, from the instance-steps
    per second measured at dt = 1e-2 (no contacts: a step's work does not depend on dt),
    and the flags' `label`. None where MJX was not measured or no step reached the error."""
    mjx = report["batch_calibration"].get("mjx")
    if not mjx or not mjx["at_target"]:
        return None
    steps = mjx["at_target"]["steps"]
    runs = [
        {
            "label": label,
            "dt": mjx["at_target"]["dt"],
            "rollouts_per_second": report["settings"][key]["mjx_batch"]["instance_steps_per_second"]
            / steps,
        }
        for key, label in XLA_SETTINGS.items()
        if report["settings"][key].get("mjx_batch")
    ]
    return max(runs, key=lambda m: m["rollouts_per_second"], default=None)


def fmt(stats, scale, digits=3):
    return f"{stats['median'] * scale:.{digits}g} ({stats['min'] * scale:.{digits}g}–{stats['max'] * scale:.{digits}g})"


def measured(report, where):
    """The opening sentence of a report: when, where, which versions, how many repeats."""
    env = report["environment"]
    return (
        f"Measured {env['date']} on {where} (load average at start "
        + ", ".join(f"{x:.2f}" for x in env["loadavg"])
        + f"), Python {env['python']}; "
        + ", ".join(f"{k} {v}" for k, v in env["versions"].items() if v)
        + f". {report['repeats']} repeats; times are median (min–max)."
    )


def mjx_sentence(report):
    """Part 3's note on MJX: what ran, its errors over the step, the step at equal accuracy."""
    cal = report["batch_calibration"]
    mjx = cal.get("mjx")
    if not mjx:
        return (
            "MJX was not measured: `mujoco.mjx` is not installed here (`pip install "
            "mujoco-mjx`, in the `bench` extra)."
        )
    coarse, fine = mjx["points"][0], mjx["points"][-1]
    order = math.log(coarse["error"] / fine["error"]) / math.log(coarse["dt"] / fine["dt"])
    matched = mjx["at_target"]
    version = report["environment"]["versions"].get("mujoco-mjx")
    text = (
        f"MJX (`mujoco-mjx` {version}): `jax.vmap` of `mjx.step` (RK4) over the same {BATCH} "
        "initial states as MuJoCo's, timed at dt = 1e-2 in alternation with bundledyn in each "
        f"worker. Its largest error over the {cal['members']} calibration rollouts: "
        + ", ".join(f"{p['error']:.2g} at dt = {p['dt']:.1e}" for p in mjx["points"])
        + f" (order {order:.1f}; MuJoCo's C RK4 {cal['mujoco_error']:.2g} at dt = 1e-2)."
    )
    if matched is None:
        return text + " No step tried reached MuJoCo's error, so there is no target row."
    return text + (
        f" At equal accuracy MJX takes dt = {matched['dt']:.1e}, {matched['steps']} steps per "
        "rollout: the target divides its instance-steps per second at dt = 1e-2 (no contacts, "
        "so a step's work does not depend on dt) by that, under the XLA flags where MJX ran "
        "faster. At dt = 1e-2 (less accurate than bundledyn's batch) its rollouts per second "
        "are in the table."
    )


def batch_cells(b, method):
    """Time per batch, rollouts/s and instance-steps/s of one bundledyn batch of `method`
    (a name in `METHODS`; part 3)."""
    return (
        f"{fmt(b['time'], 1)} | {b['rollouts_per_second']:.3g} "
        f"| {b['rollouts_per_second'] * b['mean_steps']:.3g} "
        f"({METHODS[method][1]}, {b['mean_steps']:.0f} steps each)"
    )


def markdown(report):
    env = report["environment"]
    settings = report["settings"]
    lines = [
        "# Speed against MuJoCo",
        "",
        measured(report, env["machine"]) + " Same MJCF model "
        "(`benchmarks/speed.py: chain_mjcf`) in both simulators, float64, CPU.",
        "",
        "## Targets",
        "",
        "| target | measured | limit | met | by how much |",
        "|---|--:|--:|:-:|--:|",
    ]
    for what, value, limit, met in targets(report):
        miss = "" if met else f"{value / limit:.2g}× over"
        lines.append(f"| {what} | {value:.3g} | {limit:.3g} | {'yes' if met else 'no'} | {miss} |")
    lines += [
        "",
        "## 1. One vector-field evaluation [µs]",
        "",
        "Each bundledyn column is timed in alternation with `mj_forward`, in the same worker.",
        "",
        "| n | bundledyn, CPU_XLA_FLAGS | mj_forward | bundledyn, XLA defaults | mj_forward "
        "| MuJoCo RK4 step | ratio to mj_forward (CPU_XLA_FLAGS) |",
        "|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for n, mj in report["mujoco_field"].items():
        ours, default = settings["bundledyn"]["field"][n], settings["xla_defaults"]["field"][n]
        lines.append(
            f"| {n} | {fmt(ours['per_evaluation'], 1e6)} | {fmt(ours['mj_forward'], 1e6)} "
            f"| {fmt(default['per_evaluation'], 1e6)} | {fmt(default['mj_forward'], 1e6)} "
            f"| {fmt(mj['rk4_step'], 1e6)} "
            f"| {ours['per_evaluation']['median'] / ours['mj_forward']['median']:.2g} |"
        )
    chain = report["chain"]
    lines += [
        "",
        f"## 2. {chain['t1']:g} s of the 5-body chain",
        "",
        f"Reference: RKMK87 at rtol 1e-13; diffrax Dopri8 at rtol 1e-13 agrees to "
        f"{chain['reference_agreement']:.1e}. Error: max over the pose (log of the relative "
        "pose), q, ξ and q̇ at t1.",
        "",
        "| method | setting | steps | error | time [ms] |",
        "|---|--:|--:|--:|--:|",
    ]
    for method in (*METHODS, "MuJoCo RK4"):
        for p in chain[method]:
            lines.append(
                f"| {method} | {setting_label(method, p['setting'])} | {p['steps']} "
                f"| {p['error']:.2e} | {fmt(p['time'], 1e3)} |"
            )
    mjb = settings["bundledyn"]["mujoco_batch"]
    cal = report["batch_calibration"]
    lines += [
        "",
        f"## 3. Batches of {BATCH} (5-body chain, 1 s)",
        "",
        "bundledyn: `jax.vmap(simulate)`, each method at the loosest tolerance (rtol at 1, 2 "
        "and 5 per decade) or longest fixed step whose largest final-state error over "
        f"{cal['members']} rollouts of the batch (against RKMK87 at rtol 1e-13) is at most "
        f"MuJoCo RK4's with dt = 1e-2 on the same rollouts, {cal['mujoco_error']:.2g}: "
        + ", ".join(
            f"{m} {setting_label(m, c['setting'])} "
            f"({next(p['error'] for p in c['points'] if p['setting'] == c['setting']):.2g})"
            for m, c in cal["methods"].items()
        )
        + ". Adaptive members of a `vmap`ped batch step in lockstep until the last is done; "
        "fixed steps are the same for all. "
        f"MuJoCo: `mujoco.rollout`, RK4, dt = 1e-2, {mjb['threads']} threads, timed in "
        "alternation with bundledyn in each worker. “2 threads”: the batch in two halves, "
        "each a `jax.vmap`, run at once from two Python threads (XLA's CPU runtime runs one "
        "program mostly on one core).",
        "",
        "| simulator | time per batch [s] | rollouts/s | instance-steps/s |",
        "|---|--:|--:|--:|",
    ]
    for key, label in XLA_SETTINGS.items():
        for method, b in settings[key]["batch"].items():
            setting = setting_label(b["method"], b["setting"])
            cells = batch_cells(b, b["method"])
            lines.append(f"| bundledyn {method}, {setting}, {label} | {cells} |")
        m = settings[key]["mujoco_batch"]
        lines.append(
            f"| MuJoCo rollout, beside {label} | {fmt(m['time'], 1)} "
            f"| {m['rollouts_per_second']:.3g} | {m['instance_steps_per_second']:.3g} |"
        )
        m = settings[key].get("mjx_batch")
        if m:
            lines.append(
                f"| MJX, dt = 1e-2, beside {label} (compile {m['compile']:.0f} s) "
                f"| {fmt(m['time'], 1)} "
                f"| {m['rollouts_per_second']:.3g} | {m['instance_steps_per_second']:.3g} |"
            )
    lines += ["", mjx_sentence(report)]
    lines += [
        "",
        "## 4. Compile times [s] (tracing and lowering + XLA)",
        "",
        "| n | what | CPU_XLA_FLAGS | XLA defaults |",
        "|--:|---|--:|--:|",
    ]
    for n, row in settings["bundledyn"]["compile"].items():
        for what, c in row.items():
            d = settings["xla_defaults"]["compile"][n][what]
            lines.append(
                f"| {n} | {what} | {c['trace_and_lower']:.1f} + {c['xla']:.1f} "
                f"| {d['trace_and_lower']:.1f} + {d['xla']:.1f} |"
            )
    g, m = report["gradient"], report["memory"]
    lines += [
        "",
        "In one process per setting, in the order of the table: the field traced for the "
        "forward `simulate` of n = 20 is reused (not traced again) by its `jax.grad`, as in "
        "a session that runs a model before differentiating it.",
        "",
        "## 5. Gradients",
        "",
        f"- `jax.grad` of a loss on the {chain['t1']:g} s rollout (RecursiveCheckpointAdjoint): "
        f"{fmt(g['grad'], 1e3)} ms against {fmt(g['forward'], 1e3)} ms forward, "
        f"ratio {g['ratio']:.2f} (of the medians; of the minima "
        f"{g['grad']['min'] / g['forward']['min']:.2f}, less moved by the host's phases).",
        f"- {m['steps']} RKMK4 steps, gradient through all of them: peak memory of the whole "
        f"process {m['peak_rss_bytes'] / 1e9:.2f} GB ({m['rss_before_bytes'] / 1e9:.2f} GB "
        "before compiling the gradient: imports and JAX's runtime), XLA temporary buffers "
        f"{(m['xla_temp_bytes'] or 0) / 1e6:.2f} MB, {m['seconds']:.1f} s, gradient finite: "
        f"{m['grad_finite']}.",
    ]
    return "\n".join(lines + baseline_lines(g) + gradient_profile_lines(report)) + "\n"


def baseline_lines(g):
    """Part 5a's baselines in markdown (none in results written before 2026-11-24 10:00)."""
    if "baselines" not in g:
        return []
    rows = []
    for depth, b in g["baselines"].items():
        ratio = b["grad"]["median"] / b["forward"]["median"]
        what = "linear, $L = 1$" if depth == "1" else f"$L = {depth}$"
        rows.append(
            f"| {what} | {fmt(b['field'], 1e6)} | {b['field_vjp']['median'] / b['field']['median']:.1f} "
            f"| {fmt(b['forward'], 1e3)} | {fmt(b['grad'], 1e3)} | {ratio:.2f} "
            f"| {b['grad']['min'] / b['forward']['min']:.2f} |"
        )
    return [
        "",
        "Baselines, timed in alternation with the two above: diffrax's own `Dopri8` over the "
        "same time at the same tolerance on $\\dot y = K_L\\tanh(K_{L-1}\\cdots\\tanh(K_1 y))$, "
        "$K_l$ fixed skew 30×30 matrices (`skew_network_ode`), whose VJP costs little more "
        "than the field: what diffrax's adjoint loop costs with a cheap reverse pass.",
        "",
        "| field | evaluation [µs] | VJP / evaluation | forward [ms] | `jax.grad` [ms] "
        "| ratio | ratio of the minima |",
        "|---|--:|--:|--:|--:|--:|--:|",
        *rows,
    ]


def gradient_profile_lines(report):
    """Part 5c's markdown: the units' costs and the gradient of part 5a accounted by them."""
    g = report["gradient"]
    p = g["profile"]
    med = {k: p[k]["median"] for k in ("field", "field_vjp", "step", "step_vjp")}
    forward, grad = g["forward"]["median"], g["grad"]["median"]
    steps, vjps = p["steps"], p["steps"] * med["step_vjp"]
    rest = (
        ": the rest is diffrax recomputing steps from its checkpoints"
        if forward + vjps < grad
        else " (alone, a step's VJP costs more than inside the solve)"
    )
    return [
        "",
        "### Where the gradient's time goes",
        "",
        "Per call in a compiled loop, 5-body chain [µs], timed in alternation with the "
        f"gradient above; the step is `RKMK87`'s ({p['stages']} field evaluations) at the "
        "forward solve's mean step.",
        "",
        "| unit | evaluation | VJP | VJP / evaluation |",
        "|---|--:|--:|--:|",
        # Results before 2026-11-24 timed `Scene.vector_field` and do not name the unit.
        f"| {p.get('field_unit', 'vector field')} | {fmt(p['field'], 1e6)} "
        f"| {fmt(p['field_vjp'], 1e6)} "
        f"| {med['field_vjp'] / med['field']:.1f} |",
        f"| RKMK87 step | {fmt(p['step'], 1e6)} | {fmt(p['step_vjp'], 1e6)} "
        f"| {med['step_vjp'] / med['step']:.1f} |",
        "",
        f"The forward solve takes {steps} steps (accepted and rejected): at the loop's cost "
        f"per step {steps * med['step'] * 1e3:.1f} ms, against {forward * 1e3:.1f} ms "
        f"measured. The forward solve and {steps} step VJPs ({vjps * 1e3:.0f} ms) account for "
        f"{(forward + vjps) / grad:.0%} of the gradient's {grad * 1e3:.0f} ms{rest}. "
        "A step's VJP evaluates each stage's "
        "field twice before transposing it: in the step's forward pass, and again where the "
        "stage is rematerialized (`jax.checkpoint`, cheaper than storing the field's "
        "intermediates over the stages). A gradient within 4× of the forward solve would "
        f"need the {steps} step VJPs within three forward solves, each within "
        f"{3 * forward / (steps * med['step']):.1f}× the step; it costs "
        f"{med['step_vjp'] / med['step']:.1f}×, most of it the field's VJP at "
        f"{med['field_vjp'] / med['field']:.1f}× the field.",
    ]


def device_markdown(report):
    """The report of `--device-batch`: bundledyn's batches on a device, MuJoCo on its host."""
    env, rows = report["environment"], report["device_batches"]["rows"]
    (baseline,) = (m for m in rows[0]["mujoco"] if m["threads"] == 2)
    # Results written before the fixed-step method name the settings `batch_rtol`.
    batch_settings = report.get("batch_setting") or report["batch_rtol"]
    settings = ", ".join(f"{m} {setting_label(m, x)}" for m, x in batch_settings.items())
    lines = [
        f"# Batches on {report['device_batches']['device']}",
        "",
        measured(report, f"{report['device_batches']['device']}, host {env['machine']}"),
        "",
        f"bundledyn: `jax.vmap(simulate)` of {report['t1']:g} s of the 5-body chain of "
        f"`speed.md`, float64, on the device, each method at the setting of the CPU run's "
        f"part 3 ({settings}). MuJoCo: `mujoco.rollout`, RK4, dt = 1e-2, on the host's CPU, timed "
        "in alternation with bundledyn at the first batch size only (its throughput does "
        "not grow with the batch once its threads are busy). The last column divides "
        "rollouts/s by MuJoCo's on 2 threads.",
        "",
        "| batch | simulator | time per batch [s] | rollouts/s | instance-steps/s "
        "| compile [s] | × MuJoCo, 2 threads |",
        "|--:|---|--:|--:|--:|--:|--:|",
    ]
    for row in rows:
        for method, b in row["bundledyn"].items():
            lines.append(
                f"| {row['batch']} | bundledyn {method} | {batch_cells(b, method)} | {b['compile']:.1f} "
                f"| {b['rollouts_per_second'] / baseline['rollouts_per_second']:.3g} |"
            )
        for m in row["mujoco"]:
            lines.append(
                f"| {row['batch']} | MuJoCo rollout, {m['threads']} threads | {fmt(m['time'], 1)} "
                f"| {m['rollouts_per_second']:.3g} | {m['instance_steps_per_second']:.3g} | "
                f"| {m['rollouts_per_second'] / baseline['rollouts_per_second']:.3g} |"
            )
        m = row.get("mjx")
        if m:
            lines.append(
                f"| {row['batch']} | MJX, dt = 1e-2 | {fmt(m['time'], 1)} "
                f"| {m['rollouts_per_second']:.3g} | {m['instance_steps_per_second']:.3g} "
                f"| {m['compile']:.1f} | {m['rollouts_per_second'] / baseline['rollouts_per_second']:.3g} |"
            )
    lines.append("")
    matched = report.get("mjx_at_equal_accuracy")
    if matched and any(row.get("mjx") for row in rows):
        steps = round(report["t1"] / matched["dt"])
        lines += [
            "MJX on the device at dt = 1e-2 is less accurate than the others; at equal accuracy "
            f"it takes dt = {matched['dt']:.1e} (from the CPU run's calibration), {steps} steps "
            f"per rollout, so its rollouts/s there are its instance-steps/s over {steps}: "
            + ", ".join(
                f"{r['mjx']['instance_steps_per_second'] / steps:.3g} at batch {r['batch']}"
                for r in rows
                if r.get("mjx")
            )
            + ".",
            "",
        ]
    for method, a in report["device_batches"]["agreement_with_cpu"].items():
        lines.append(
            f"- {method}: the first {a['batch']} rollouts, run again on the host's CPU, end "
            f"in poses that differ by at most {a['max_pose_difference']:.1e} from the "
            f"device's; same step counts: {'yes' if a['same_steps'] else 'no'}."
        )
    return "\n".join(lines) + "\n"


def device_batch_main(args, repeats):
    """`--device-batch`: part 3 on JAX's default device at the CPU run's tolerances."""
    import jax

    import bundledyn as bd

    bd.enable_x64()
    cpu = json.loads((args.out / "speed.json").read_text())
    sizes = (256, 1024) if args.quick else DEVICE_BATCHES
    t1 = 0.2 if args.quick else 1.0
    report = {
        "environment": environment(),
        "repeats": repeats,
        "t1": t1,
        "batch_setting": cpu["batch_setting"],
        "mjx_at_equal_accuracy": (cpu["batch_calibration"].get("mjx") or {}).get("at_target"),
        "device_batches": device_batches(sizes, cpu["batch_setting"], t1, repeats),
    }
    text = device_markdown(report)
    print(text)
    if not args.quick:
        name = f"speed_{jax.devices()[0].platform}"
        (args.out / f"{name}.json").write_text(json.dumps(report, indent=1) + "\n")
        (args.out / f"{name}.md").write_text(text)
    return report


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="small sizes, 2 repeats, no files")
    parser.add_argument("--repeats", type=int, help="timed repeats (default 5; quick 2)")
    parser.add_argument("--out", type=pathlib.Path, default=RESULTS, help="results folder")
    parser.add_argument(
        "--report-only", action="store_true", help="redraw speed.md from speed.json"
    )
    parser.add_argument(
        "--device-batch",
        action="store_true",
        help="part 3 only, on JAX's default device (a GPU), at the settings of --out's "
        "speed.json; writes speed_<platform>.{md,json}",
    )
    parser.add_argument("--worker", nargs=4, help=argparse.SUPPRESS)
    parser.add_argument("--memory", nargs=1, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    repeats = args.repeats or (2 if args.quick else 5)
    if args.worker:
        ns = [int(n) for n in args.worker[0].split(",")]
        batch_settings, t1 = json.loads(args.worker[2]), float(args.worker[3])
        print(json.dumps(worker(ns, int(args.worker[1]), batch_settings, t1)))
        return 0
    if args.memory:
        import bundledyn as bd

        bd.enable_x64()
        print(json.dumps(gradient_memory(int(args.memory[0]))))
        return 0
    if args.report_only:
        report = json.loads((args.out / "speed.json").read_text())
        (args.out / "speed.md").write_text(markdown(report))
        for path in args.out.glob("speed_*.json"):
            path.with_suffix(".md").write_text(device_markdown(json.loads(path.read_text())))
        return 0
    if args.device_batch:
        return device_batch_main(args, repeats)

    import bundledyn as bd

    bd.use_cpu_xla_flags()
    bd.enable_x64()
    try:
        import mujoco  # noqa: F401
    except ImportError:
        print("mujoco is not installed (pip install '.[bench]'): nothing to compare against")
        return 1
    ns = (1, 2, 5) if args.quick else (1, 5, 10, 20)
    report = {"environment": environment(), "repeats": repeats, "quick": args.quick}
    print("part 2: chain", flush=True)
    report["chain"] = chain_ten_seconds(repeats, args.quick)
    batch_t1 = 0.2 if args.quick else 1.0
    print("part 3: batch settings", flush=True)
    report["batch_calibration"] = batch_calibration(batch_t1, args.quick)
    report["batch_setting"] = {
        method: c["setting"] for method, c in report["batch_calibration"]["methods"].items()
    }
    print("part 1: MuJoCo", flush=True)
    report["mujoco_field"] = {str(n): mujoco_rk4_step(n, repeats) for n in ns}
    print("part 5: gradients", flush=True)
    report["gradient"] = gradient_cost(repeats, report["chain"]["t1"])
    steps = 1000 if args.quick else MEMORY_STEPS
    report["memory"] = run_worker("memory", [str(steps)], bd.CPU_XLA_FLAGS)
    report["settings"] = {}
    for key, flags in (("bundledyn", bd.CPU_XLA_FLAGS), ("xla_defaults", ())):
        print(f"parts 1, 3, 4 with {key}", flush=True)
        worker_args = [
            ",".join(map(str, ns)),
            str(repeats),
            json.dumps(report["batch_setting"]),
            str(batch_t1),
        ]
        report["settings"][key] = run_worker("worker", worker_args, flags)
    text = markdown(report)
    print(text)
    if not args.quick:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "speed.json").write_text(json.dumps(report, indent=1) + "\n")
        (args.out / "speed.md").write_text(text)
    return report


if __name__ == "__main__":
    main()
