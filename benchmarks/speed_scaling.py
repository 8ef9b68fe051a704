"""Speed scaling with the number of bodies: vector field and one simulated second.

For free-floating chains of n = 1, 2, 5, 10, 20 boxes joined by hinges (`Revolute`
joints with axes alternating between y and z, as in MuJoCo hinge chains; n = 1 is a
single `RigidBody`), no forces, float64, this script times

1. one evaluation of `scene.vector_field` under `jax.jit`: compile time, the steady
   time of one dispatched call, and the cost of one evaluation inside a compiled
   `lax.fori_loop` of 100 evaluations (no dispatch);
2. `bd.simulate(scene, state, 1.0, rtol=1e-6, atol=1e-8)` (RKMK54) under `jax.jit`:
   compile time, steady wall time, steps and vector-field evaluations;

each with XLA's CPU fusion emitters on (XLA's default) and off
(`XLA_FLAGS=--xla_cpu_use_fusion_emitters=false`, what bundledyn's command line sets).
XLA reads its flags when the backend starts, so each setting runs in a fresh worker
subprocess that prints its measurements as JSON.

Compile time is the first call's time minus the median steady time; the JSON splits it
into tracing and lowering (`jit(f).lower`) and XLA's compilation (`.compile()`), which is
the part the flag affects. Steady times are the median, min and max over the repeats.

Usage, from the repository root::

    python -m benchmarks.speed_scaling            # n = 1, 2, 5, 10, 20; writes results/
    python -m benchmarks.speed_scaling --quick    # n = 1, 2, 5, 3 repeats; prints only
    python -m benchmarks.speed_scaling --repeats 7
"""

import argparse
import datetime
import json
import os
import pathlib
import platform
import statistics
import subprocess
import sys
import time

FLAG = "--xla_cpu_use_fusion_emitters=false"
SETTINGS = {"default": False, "flag": True}  # setting name -> whether FLAG is set
FULL_NS = (1, 2, 5, 10, 20)
QUICK_NS = (1, 2, 5)
LOOP_EVALS = 100  # vector-field evaluations inside one compiled loop
CALLS_PER_REPEAT = 100  # dispatched vector-field calls per timed repeat
T1, RTOL, ATOL = 1.0, 1e-6, 1e-8
ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results" / "speed_scaling"


# --------------------------------------------------------------------------- worker side


def box(mass, size, com):
    """A solid box of the given mass and edge lengths, centre of mass at `com`."""
    import numpy as np

    import bundledyn as bd

    a, b, c = size
    inertia = mass / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    return bd.RigidBody(mass, com, inertia)


def chain_scene(n):
    """A free-floating chain of `n` boxes joined by hinges with alternating axes, no forces."""
    import numpy as np

    import bundledyn as bd

    bodies = [
        box(1.0 + 0.3 * i, (0.5, 0.1 + 0.02 * i, 0.08), (0.02 * i, 0.01, 0.0)) for i in range(n)
    ]
    if n == 1:
        return bd.Scene(bodies[0])
    placement = np.eye(4)
    placement[0, 3] = 0.5
    links = [
        bd.Link(
            bodies[i],
            bd.Revolute((0.0, 0.0, 1.0) if i % 2 else (0.0, 1.0, 0.0), (-0.25, 0.0, 0.0)),
            i - 1,
            placement,
        )
        for i in range(1, n)
    ]
    return bd.Scene(bd.Multibody(bodies[0], links))


def initial_state(scene):
    """A tumbling initial state: bent shape, base twist and joint rates all non-zero."""
    import jax.numpy as jnp

    import bundledyn as bd

    k = jnp.arange(scene.system.shape_dim, dtype=float)
    xi = jnp.array([0.3, -0.2, 0.5, 0.1, 0.0, -0.1])
    return bd.State(jnp.eye(4), 0.3 * jnp.sin(k + 1.0), xi, 0.5 * jnp.cos(k))


def summary(samples):
    """Median, min and max of a list of times (seconds)."""
    return {"median": statistics.median(samples), "min": min(samples), "max": max(samples)}


def timed(jitted, *args, repeats, calls=1):
    """Time the jitted function `jitted(*args)`: compilation, then steady calls.

    The first call is split into tracing and lowering (`jitted.lower`), XLA compilation
    (`.compile()`, which fills `jitted`'s cache) and the first execution. Then `repeats`
    samples of `calls` calls each, every call waited for (`jax.block_until_ready`).
    Returns these times, the compile time (first call minus the steady median) and the
    steady per-call `summary`, all in seconds.
    """
    import jax

    start = time.perf_counter()
    lowered = jitted.lower(*args)
    trace_lower = time.perf_counter() - start
    lowered.compile()
    xla_compile = time.perf_counter() - start - trace_lower
    jax.block_until_ready(jitted(*args))
    first = time.perf_counter() - start
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(calls):
            jax.block_until_ready(jitted(*args))
        samples.append((time.perf_counter() - start) / calls)
    steady = summary(samples)
    return {
        "first": first,
        "trace_lower": trace_lower,
        "xla_compile": xla_compile,
        "compile": first - steady["median"],
        "steady": steady,
    }


