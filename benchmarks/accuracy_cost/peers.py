"""Peers on the chain: MuJoCo's integrators on the same MJCF model, and scipy's DOP853 on
bundledyn's jitted vector field."""

import time

import jax
import jax.numpy as jnp
import numpy as np

import bundledyn as bd
from benchmarks._errors import state_error
from benchmarks._mujoco import final_state, physics_state
from benchmarks._timing import summary
from benchmarks.accuracy_cost.problems import Problem


def _series(label, fixed, order, points):
    return {
        "method": label,
        "family": "peer",
        "fixed": fixed,
        "order": order,
        "compile": 0.0,
        "points": points,
    }


def _log(problem, label, what, point):
    print(
        f"  {problem.name:16} {label:19} {what}={point['setting']:8.1e} "
        f"error={point['error']:8.1e} time={point['time']['median'] * 1e3:9.2f} ms",
        flush=True,
    )


def mujoco_peer(problem: Problem, ref, repeats: int, steps_list):
    """MuJoCo's RK4, Euler and implicitfast on chain5.xml (gravity off), in C through
    `mujoco.rollout`, over numbers of steps `steps_list`."""
    try:
        import mujoco
        from mujoco import rollout
    except ImportError:
        print("  mujoco is not installed: MuJoCo peers skipped (pip install '.[bench]')")
        return []
    model = mujoco.MjModel.from_xml_path(str(bd.models / "chain5.xml"))
    model.opt.gravity[:] = 0.0
    system = problem.scene.system
    data, initial = physics_state(model, system, problem.state)
    results = []
    for label, integrator, order in (
        ("MuJoCo RK4", mujoco.mjtIntegrator.mjINT_RK4, 4),
        ("MuJoCo Euler", mujoco.mjtIntegrator.mjINT_EULER, 1),
        ("MuJoCo implicitfast", mujoco.mjtIntegrator.mjINT_IMPLICITFAST, 1),
    ):
        model.opt.integrator = integrator
        stages = 4 if integrator == mujoco.mjtIntegrator.mjINT_RK4 else 1
        points = []
        for n in steps_list:
            model.opt.timestep = problem.t1 / n
            runs = []
            for _ in range(repeats + 1):
                start = time.perf_counter()
                states, _ = rollout.rollout(model, data, initial[None], nstep=n)
                runs.append(time.perf_counter() - start)
            end = final_state(model, system, states)
            points.append(
                {
                    "setting": problem.t1 / n,
                    "ok": True,
                    "error": state_error(end, ref),
                    "steps": n,
                    "evaluations": n * stages,
                    "time": summary(runs[1:]),
                }
            )
            _log(problem, label, "dt", points[-1])
        results.append(_series(label, True, order, points))
    return results


def scipy_peer(problem: Problem, ref, repeats: int, rtols):
    """scipy's DOP853 on bundledyn's jitted vector field (`bd.SceneTerm.vf` on the
    flattened 4×4 pose and the rest of the integration state), over `rtols`."""
    try:
        from scipy.integrate import DOP853, solve_ivp
    except ImportError:
        print("  scipy is not installed: the DOP853 peer is skipped")
        return []
    term = bd.SceneTerm(problem.scene)
    g0, x0 = term.encode(0.0, problem.state)

    @jax.jit
    def field(t, y):
        gdot, xdot = term.vf(t, (y[:16].reshape(4, 4), y[16:]), None)
        return jnp.concatenate([gdot.reshape(-1), xdot])

    y0 = np.concatenate([np.asarray(g0).reshape(-1), np.asarray(x0)])

    def fn(t, y):
        return np.asarray(field(t, y))

    def solve(rtol):
        return solve_ivp(
            fn, (0.0, problem.t1), y0, method="DOP853", rtol=rtol, atol=rtol * problem.atol_ratio
        )

    # Compiles the field for the arguments solve_ivp passes. A call with the Python float 0.0
    # compiles for a weakly typed t, and solve_ivp's NumPy t then compiled again inside the
    # first timed solve (2.2 s of the 2026-11-22 run's rtol 1e-4 maximum).
    solve(rtols[0])
    points = []
    for rtol in rtols:
        runs = []
        for _ in range(repeats):
            start = time.perf_counter()
            sol = solve(rtol)
            runs.append(time.perf_counter() - start)
        y = sol.y[:, -1]
        g = bd.project_to_se3(jnp.asarray(y[:16].reshape(4, 4)))
        end = term.decode(problem.t1, (g, jnp.asarray(y[16:])))
        points.append(
            {
                "setting": rtol,
                "ok": bool(sol.success),
                "error": state_error(end, ref),
                "steps": int(sol.t.size - 1),
                "evaluations": int(sol.nfev),
                "time": summary(runs),
            }
        )
        _log(problem, "scipy DOP853", "rtol", points[-1])
    return [_series("scipy DOP853", False, DOP853.order, points)]
