"""What accuracy costs in time: work–precision of every solver, with peers measured in the same run.

For six scenes (a Dzhanibekov rigid body, the free MJCF chain `chain5.xml`, an affine
body on a shape spring, the falling cat with a prescribed shape loop, a 10-body chain in
a gravity gradient, and a stiff chain whose spring is 10⁶ times stiffer than its soft one)
this script sweeps every method over its tolerances (adaptive) or step sizes (fixed) and
records, for each point: the error of the state at t1 against a reference solution, the
energy and momentum drift, the wall time (median, min and max of ≥ 5 runs after
compilation), the steps and vector-field evaluations, and the compile time.

The reference is RKMK 5(4) at rtol 1e-13; a second reference, Dopri8 on the embedded
state at rtol 1e-13, must agree with it, and their difference is reported as the floor
below which errors mean nothing. The error of a state is the largest of
$|\\log(g_{\\rm ref}^{-1}g)|_\\infty$, $|q - q_{\\rm ref}|_\\infty$, $|\\xi - \\xi_{\\rm ref}|_\\infty$ and
$|\\dot q - \\dot q_{\\rm ref}|_\\infty$.

Peers on the chain, when installed (extra `bench`, i.e. `mujoco` and `scipy`): MuJoCo's
RK4, Euler and implicitfast integrators on the identical MJCF model with gravity off, run
by `mujoco.rollout` in C; and scipy's `solve_ivp(DOP853)` on bundledyn's jitted vector
field as a non-JAX baseline. Throughput of vmapped batches (1, 64, 1024), the cost of
`jax.grad` of a rollout loss under two adjoints, and compile time against the number of
bodies complete the report.

Usage, from the repository root::

    python -m benchmarks.accuracy_cost            # everything; writes benchmarks/results/
    python -m benchmarks.accuracy_cost --quick    # one scene, a few points: under a minute
    python -m benchmarks.accuracy_cost --out DIR  # write the report elsewhere
"""

import argparse
import dataclasses
import datetime
import json
import os
import pathlib
import platform
import sys
import time
import warnings
from collections.abc import Callable

import diffrax
import jax
import jax.numpy as jnp
import numpy as np

import bundledyn as bd
from benchmarks.speed import (
    chain_scene,
    state_error,
    summary,
    time_at_error as _time_at_error,
    timed,
)

jax.config.update("jax_enable_x64", True)

ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
MAX_STEPS = 200_000
ATOL_RATIO = 1e-3  # atol = rtol * ATOL_RATIO for every adaptive method
REFERENCE_RTOL = 1e-13
FULL_RTOLS = tuple(10.0**-k for k in range(3, 13))
FULL_STEPS = (25, 50, 100, 200, 400, 800, 1600)  # steps over [0, t1] for fixed-step methods
QUICK_RTOLS = (1e-4, 1e-7, 1e-10)
QUICK_STEPS = (50, 200, 800)


# ----------------------------------------------------------------------------- problems


@dataclasses.dataclass(frozen=True)
class Problem:
    """A scene, its initial state and horizon, and which invariants it has."""

    name: str
    title: str
    scene: bd.Scene
    state: bd.State
    t1: float
    energy: bool  # energy conserved (no prescribed motion, no damping)
    momentum: bool  # spatial momentum conserved (no external wrench)
    stiff: bool = False
    atol_ratio: float = ATOL_RATIO  # atol = rtol * atol_ratio


def _moving(d, xi=(0.3, 0.2, -0.4, 0.1, 0.0, 0.2), qdot=0.5, q=0.1):
    return bd.State(jnp.eye(4), q * jnp.ones(d), jnp.asarray(xi), qdot * jnp.ones(d))


def mjcf_chain():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the joint refs; handled through qpos0
        return bd.Multibody.from_mjcf(bd.models / "chain5.xml")


def dzhanibekov():
    body = bd.RigidBody(1.0, [0.0, 0.0, 0.0], np.diag([1.0, 2.0, 3.0]))
    omega = np.array([0.01, 2.0, 0.01])  # near the intermediate axis
    return Problem(
        "dzhanibekov",
        "torque-free asymmetric body near its intermediate axis (Dzhanibekov), 20 s",
        bd.Scene(body),
        bd.State(jnp.eye(4), (), jnp.concatenate([omega, jnp.zeros(3)])),
        20.0,
        True,
        True,
    )