def measure_vector_field(scene, y, repeats):
    """One jitted `scene.vector_field(t, y, None)`: compile time and steady dispatched call."""
    import jax

    field = jax.jit(lambda t, y: scene.vector_field(t, y, None))
    return timed(field, 0.0, y, repeats=repeats, calls=CALLS_PER_REPEAT)


def measure_vector_field_in_loop(scene, y, repeats):
    """`LOOP_EVALS` evaluations in one compiled `fori_loop`: steady cost per evaluation.

    Each iteration takes a tiny explicit-Euler step, so every evaluation depends on the
    previous one and none can be hoisted out of the loop.
    """
    import jax

    def body(i, y):
        dy = scene.vector_field(1e-6 * i, y, None)
        return jax.tree.map(lambda a, b: a + 1e-6 * b, y, dy)

    loop = jax.jit(lambda y: jax.lax.fori_loop(0, LOOP_EVALS, body, y))
    result = timed(loop, y, repeats=repeats)
    result["steady"] = {k: v / LOOP_EVALS for k, v in result["steady"].items()}
    return result


def measure_simulate(scene, state, repeats):
    """`bd.simulate` over one second (RKMK54) jitted as a closure over the scene.

    Besides the times, returns diffrax's step counts and the number of vector-field
    evaluations, 6 per step plus 1: RKMK54 has 7 stages and is FSAL (a rejected step
    keeps the stored first stage), and diffrax's initial step is 0.01 here, not an
    estimate (counted with a callback for n = 1 and 5).
    """
    import jax

    import bundledyn as bd

    def run(state):
        traj = bd.simulate(scene, state, T1, rtol=RTOL, atol=ATOL)
        return traj.g[-1], traj.stats

    run = jax.jit(run)
    result = timed(run, state, repeats=repeats)
    stats = {k: int(v) for k, v in run(state)[1].items()}
    stats["vector_field_evals"] = 6 * stats["num_steps"] + 1
    result["stats"] = stats
    return result


def worker(ns, repeats):
    """Measure every chain length in this process; returns a JSON-serializable dict."""
    import jax

    import bundledyn as bd
    from bundledyn._simulate import initial_condition

    bd.enable_x64()
    jax.block_until_ready(jax.jit(lambda x: x + 1.0)(1.0))  # start the backend untimed
    out = {"xla_flags": os.environ.get("XLA_FLAGS", ""), "chains": {}}
    for n in ns:
        scene = chain_scene(n)
        state = initial_state(scene)
        y = initial_condition(scene, state, 0.0)
        out["chains"][str(n)] = {
            "shape_dim": scene.system.shape_dim,
            "vector_field": measure_vector_field(scene, y, repeats),
            "vector_field_in_loop": measure_vector_field_in_loop(scene, y, repeats),
            "simulate": measure_simulate(scene, state, repeats),
        }
        print(f"  n = {n} done", file=sys.stderr, flush=True)
    return out


# --------------------------------------------------------------------------- driver side


