"""One model's solve at equal error: bundledyn's default solver over a sweep of
tolerances against MuJoCo's RK4 at dt = 1e-4, both judged against RK4 at an eighth of
that step, and timed in alternation.

RK4 at dt/8 is 8^4 = 4096 times more accurate than at dt, so it resolves the error RK4
makes at dt; bundledyn's time to that error is interpolated log–log between the two
tolerances that bracket it (`family.measure.time_to_reach`). Where RK4's error is below
`ROUNDING`, both solves are exact to rounding and the target is `ROUNDING` itself: below
it, a 1 s solve's accumulated rounding, not its method, sets the error."""

import time

import diffrax
import jax
import jax.numpy as jnp
import numpy as np

import bundledyn as bd
from benchmarks._timing import blocking, interleaved
from benchmarks.family.measure import time_to_reach

TOLERANCES = (1e-6, 1e-8, 1e-10, 1e-12, 1e-13)  # rtol = atol, loosest first
SURVEYED = 1e-12  # the tolerance whose final state the survey compares with MuJoCo's
ROUNDING = 1e-12


def tolerance_run(scene, t1):
    """A jitted `(state, tolerance) -> (final state, steps)` of `bd.simulate` at rtol =
    atol = tolerance (traced: one compilation for the sweep). A solve that spends its step
    budget ends in a NaN state, as far from the reference as can be."""

    @jax.jit
    def run(state, tolerance):
        traj = bd.simulate(
            scene, state, t1, rtol=tolerance, atol=tolerance, max_steps=200_000, throw=False
        )
        failed = traj.result != diffrax.RESULTS.successful
        parts = (traj.g[-1], traj.q[-1], traj.xi[-1], traj.qdot[-1])
        end = bd.State(*(jnp.where(failed, jnp.nan, x) for x in parts))
        return end, traj.stats["num_steps"]

    return run


def sweep(run, state, to_mujoco, error_of):
    """Each tolerance's point `{"setting", "error", "steps"}` (the error by `error_of` of
    MuJoCo's `(qpos, qvel)` of the final state, `to_mujoco`), a sampler of its solve, and
    the seconds of the first call (compiling)."""
    points, samplers, first = [], {}, None
    for tolerance in TOLERANCES:
        began = time.perf_counter()
        end, steps = jax.block_until_ready(run(state, tolerance))
        first = time.perf_counter() - began if first is None else first
        error = error_of(to_mujoco(end)) if np.all(np.isfinite(np.asarray(end.q))) else np.inf
        points.append({"setting": tolerance, "error": float(error), "steps": int(steps)})
        samplers[tolerance] = blocking(run, state, tolerance)
    return points, samplers, first


def equal_error(points, mujoco_point):
    """bundledyn's time to MuJoCo RK4's error (at least `ROUNDING`) over MuJoCo's time:
    infinite where the sweep does not reach that error."""
    ours = time_to_reach(points, max(mujoco_point["error"], ROUNDING))
    return float("inf") if ours is None else ours / mujoco_point["time"]["median"]


def timed_sweep(run, state, to_mujoco, error_of, mujoco_sampler, mujoco_error, repeats):
    """The sweep's points and MuJoCo RK4's, timed in alternation, and the ratio at equal
    error: `{"points", "mujoco", "ratio", "first_call"}`."""
    points, samplers, first = sweep(run, state, to_mujoco, error_of)
    timed = interleaved(samplers | {"mujoco": mujoco_sampler}, repeats)
    for point in points:
        point["time"] = timed[point["setting"]][1]
    mujoco_point = {"error": mujoco_error, "time": timed["mujoco"][1]}
    ratio = equal_error(points, mujoco_point)
    return {"points": points, "mujoco": mujoco_point, "ratio": ratio, "first_call": first}