def chain():
    system = mjcf_chain()
    return Problem(
        "chain",
        "free-floating MJCF chain (chain5.xml: hinge, ball, universal, slide, composite), 2 s",
        bd.Scene(system),
        _moving(system.shape_dim),
        2.0,
        True,
        True,
    )


def affine_spring():
    body = bd.AffineBody(3.0, 3.0 / 5.0 * np.diag([0.5**2, 0.3**2, 0.2**2]))
    scene = bd.Scene(body, (bd.ShapeSpring(40.0 * jnp.ones(6)),))
    return Problem(
        "affine_spring",
        "affine body on an isotropic shape spring, 1 s",
        scene,
        bd.State(
            jnp.eye(4),
            0.1 * jnp.arange(6.0) / 6,
            jnp.array([0.5, -0.3, 0.8, 0.1, 0.0, 0.0]),
            0.3 * jnp.ones(6),
        ),
        1.0,
        True,
        True,
    )


def falling_cat():
    half = bd.RigidBody(1.5, [0.0, 0.0, 0.0], np.diag([0.02, 0.08, 0.08]))
    offset = np.eye(4)
    offset[0, 3] = 0.5
    cat = bd.Multibody(
        half, [bd.Link(half, bd.Universal([0, 0, 1], [0, 1, 0], [-0.25, 0, 0]), 0, offset)]
    )

    def bend(t):
        phase = 2 * jnp.pi * t
        return 0.6 * jnp.array([jnp.sin(phase), 1.0 - jnp.cos(phase)])

    scene = bd.Scene(cat, shape=bd.Prescribed(bend))
    q0, qdot0 = scene.shape.at(0.0)
    state = bd.State(jnp.eye(4), q0, -bd.connection(cat, q0) @ qdot0, qdot0)
    return Problem(
        "falling_cat",
        "falling cat: prescribed shape loop at zero momentum, 1 s",
        scene,
        state,
        1.0,
        False,
        True,
    )


def gravity_gradient_chain():
    system = chain_scene(10).system
    effect = bd.GravityGradient(3.986e14, (-7.0e6, 0.0, 0.0), per_body=True)
    # Released at rest 630 km above the centre: it falls 1.6 km in 20 s while the gradient
    # (~1e-6 s⁻²) turns and stretches it. An orbital 7.5 km/s would make the Galilean
    # cancellations in (2.6)–(2.7) lose digits: RKMK54 then took 47,073 steps at rtol 1e-9.
    state = bd.State(jnp.eye(4), 0.2 * jnp.ones(9), jnp.zeros(6), 0.05 * jnp.ones(9))
    return Problem(
        "gravity_gradient",
        "10-body hinge chain falling in a central field (gravity gradient), 20 s",
        bd.Scene(system, (effect,)),
        state,
        20.0,
        True,
        False,
        # Forces in a field centred 7e6 m away carry rounding of ~1e-15 in absolute terms;
        # an atol below that makes the steps noise-limited (42,265 steps at rtol 1e-13).
        atol_ratio=1.0,
    )


def stiff_chain():
    system = chain_scene(3).system
    # Joint 1 is a spring 10⁶ times stiffer than joint 2, damped: a fast mode ~10³ times
    # faster than the slow one, decaying at ~10³ s⁻¹. It starts at rest at its equilibrium,
    # so after a short transient the motion is slow and an explicit method's step is bounded
    # by stability, not accuracy: the classic stiff case.
    effects = (bd.ShapeSpring(jnp.array([1.0e6, 1.0])), bd.ShapeDamper(jnp.array([300.0, 0.0])))
    state = bd.State(
        jnp.eye(4),
        jnp.array([0.0, 0.3]),
        jnp.array([0.3, 0.2, -0.4, 0.1, 0.0, 0.2]),
        jnp.array([0.0, 0.5]),
    )
    return Problem(
        "stiff",
        "3-body chain, one damped spring 10⁶ times stiffer than the other, 0.5 s",
        bd.Scene(system, effects),
        state,
        0.5,
        False,
        True,
        stiff=True,
    )