def run_worker(flag, ns, repeats):
    """Run `worker` in a fresh interpreter with or without FLAG; returns its JSON."""
    flags = [f for f in os.environ.get("XLA_FLAGS", "").split() if "fusion_emitters" not in f]
    env = dict(os.environ, XLA_FLAGS=" ".join(flags + [FLAG] if flag else flags))
    command = [sys.executable, "-m", "benchmarks.speed_scaling", "--worker"]
    command += ["--ns", ",".join(map(str, ns)), "--repeats", str(repeats)]
    done = subprocess.run(command, env=env, cwd=ROOT, stdout=subprocess.PIPE, check=True, text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def machine():
    """CPU model, core counts, load average and library versions."""
    import diffrax
    import jax
    import jaxlib

    import bundledyn as bd

    cpu = platform.processor()
    try:
        lines = pathlib.Path("/proc/cpuinfo").read_text().splitlines()
        cpu = next(line.split(":", 1)[1].strip() for line in lines if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return {
        "cpu": cpu or platform.machine(),
        "nproc": len(os.sched_getaffinity(0)),
        "loadavg": os.getloadavg(),
        "python": platform.python_version(),
        "jax": jax.__version__,
        "jaxlib": jaxlib.__version__,
        "diffrax": diffrax.__version__,
        "bundledyn": bd.__version__,
    }


def compare(chain_results, n, what, key, scale, fmt):
    """Cells `default`, `flag`, `default / flag` for one measurement of chain `n`.

    `key` is a top-level time (`compile`, `xla_compile`) or a steady statistic
    (`median`, shown as `median (min)`).
    """
    cells, values = [], []
    for setting in SETTINGS:
        entry = chain_results[setting][n][what]
        value = entry[key] if key in entry else entry["steady"][key]
        text = format(value * scale, fmt)
        if key == "median":
            text += f" ({format(entry['steady']['min'] * scale, fmt)})"
        cells.append(text)
        values.append(value)
    return [*cells, f"{values[0] / values[1]:.2f}"]


def table(report):
    """The report as markdown: setup, compile times, steady times."""
    info = report["machine"]
    chains = {setting: report["results"][setting]["chains"] for setting in SETTINGS}
    ns = list(chains["default"])
    lines = [
        "# Speed scaling with chain length",
        "",
        f"- date: {report['date']}; total wall time {report['wall_s']:.0f} s",
        f"- machine: {info['cpu']}, {info['nproc']} cores, load average at start "
        + ", ".join(f"{x:.2f}" for x in info["loadavg"])
        + " (shared machine: other processes were running; expect noise of tens of %)",
        f"- versions: python {info['python']}, jax {info['jax']}, jaxlib {info['jaxlib']}, "
        f"diffrax {info['diffrax']}, bundledyn {info['bundledyn']}; float64, CPU",
        f"- systems: free-floating chains of n boxes, n - 1 hinges with alternating axes, "
        f"no forces; simulate: RKMK54, t1 = {T1}, rtol = {RTOL}, atol = {ATOL}",
        f"- settings: **default** = XLA's CPU fusion emitters on; **flag** = `{FLAG}`; "
        "ratio = default / flag (> 1: the flag is faster)",
        "- compile = first call minus steady median = tracing and lowering + XLA "
        "compilation (only the latter depends on the flag)",
        f"- repeats: {report['repeats']}; steady times: median (min), max in the JSON; "
        "ratios of medians",
        "",
        "## Compile time (s)",
        "",
        "| n | dof | vector field default | flag | ratio | simulate default | flag | ratio "
        "| simulate, XLA part: default | flag | ratio |",
        "|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for n in ns:
        row = [n, 6 + chains["default"][n]["shape_dim"]]
        row += compare(chains, n, "vector_field", "compile", 1, ".2f")
        row += compare(chains, n, "simulate", "compile", 1, ".2f")
        row += compare(chains, n, "simulate", "xla_compile", 1, ".2f")
        lines.append("| " + " | ".join(map(str, row)) + " |")
    lines += [
        "",
        "## Steady time",
        "",
        "vector field: one jitted call (µs, dispatch included) and one evaluation inside a "
        f"compiled loop of {LOOP_EVALS} (µs); simulate: one simulated second (ms); steps and "
        "field evaluations of the default run.",
        "",
        "| n | call default | flag | ratio | in loop default | flag | ratio "
        "| simulate default | flag | ratio | steps (rejected) | field evals |",
        "|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for n in ns:
        stats = chains["default"][n]["simulate"]["stats"]
        row = [n, *compare(chains, n, "vector_field", "median", 1e6, ".1f")]
        row += compare(chains, n, "vector_field_in_loop", "median", 1e6, ".1f")
        row += compare(chains, n, "simulate", "median", 1e3, ".1f")
        row += [f"{stats['num_steps']} ({stats['num_rejected_steps']})"]
        row += [stats["vector_field_evals"]]
        lines.append("| " + " | ".join(map(str, row)) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    """Command line: run both settings in subprocesses, print and store the report."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="n = 1, 2, 5; 3 repeats; no files")
    parser.add_argument("--repeats", type=int, help="timed repeats (default 5, quick 3)")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--ns", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    repeats = args.repeats or (3 if args.quick else 5)
    if args.worker:
        ns = [int(n) for n in args.ns.split(",")]
        print(json.dumps(worker(ns, repeats)))
        return 0

    ns = QUICK_NS if args.quick else FULL_NS
    report = {
        "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
        "machine": machine(),
        "repeats": repeats,
        "results": {},
    }
    start = time.perf_counter()
    for name, flag in SETTINGS.items():
        print(f"{name} ({FLAG if flag else 'no flag'}):", file=sys.stderr, flush=True)
        report["results"][name] = run_worker(flag, ns, repeats)
    report["wall_s"] = time.perf_counter() - start
    text = table(report)
    print(text)
    if not args.quick:
        RESULTS.parent.mkdir(parents=True, exist_ok=True)
        RESULTS.with_suffix(".md").write_text(text)
        RESULTS.with_suffix(".json").write_text(json.dumps(report, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
