"""The survey's markdown from a run's JSON (its diagram is `plot.draw`'s)."""

import math
import statistics

from benchmarks._report import provenance_lines, versions
from benchmarks.survey.gradient import TOLERANCE as GRADIENT_TOLERANCE
from benchmarks.survey.measure import METRIC_GOAL, ROLLOUT_GOAL
from benchmarks.survey.plot import SERIES, ratios
from benchmarks.survey.solves import ROUNDING, TOLERANCES


def _reason(entry):
    """The first sentence of a refusal: what the model has that bundledyn refuses."""
    text = " ".join(entry["reason"].split())
    return text.split(";")[0].split(". ")[0].replace("|", "/")


def _row(entry):
    if entry["status"] != "imported":
        return f"| {entry['name']} | {entry.get('nv', '')} | {entry['status']}: {_reason(entry)} | | | | | | | | |"
    field = entry["field"]
    off = "; ".join(entry["turned_off"][1:]) or "–"
    verdict = "yes" if entry["passed"] else "**no**"
    return (
        f"| {entry['name']} | {entry['nv']} | {entry['base']} | {entry['metric_error']:.1e} | "
        f"{entry['rollout_error']:.1e} / {entry['fine_rollout_error']:.1e} ({entry['rk4_error']:.1e}) {verdict} | "
        f"{field['ratio']:.1f} ({field['field']['median'] * 1e6:.3g} µs) | {_dense(entry)} | "
        f"{entry['seconds'][1]:.2f} s, {entry['steps']} steps / {entry['mujoco_seconds']:.2f} s "
        f"({entry['seconds'][0]:.1f} s first call) | {_equal_error(entry)} | {_gradient(entry)} | "
        f"{off} |"
    )


def _equal_error(entry):
    """The solve's cell: its time to RK4's error over RK4's, and that error."""
    solves = entry["solves"]
    ratio = "not reached" if math.isinf(solves["ratio"]) else f"{solves['ratio']:.2f}"
    return f"{ratio} (at {solves['mujoco']['error']:.0e})"


def _gradient(entry):
    """The gradient's cell: its time over the forward solve's, and its compile seconds."""
    gradient = entry["gradient"]
    if "error" in gradient:
        return f"failed: {gradient['error'][:80]}".replace("|", "/")
    return f"{gradient['ratio']:.1f} ({gradient['compile']['grad']:.0f} s compile)"


def _dense(entry):
    """The dense field's cell: its ratio to `mj_forward` and time, where it was timed."""
    field = entry["field"]
    if "dense" not in field:
        return "(the default)" if entry.get("algorithm") == "DenseField" else "–"
    agree = field["agreement"]
    return (
        f"{field['dense_ratio']:.1f} ({field['dense']['median'] * 1e6:.3g} µs); "
        f"{agree['field']:.0e}, {agree['vjp']:.0e}"
    )


def summary(report):
    models = report["models"]
    imported = [m for m in models if m["status"] == "imported"]
    passed = [m for m in imported if m["passed"]]
    ratios = [m["field"]["ratio"] for m in imported]
    lines = [
        f"{len(models)} model files: {len(imported)} import, {len(passed)} of them equal MuJoCo "
        f"(metric to {METRIC_GOAL:g} relative, {report['horizon']:g} s rollout to "
        f"{ROLLOUT_GOAL:g} in qpos and qvel, against RK4 at dt = 1e-4 or, where that step's "
        f"own error is larger, at 1.25e-5); {len(models) - len(imported)} refused or failed.",
    ]
    if ratios:
        worst = max(imported, key=lambda m: m["field"]["ratio"])
        lines[0] += (
            f" The field costs {statistics.median(ratios):.1f}× `mj_forward` (median), "
            f"{worst['field']['ratio']:.1f}× at worst ({worst['name']}, {worst['nv']} DoF)."
        )
    lines += [_series_line(imported, key, what, limit) for key, what, limit in SERIES[1:]]
    dense = [m["field"]["dense_ratio"] for m in imported if "dense_ratio" in m["field"]]
    if dense:
        lines[0] += (
            f" Where the default is the articulated-body field ({len(dense)} models), the "
            f"dense field would cost {statistics.median(dense):.1f}× (median), "
            f"{max(dense):.1f}× at worst. The two fields agree to "
            f"{max(m['field']['agreement']['field'] for m in imported if 'dense' in m['field']):.0e} "
            "and their VJPs to "
            f"{max(m['field']['agreement']['vjp'] for m in imported if 'dense' in m['field']):.0e} "
            "on every one of them (relative to the largest entry)."
        )
    return lines


def _series_line(imported, key, what, limit):
    """A ratio's median and worst over the models that have it, against its limit."""
    values = sorted((ratios(m)[key], m["name"], m["nv"]) for m in imported if key in ratios(m))
    if not values:
        return f"{what}: not measured."
    worst = values[-1]
    within = sum(v <= limit for v, _, _ in values)
    missing = len(imported) - len(values)
    return (
        f"{what}: {statistics.median(v for v, _, _ in values):.2f}× (median), {worst[0]:.2f}× "
        f"at worst ({worst[1]}, {worst[2]} DoF); {within} of {len(values)} models within "
        f"{limit:g}×" + (f", {missing} not reached or failed." if missing else ".")
    )


def markdown(report):
    env = report["environment"]
    lines = [
        "# Every MuJoCo model of dm_control and gymnasium, imported",
        "",
        *provenance_lines(report),
        f"Packages: {versions(env)}. Each model with its passive forces and gravity as it has "
        f"them (`Scene.from_mjcf(path, passive=True, gravity=True)`), from a state near its "
        f"home pose; MuJoCo with contacts, limits, actuators and friction loss off, RK4 at "
        f"dt = 1e-4, and what the import leaves out (last column) off too; bundledyn's "
        f"default solver ({report['solver']}) at rtol = atol = 1e-12. The field's time is a median over {report['repeats']} samples, in "
        "alternation with `mj_forward` on the same state (and with the dense field, "
        "`DenseField()`, where the scene's default is another). The solve at equal error: "
        f"bundledyn at rtol = atol = {', '.join(f'{t:.0e}' for t in TOLERANCES)} and MuJoCo "
        "RK4 at dt = 1e-4, timed in alternation (medians), each judged against RK4 at "
        f"1.25e-5; bundledyn's time to RK4's error (or to {ROUNDING:g} where RK4's is smaller: "
        "both are then exact to rounding) is interpolated log–log. The gradient: "
        "`jax.grad` of the final shape's squared norm in the initial shape velocity, "
        f"default solver and adjoint at rtol = atol = {GRADIENT_TOLERANCE:g}, over the "
        "same loss's forward solve, in alternation.",
        "",
        *(part for line in summary(report) for part in (line, "")),
        *(
            [f"![ratios against degrees of freedom]({report['figure']})", ""]
            if report.get("figure")
            else []
        ),
        "| model | DoF | base | metric error | rollout error against RK4 at dt = 1e-4 / "
        "at 1.25e-5 (RK4's own error at 1e-4), within goal | field / mj_forward "
        "(field µs), the scene's default | dense field / mj_forward (µs); its difference "
        "from the default, in values and VJPs | bundledyn solve at 1e-12 / "
        "MuJoCo RK4 | time to RK4's error / RK4's (that error) | jax.grad / forward "
        "(its compile) | also off in MuJoCo |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
        *(_row(entry) for entry in report["models"]),
        "",
    ]
    return "\n".join(lines)