PROBLEMS = {
    "dzhanibekov": dzhanibekov,
    "chain": chain,
    "affine_spring": affine_spring,
    "falling_cat": falling_cat,
    "gravity_gradient": gravity_gradient_chain,
    "stiff": stiff_chain,
}


# ------------------------------------------------------------------------------ methods


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


def methods_for(problem: Problem, quick: bool):
    if quick:
        return ["RKMK54", "RKMK4", "Tsit5"]
    names = ["LieEuler", "RKMK4", "RKMK54", "Tsit5", "Dopri5", "Dopri8"]
    if isinstance(problem.scene.shape, bd.Free) and problem.scene.system.shape_dim:
        names.insert(3, "VariationalMidpoint")
    if problem.stiff:
        names.append("Kvaerno5")
    return names


# ------------------------------------------------------------------------------ running


def final_state(traj):
    return traj.g[-1], traj.q[-1], traj.xi[-1], traj.qdot[-1]


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


def sweep(problem: Problem, method: Method, ref, quick: bool, repeats: int):
    if method.fixed:
        settings = [problem.t1 / n for n in (QUICK_STEPS if quick else FULL_STEPS)]
    else:
        settings = [r for r in (QUICK_RTOLS if quick else FULL_RTOLS) if r >= method.tightest]
    solve = make_solve(problem, method)
    points, compile_time = [], None
    for setting in settings:
        out, compiled, runs = timed(solve, jnp.asarray(setting), repeats=repeats)
        compile_time = compiled if compile_time is None else compile_time
        state, energy, momentum, steps, ok = out
        steps = int(steps)
        points.append(
            {
                "setting": setting,
                "ok": bool(ok),
                "error": state_error(state, ref) if bool(ok) else float("nan"),
                "energy_drift": float(energy),
                "momentum_drift": float(momentum),
                "steps": steps,
                "evaluations": steps * method.stages,
                "time": runs,
            }
        )
        print(
            f"  {problem.name:16} {method.name:19} {'dt' if method.fixed else 'rtol'}={setting:8.1e} "
            f"error={points[-1]['error']:8.1e} time={points[-1]['time']['median'] * 1e3:9.2f} ms "
            f"steps={steps}",
            flush=True,
        )
    return {
        "method": method.name,
        "family": method.family,
        "fixed": method.fixed,
        "compile": compile_time,
        "points": points,
    }


# -------------------------------------------------------------------------------- peers


def mujoco_peer(problem: Problem, ref, repeats: int, steps_list):
    """MuJoCo's integrators on chain5.xml (gravity off), in C through `mujoco.rollout`."""
    try:
        import mujoco
        from mujoco import rollout
    except ImportError:
        print("  mujoco is not installed: MuJoCo peers skipped (pip install '.[bench]')")
        return []
    from bundledyn._systems._mujoco import mujoco_from_state, state_from_mujoco

    model = mujoco.MjModel.from_xml_path(str(bd.models / "chain5.xml"))
    model.opt.gravity[:] = 0.0
    system = problem.scene.system
    s = problem.state
    qpos, qvel = mujoco_from_state(system, s.g, s.q, s.xi, s.qdot, qpos0=model.qpos0)
    data = mujoco.MjData(model)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    data.qpos[:], data.qvel[:] = np.asarray(qpos), np.asarray(qvel)
    mujoco.mj_forward(model, data)
    initial = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, initial, spec)
    results = []
    for label, integrator in (
        ("MuJoCo RK4", mujoco.mjtIntegrator.mjINT_RK4),
        ("MuJoCo Euler", mujoco.mjtIntegrator.mjINT_EULER),
        ("MuJoCo implicitfast", mujoco.mjtIntegrator.mjINT_IMPLICITFAST),
    ):
        model.opt.integrator = integrator
        points = []
        for n in steps_list:
            model.opt.timestep = problem.t1 / n
            runs = []
            for _ in range(repeats + 1):
                start = time.perf_counter()
                states, _ = rollout.rollout(model, data, initial[None], nstep=n)
                runs.append(time.perf_counter() - start)
            end = states[0, -1]
            qpos_t1 = end[1 : 1 + model.nq]
            qvel_t1 = end[1 + model.nq : 1 + model.nq + model.nv]
            g, q, xi, qdot = state_from_mujoco(system, qpos_t1, qvel_t1, qpos0=model.qpos0)
            points.append(
                {
                    "setting": problem.t1 / n,
                    "ok": True,
                    "error": state_error((g, q, xi, qdot), ref),
                    "steps": n,
                    "evaluations": n * (4 if integrator == mujoco.mjtIntegrator.mjINT_RK4 else 1),
                    "time": summary(runs[1:]),
                }
            )
            print(
                f"  {problem.name:16} {label:19} dt={problem.t1 / n:8.1e} error={points[-1]['error']:8.1e} time={points[-1]['time']['median'] * 1e3:9.2f} ms",
                flush=True,
            )
        results.append(
            {"method": label, "family": "peer", "fixed": True, "compile": 0.0, "points": points}
        )
    return results


