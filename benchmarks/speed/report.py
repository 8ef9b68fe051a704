"""`speed.md`: the CPU run's report, redrawn from `speed.json` alone (`--report-only`)."""

import math

from benchmarks._report import fmt, provenance_lines, versions
from benchmarks.speed.config import BATCH, METHODS, XLA_SETTINGS, setting_label
from benchmarks.speed.gradient_report import gradient_lines
from benchmarks.speed.targets import targets


def measured(report, where):
    """The opening sentence of a report: when, where, which versions, how many repeats."""
    env = report["environment"]
    return (
        f"Measured {env['date']} on {where} (load average at start "
        + ", ".join(f"{x:.2f}" for x in env["loadavg"])
        + f"), Python {env['python']}; "
        + versions(env)
        + f". {report['repeats']} repeats; times are median (min–max)."
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
    """The whole report: targets, then parts 1 to 5."""
    env = report["environment"]
    lines = [
        "# Speed against MuJoCo",
        "",
        *provenance_lines(report),
        measured(report, env["machine"]) + " Same MJCF model "
        "(`benchmarks/_models.py: chain_mjcf`) in both simulators, float64, CPU.",
        "",
        "## Targets",
        "",
        "| target | measured | limit | met | by how much |",
        "|---|--:|--:|:-:|--:|",
    ]
    for what, value, limit, met in targets(report):
        miss = "" if met else f"{value / limit:.2g}× over"
        lines.append(f"| {what} | {value:.3g} | {limit:.3g} | {'yes' if met else 'no'} | {miss} |")
    lines += field_lines(report) + chain_lines(report) + batch_lines(report)
    lines += compile_lines(report) + gradient_lines(report)
    return "\n".join(lines) + "\n"


def field_lines(report):
    """Part 1: the field against `mj_forward` under both XLA settings."""
    settings = report["settings"]
    lines = [
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
    return lines


def chain_lines(report):
    """Part 2: every method's points on the 10 s solve."""
    chain = report["chain"]
    lines = [
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
    return lines


def batch_lines(report):
    """Part 3: the batches under both XLA settings, beside MuJoCo's and MJX's."""
    settings = report["settings"]
    mjb = settings["bundledyn"]["mujoco_batch"]
    cal = report["batch_calibration"]
    lines = [
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
    return lines + ["", mjx_sentence(report)]


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


def compile_lines(report):
    """Part 4: compile times under both XLA settings."""
    settings = report["settings"]
    lines = [
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
    return lines + [
        "",
        "In one process per setting, in the order of the table: the field traced for the "
        "forward `simulate` of n = 20 is reused (not traced again) by its `jax.grad`, as in "
        "a session that runs a model before differentiating it.",
    ]
