"""Part 2: 10 s of the 5-body chain, bundledyn's solvers and MuJoCo RK4 over their
settings, errors against a reference and times in alternation."""

import jax

from benchmarks._errors import state_error
from benchmarks._models import chain_scene, initial_state, mujoco_model
from benchmarks._mujoco import rollout_final_state
from benchmarks._timing import blocking, interleaved
from benchmarks.speed.config import FIXED_STEPS, METHODS, MUJOCO_DT, T_CHAIN, rollout_fn


def chain_ten_seconds(repeats, quick):
    """Part 2: bundledyn's solvers and MuJoCo RK4 on 10 s of the 5-body chain, errors vs a reference."""
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
        model = mujoco_model(5, dt)
        final, samplers["MuJoCo RK4", dt] = rollout_final_state(model, t1, scene.system, state)
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