def scipy_peer(problem: Problem, ref, repeats: int, rtols):
    """scipy's DOP853 on bundledyn's jitted vector field (flattened 4×4 pose and x)."""
    try:
        from scipy.integrate import solve_ivp
    except ImportError:
        print("  scipy is not installed: the DOP853 peer is skipped")
        return []
    from bundledyn._simulate import initial_condition

    scene = problem.scene
    g0, x0 = initial_condition(scene, problem.state, 0.0)

    @jax.jit
    def field(t, y):
        g, x = y[:16].reshape(4, 4), y[16:]
        gdot, xdot = scene.vector_field(t, (g, x))
        return jnp.concatenate([gdot.reshape(-1), xdot])

    y0 = np.concatenate([np.asarray(g0).reshape(-1), np.asarray(x0)])
    fn = lambda t, y: np.asarray(field(t, y))
    fn(0.0, y0)  # compile
    points = []
    for rtol in rtols:
        runs = []
        for _ in range(repeats):
            start = time.perf_counter()
            sol = solve_ivp(
                fn,
                (0.0, problem.t1),
                y0,
                method="DOP853",
                rtol=rtol,
                atol=rtol * problem.atol_ratio,
            )
            runs.append(time.perf_counter() - start)
        y = sol.y[:, -1]
        g = bd.project_to_se3(jnp.asarray(y[:16].reshape(4, 4)))
        q, U, qdot = scene.split(problem.t1, jnp.asarray(y[16:]))
        xi = U - bd.connection(scene.system, q) @ qdot
        points.append(
            {
                "setting": rtol,
                "ok": bool(sol.success),
                "error": state_error((g, q, xi, qdot), ref),
                "steps": int(sol.t.size - 1),
                "evaluations": int(sol.nfev),
                "time": summary(runs),
            }
        )
        print(
            f"  {problem.name:16} {'scipy DOP853':19} rtol={rtol:8.1e} error={points[-1]['error']:8.1e} time={points[-1]['time']['median'] * 1e3:9.2f} ms",
            flush=True,
        )
    return [
        {
            "method": "scipy DOP853",
            "family": "peer",
            "fixed": False,
            "compile": 0.0,
            "points": points,
        }
    ]


# --------------------------------------------------------------------------- throughput


def throughput(problem: Problem, batches, repeats, t1=1.0, rtol=1e-6):
    """Rollouts per second of `jax.vmap(simulate)` over perturbed initial velocities."""
    scene, s = problem.scene, problem.state

    @jax.jit
    def batch(xi):
        def one(x):
            traj = bd.simulate(
                scene, bd.State(s.g, s.q, x, s.qdot), t1, rtol=rtol, atol=rtol * problem.atol_ratio
            )
            return traj.g[-1], traj.stats["num_steps"]

        return jax.vmap(one)(xi)

    rows = []
    for n in batches:
        xi = s.xi + 0.05 * jax.random.normal(jax.random.key(n), (n, 6))
        (_, steps), compiled, runs = timed(batch, xi, repeats=repeats)
        t = runs["median"]
        rows.append(
            {
                "batch": n,
                "time": runs,
                "rollouts_per_second": n / t,
                "instance_steps_per_second": float(jnp.sum(steps)) / t,
                "compile": compiled,
            }
        )
        print(
            f"  throughput batch={n:5d}: {n / t:9.1f} rollouts/s ({t:.3f} s per batch)", flush=True
        )
    return rows


