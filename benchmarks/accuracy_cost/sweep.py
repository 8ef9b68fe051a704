"""Every method swept over its tolerances or steps on one problem, against a reference."""

import dataclasses
import time
from collections.abc import Callable

import diffrax
import jax
import jax.numpy as jnp

import bundledyn as bd
from benchmarks._errors import final_state, state_error
from benchmarks._timing import timed
from benchmarks.accuracy_cost.problems import Problem
from bundledyn._simulate import DEFAULT_SOLVER

MAX_STEPS = 200_000
REFERENCE_RTOL = 1e-13
FULL_RTOLS = tuple(10.0**-k for k in range(3, 13))
FULL_STEPS = (25, 50, 100, 200, 400, 800, 1600)  # steps over [0, t1] for fixed-step methods
QUICK_RTOLS = (1e-5, 1e-7, 1e-9, 1e-11)  # three within digits.ERROR_CEILING: a cost per digit
QUICK_STEPS = (50, 200, 800)


@dataclasses.dataclass(frozen=True)
class Method:
    name: str
    make: Callable
    fixed: bool
    stages: int  # vector-field evaluations per step (nominal; FSAL counted once)
    family: str
    tightest: float = 0.0  # no adaptive setting below this is swept


METHODS = {
    "LieEuler": Method("LieEuler", bd.LieEuler, True, 1, "Lie group"),
    "RKMK4": Method("RKMK4", bd.RKMK4, True, 4, "Lie group"),
    "RKMK54": Method("RKMK54", bd.RKMK54, False, 7, "Lie group"),
    # 13 of its 14 stages: saving only at t1, `simulate` skips the dense output's stage.
    "RKMK87": Method("RKMK87", bd.RKMK87, False, 13, "Lie group"),
    "VariationalMidpoint": Method(
        "VariationalMidpoint", bd.VariationalMidpoint, True, 8, "Lie group"
    ),
    "Tsit5": Method("Tsit5", diffrax.Tsit5, False, 6, "embedded"),
    "Dopri5": Method("Dopri5", diffrax.Dopri5, False, 6, "embedded"),
    "Dopri8": Method("Dopri8", diffrax.Dopri8, False, 12, "embedded"),
    # An implicit step costs a Newton solve per stage: 19 s per solve at rtol 1e-10 on the
    # stiff chain, so its sweep stops at 1e-9.
    "Kvaerno5": Method("Kvaerno5", diffrax.Kvaerno5, False, 7, "embedded", tightest=1e-9),
}


def default_solver():
    """The solver class `bd.simulate` integrates with when given none."""
    return DEFAULT_SOLVER


def methods_for(problem: Problem, quick: bool, default: str):
    """The methods swept on `problem`, `default` (the library's default solver) first."""
    if quick:
        names = ["RKMK54", "RKMK4", "Tsit5"]
    else:
        names = ["LieEuler", "RKMK4", "RKMK54", "Tsit5", "Dopri5", "Dopri8"]
        if isinstance(problem.scene.shape, bd.Free) and problem.scene.system.shape_dim:
            names.insert(3, "VariationalMidpoint")
        if problem.stiff:
            names.append("Kvaerno5")
    return [default, *(name for name in names if name != default)]


def _drift(series, relative):
    change = jnp.max(jnp.abs(series[-1] - series[0]))
    size = jnp.max(jnp.abs(series[0]))
    return change / size if relative else change


def make_solve(problem: Problem, method: Method):
    """A jitted `setting -> (final state, energy drift, momentum drift, steps, success)`."""

    @jax.jit
    def solve(setting):
        if method.fixed:
            options = dict(dt0=setting)
        else:
            options = dict(rtol=setting, atol=setting * problem.atol_ratio)
        if method.name == "Kvaerno5":
            options["dt0"] = 1e-4  # the implicit method's first Newton solve needs a small step
        traj = bd.simulate(
            problem.scene,
            problem.state,
            problem.t1,
            solver=method.make(),
            max_steps=MAX_STEPS,
            throw=False,
            **options,
        )
        energy = _drift(traj.energy(), True) if problem.energy else jnp.nan
        momentum = _drift(traj.spatial_momentum(), bool(problem.momentum))
        ok = traj.result == diffrax.RESULTS.successful
        return final_state(traj), energy, momentum, traj.stats["num_steps"], ok

    return solve


def reference(problem: Problem):
    """RKMK 5(4) and Dopri8 at the tightest tolerance; their difference is the error floor."""
    states = []
    for name in ("RKMK54", "Dopri8"):
        state, *_rest, ok = make_solve(problem, METHODS[name])(jnp.asarray(REFERENCE_RTOL))
        if not bool(ok):
            raise RuntimeError(f"the {name} reference of {problem.name} did not finish")
        states.append(state)
    return states[0], state_error(states[0], states[1])


def _compile(solve, setting):
    """Seconds to compile `solve`, which `jax.jit` then reuses: timed apart from the runs,
    since a first setting whose solve raises would take its compile time with it."""
    start = time.perf_counter()
    solve.lower(jnp.asarray(setting)).compile()
    return time.perf_counter() - start


def _measured(method: Method, setting, out, runs, ref):
    """A sweep point from a solve's output `out` and the summary of its `runs`."""
    state, energy, momentum, steps, ok = out
    steps = int(steps)
    return {
        "setting": setting,
        "ok": bool(ok),
        "error": state_error(state, ref) if bool(ok) else float("nan"),
        "energy_drift": float(energy),
        "momentum_drift": float(momentum),
        "steps": steps,
        "evaluations": steps * method.stages,
        "time": runs,
    }


def _raised(setting, error):
    """A sweep point whose solve raised, with the message of the check that stopped it
    (equinox's, inside the compiled solve) or else the error's first line."""
    lines = str(error).splitlines()
    check = (line.split(": ", 1)[1] for line in lines if "EquinoxRuntimeError: " in line)
    return {"setting": setting, "ok": False, "error": float("nan"), "raised": next(check, lines[0])}


def _log(problem: Problem, method: Method, point):
    setting = f"{'dt' if method.fixed else 'rtol'}={point['setting']:8.1e}"
    if "raised" in point:
        outcome = f"raised: {point['raised']}"
    else:
        outcome = (
            f"error={point['error']:8.1e} time={point['time']['median'] * 1e3:9.2f} ms "
            f"steps={point['steps']}"
        )
    print(f"  {problem.name:16} {method.name:19} {setting} {outcome}", flush=True)


def sweep(problem: Problem, method: Method, ref, quick: bool, repeats: int):
    """`method`'s series on `problem`: a point per tolerance (adaptive) or step (fixed)."""
    if method.fixed:
        settings = [problem.t1 / n for n in (QUICK_STEPS if quick else FULL_STEPS)]
    else:
        settings = [r for r in (QUICK_RTOLS if quick else FULL_RTOLS) if r >= method.tightest]
    solve = make_solve(problem, method)
    compile_time = _compile(solve, settings[0])
    points = []
    for setting in settings:
        try:
            out, _, runs = timed(solve, jnp.asarray(setting), repeats=repeats)
            point = _measured(method, setting, out, runs, ref)
        except jax.errors.JaxRuntimeError as error:
            # A fixed step too long for the scene: the state blows up, and bundledyn raises
            # where its field stops being finite (`AbstractRKMK`), `throw=False` or not.
            point = _raised(setting, error)
        points.append(point)
        _log(problem, method, point)
    return {
        "method": method.name,
        "family": method.family,
        "fixed": method.fixed,
        "order": method.make().order(None),  # the order the solver class declares
        "compile": compile_time,
        "points": points,
    }