def gradient_cost(problem: Problem, repeats, t1=1.0, rtol=1e-8):
    """Time of `jax.grad` of a rollout loss relative to the forward solve, per adjoint."""
    scene, s = problem.scene, problem.state

    def loss(xi, adjoint):
        traj = bd.simulate(
            scene,
            bd.State(s.g, s.q, xi, s.qdot),
            t1,
            rtol=rtol,
            atol=rtol * problem.atol_ratio,
            adjoint=adjoint,
        )
        return jnp.sum(traj.g[-1, :3, 3] ** 2) + jnp.sum(traj.q[-1] ** 2)

    forward = jax.jit(lambda xi: loss(xi, diffrax.RecursiveCheckpointAdjoint()))
    _, _, base = timed(forward, s.xi, repeats=repeats)
    rows = [{"adjoint": "forward solve", "time": base, "ratio": 1.0}]
    for name, adjoint in (
        ("RecursiveCheckpointAdjoint", diffrax.RecursiveCheckpointAdjoint()),
        (
            "BacksolveAdjoint",
            diffrax.BacksolveAdjoint(
                stepsize_controller=diffrax.PIDController(rtol=rtol, atol=rtol * problem.atol_ratio)
            ),
        ),
    ):
        grad = jax.jit(jax.grad(lambda xi, a=adjoint: loss(xi, a)))
        _, compiled, runs = timed(grad, s.xi, repeats=repeats)
        rows.append(
            {
                "adjoint": name,
                "time": runs,
                "ratio": runs["median"] / base["median"],
                "compile": compiled,
            }
        )
        print(f"  grad ({name}): {rows[-1]['ratio']:.2f}x the forward solve", flush=True)
    return rows


def compile_times(ns, repeats=3):
    """Compile time of `simulate` for hinge chains of n bodies (n = 1 is a single body)."""
    rows = []
    for n in ns:
        system = chain_scene(n).system
        d = system.shape_dim
        scene, state = bd.Scene(system), _moving(d)
        solve = jax.jit(
            lambda scene=scene, state=state: bd.simulate(scene, state, 1.0, rtol=1e-6, atol=1e-9).g[
                -1
            ]
        )
        _, compiled, runs = timed(solve, repeats=repeats)
        rows.append({"bodies": n, "compile": compiled, "run": runs})
        print(f"  compile n={n:2d}: {compiled:6.1f} s", flush=True)
    return rows


# ------------------------------------------------------------------------------- report


def environment():
    import importlib.metadata as md

    versions = {}
    for package in (
        "bundledyn",
        "jax",
        "jaxlib",
        "diffrax",
        "equinox",
        "numpy",
        "scipy",
        "mujoco",
        "matplotlib",
    ):
        try:
            versions[package] = md.version(package)
        except md.PackageNotFoundError:
            versions[package] = None
    return {
        "date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, {platform.processor() or platform.platform()}",
        "python": platform.python_version(),
        "xla_flags": os.environ.get("XLA_FLAGS", ""),
        "versions": versions,
    }


def plot(problem_result, path):
    try:
        from bundledyn import viz
    except ImportError:
        print("  matplotlib is not installed: no diagrams (pip install '.[viz]')")
        return None
    viz.plot_work_precision(
        problem_result["series"],
        title=problem_result["title"],
        floor=problem_result["reference_agreement"],
        path=path,
    )
    return path.name


def digit_costs(series):
    """Seconds per extra correct digit between successive points of one method."""
    pts = [p for p in series["points"] if p["ok"] and p["error"] > 0]
    rows = []
    for a, b in zip(pts, pts[1:], strict=False):
        digits = np.log10(a["error"] / b["error"])
        if digits > 0.1:
            rows.append((a["error"], b["error"], b["time"]["median"] / a["time"]["median"], digits))
    return rows


def time_at_error(series, target):
    """Interpolated (log–log) wall time at which a method reaches `target` error, or None."""
    return _time_at_error([p for p in series["points"] if p["ok"]], target)


TARGETS = (1e-3, 1e-4, 1e-6, 1e-8, 1e-10)


def time_to_error_table(series_list):
    """Milliseconds each method needs to reach each target error (log–log interpolation)."""
    header = "| time [ms] to reach error | " + " | ".join(f"{e:.0e}" for e in TARGETS) + " |"
    lines = [header, "|---|" + "---|" * len(TARGETS)]
    for series in series_list:
        cells = []
        for target in TARGETS:
            t = time_at_error(series, target)
            reached = [
                p["time"]["median"] for p in series["points"] if p["ok"] and p["error"] <= target
            ]
            if t is not None:
                cells.append(f"{t * 1e3:.3g}")
            elif reached:  # already below the target at its loosest setting
                cells.append(f"≤ {min(reached) * 1e3:.3g}")
            else:
                cells.append("–")
        lines.append(f"| {series['method']} | " + " | ".join(cells) + " |")
    peer = next((s for s in series_list if s["method"] == "MuJoCo RK4"), None)
    rkmk54 = next((s for s in series_list if s["method"] == "RKMK54"), None)
    if peer and rkmk54:
        ratios = []
        for target in TARGETS:
            a, b = time_at_error(rkmk54, target), time_at_error(peer, target)
            ratios.append("–" if a is None or b is None else f"{a / b:.2g}")
        lines.append("| **RKMK54 / MuJoCo RK4** | " + " | ".join(ratios) + " |")
    return lines


def markdown(report):
    env = report["environment"]
    lines = [
        "# What accuracy costs in time",
        "",
        f"Measured {env['date']} on {env['machine']}, Python {env['python']}, XLA_FLAGS=`{env['xla_flags']}`.",
        "Versions: " + ", ".join(f"{k} {v}" for k, v in env["versions"].items() if v) + ".",
        "",
        *(
            [
                f"Throughput, gradients and compile times measured {report['extras_environment']['date']} (same machine).",
                "",
            ]
            if "extras_environment" in report
            else []
        ),
        "Times are medians of the runs after compilation (min–max in brackets); errors are",
        "the largest deviation of the state at t1 from the reference (see the script's docstring).",
        "",
    ]
    for result in report["problems"]:
        lines += [f"## {result['title']}", ""]
        if result.get("figure"):
            lines += [f"![work–precision]({result['figure']})", ""]
        lines += [
            f"Reference: RKMK 5(4) vs Dopri8 at rtol {REFERENCE_RTOL:g} agree to {result['reference_agreement']:.1e} (the error floor).",
            "",
            "| method | setting | error | time [ms] | steps | evals | energy drift | momentum drift |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for series in result["series"]:
            for p in series["points"]:
                t = p["time"]
                setting = (
                    f"dt={p['setting']:.1e}" if series["fixed"] else f"rtol={p['setting']:.0e}"
                )
                energy = p.get("energy_drift", float("nan"))
                momentum = p.get("momentum_drift", float("nan"))
                lines.append(
                    f"| {series['method']} | {setting} | {p['error']:.1e} | {t['median'] * 1e3:.2f} ({t['min'] * 1e3:.2f}–{t['max'] * 1e3:.2f}) "
                    f"| {p['steps']} | {p['evaluations']} | {energy:.1e} | {momentum:.1e} |"
                )
        lines += [
            "",
            "Compile times: "
            + ", ".join(
                f"{s['method']} {s['compile']:.1f} s"
                for s in result["series"]
                if s["family"] != "peer"
            ),
            "",
        ]
        lines += time_to_error_table(result["series"]) + [""]
        rkmk54 = next((s for s in result["series"] if s["method"] == "RKMK54"), None)
        if rkmk54:
            costs = digit_costs(rkmk54)
            if costs:
                lines.append(
                    "RKMK 5(4), cost of each extra digit: "
                    + ", ".join(
                        f"{e0:.0e}→{e1:.0e}: ×{r:.2f} per {d:.1f} digits" for e0, e1, r, d in costs
                    )
                    + "."
                )
                lines.append("")
    for key, title in (
        ("throughput", "Throughput of vmapped rollouts (chain, 1 s, rtol 1e-6)"),
        ("gradients", "Gradient cost (chain, 1 s, rtol 1e-8)"),
        ("compile", "Compile time of `simulate` against the number of bodies"),
    ):
        rows = report.get(key)
        if not rows:
            continue
        columns = list(dict.fromkeys(k for row in rows for k in row))
        lines += [f"## {title}", "", "| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
        for row in rows:
            cells = []
            for v in (row.get(k, "–") for k in columns):
                if isinstance(v, dict):
                    cells.append(f"{v['median']:.3g} ({v['min']:.3g}–{v['max']:.3g})")
                elif isinstance(v, float):
                    cells.append(f"{v:.3g}")
                else:
                    cells.append(str(v))
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one scene, three points per method")
    parser.add_argument("--out", type=pathlib.Path, default=RESULTS, help="folder for the report")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument(
        "--problems", nargs="*", default=None, help="subset of " + ", ".join(PROBLEMS)
    )
    parser.add_argument(
        "--report-only", action="store_true", help="rewrite the markdown and diagrams from the JSON"
    )
    parser.add_argument(
        "--extras-only",
        action="store_true",
        help="measure throughput, gradient cost and compile times into the existing JSON",
    )
    args = parser.parse_args(argv)
    if args.report_only:
        return rewrite_report(args.out, "accuracy_cost_quick" if args.quick else "accuracy_cost")
    if args.extras_only:
        report = json.loads((args.out / "accuracy_cost.json").read_text())
        report["extras_environment"] = environment()
        measure_extras(report, args.repeats)
        write_report(report, args.out)
        return report
    names = args.problems or (["dzhanibekov"] if args.quick else list(PROBLEMS))
    args.out.mkdir(parents=True, exist_ok=True)
    report = {"environment": environment(), "quick": args.quick, "problems": []}
    for name in names:
        problem = PROBLEMS[name]()
        print(f"{problem.title}", flush=True)
        ref, agreement = reference(problem)
        print(f"  reference agreement (RKMK54 vs Dopri8): {agreement:.1e}", flush=True)
        series = [
            sweep(problem, METHODS[m], ref, args.quick, args.repeats)
            for m in methods_for(problem, args.quick)
        ]
        if name == "chain" and not args.quick:
            series += mujoco_peer(
                problem, ref, args.repeats, (100, 200, 400, 800, 1600, 3200, 6400, 12800)
            )
            series += scipy_peer(problem, ref, args.repeats, (1e-4, 1e-6, 1e-8, 1e-10))
        result = {
            "name": name,
            "title": problem.title,
            "reference_agreement": agreement,
            "series": series,
        }
        result["figure"] = plot(result, args.out / f"accuracy_cost_{name}.png")
        report["problems"].append(result)
        write_report(report, args.out)  # after every scene: a long run keeps what it measured
    if not args.quick and args.problems is None:
        measure_extras(report, args.repeats)
        write_report(report, args.out)
    return report


def measure_extras(report, repeats):
    """Throughput, gradient cost and compile time against bodies, on the chain."""
    chain_problem = PROBLEMS["chain"]()
    print("throughput, gradients, compile times", flush=True)
    report["throughput"] = throughput(chain_problem, (1, 64, 1024), repeats)
    report["gradients"] = gradient_cost(chain_problem, repeats)
    report["compile"] = compile_times((1, 2, 5, 10, 20))


def write_report(report, out):
    stem = "accuracy_cost_quick" if report["quick"] else "accuracy_cost"
    (out / f"{stem}.json").write_text(json.dumps(report, indent=1, default=float))
    (out / f"{stem}.md").write_text(markdown(report))
    print(f"wrote {out / (stem + '.md')}", flush=True)


def rewrite_report(out, stem):
    """Diagrams and markdown again from a results JSON, without measuring anything."""
    report = json.loads((out / f"{stem}.json").read_text())
    for result in report["problems"]:
        result["figure"] = plot(result, out / f"accuracy_cost_{result['name']}.png")
    (out / f"{stem}.md").write_text(markdown(report))
    print(f"rewrote {out / (stem + '.md')}")
    return report


if __name__ == "__main__":
    bd.use_cpu_xla_flags()  # before the first computation: importing starts no backend
    main(sys.argv[1:])
