"""The accuracy–cost report: work–precision diagrams and the markdown of a run's JSON."""

import numpy as np

from benchmarks._errors import time_at_error as _time_at_error
from benchmarks._report import fmt, provenance_lines, versions
from benchmarks.accuracy_cost.sweep import REFERENCE_RTOL

TARGETS = (1e-3, 1e-4, 1e-6, 1e-8, 1e-10)


def plot(problem_result, path):
    """The problem's work–precision diagram at `path`; its file name, or None without
    matplotlib."""
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
    """Time ratio per extra correct digit between successive points of one method."""
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


def _time_cell(series, target):
    t = time_at_error(series, target)
    if t is not None:
        return f"{t * 1e3:.3g}"
    reached = [p["time"]["median"] for p in series["points"] if p["ok"] and p["error"] <= target]
    return f"≤ {min(reached) * 1e3:.3g}" if reached else "–"  # ≤: below target when loosest


def time_to_error_table(series_list):
    """Milliseconds each method needs to reach each target error, and RKMK54 over MuJoCo RK4."""
    header = "| time [ms] to reach error | " + " | ".join(f"{e:.0e}" for e in TARGETS) + " |"
    lines = [header, "|---|" + "---|" * len(TARGETS)]
    for series in series_list:
        cells = [_time_cell(series, target) for target in TARGETS]
        lines.append(f"| {series['method']} | " + " | ".join(cells) + " |")
    by_name = {s["method"]: s for s in series_list}
    peer, rkmk54 = by_name.get("MuJoCo RK4"), by_name.get("RKMK54")
    if peer and rkmk54:
        ratios = []
        for target in TARGETS:
            a, b = time_at_error(rkmk54, target), time_at_error(peer, target)
            ratios.append("–" if a is None or b is None else f"{a / b:.2g}")
        lines.append("| **RKMK54 / MuJoCo RK4** | " + " | ".join(ratios) + " |")
    return lines


def _points_table(result):
    lines = [
        "| method | setting | error | time [ms] | steps | evals | energy drift | momentum drift |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for series in result["series"]:
        for p in series["points"]:
            setting = f"dt={p['setting']:.1e}" if series["fixed"] else f"rtol={p['setting']:.0e}"
            energy = p.get("energy_drift", float("nan"))
            momentum = p.get("momentum_drift", float("nan"))
            lines.append(
                f"| {series['method']} | {setting} | {p['error']:.1e} | {fmt(p['time'], 1e3)} "
                f"| {p['steps']} | {p['evaluations']} | {energy:.1e} | {momentum:.1e} |"
            )
    return lines


def _problem_section(result):
    lines = [f"## {result['title']}", ""]
    if result.get("figure"):
        lines += [f"![work–precision]({result['figure']})", ""]
    lines += [
        f"Reference: RKMK 5(4) vs Dopri8 at rtol {REFERENCE_RTOL:g} agree to "
        f"{result['reference_agreement']:.1e} (the error floor).",
        "",
        *_points_table(result),
        "",
        "Compile times: "
        + ", ".join(
            f"{s['method']} {s['compile']:.1f} s" for s in result["series"] if s["family"] != "peer"
        ),
        "",
        *time_to_error_table(result["series"]),
        "",
    ]
    rkmk54 = next((s for s in result["series"] if s["method"] == "RKMK54"), None)
    costs = digit_costs(rkmk54) if rkmk54 else []
    if costs:
        steps = (f"{e0:.0e}→{e1:.0e}: ×{r:.2f} per {d:.1f} digits" for e0, e1, r, d in costs)
        lines += ["RKMK 5(4), cost of each extra digit: " + ", ".join(steps) + ".", ""]
    return lines


def _cell(v):
    if isinstance(v, dict):
        return f"{v['median']:.3g} ({v['min']:.3g}–{v['max']:.3g})"
    return f"{v:.3g}" if isinstance(v, float) else str(v)


EXTRAS = (
    ("throughput", "Throughput of vmapped rollouts (chain, 1 s, rtol 1e-6)"),
    ("gradients", "Gradient cost (chain, 1 s, rtol 1e-8)"),
    ("compile", "Compile time of `simulate` against the number of bodies"),
)


def _extras_section(report):
    lines = []
    for key, title in EXTRAS:
        rows = report.get(key)
        if not rows:
            continue
        columns = list(dict.fromkeys(k for row in rows for k in row))
        lines += [f"## {title}", "", "| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
        lines += ["| " + " | ".join(_cell(row.get(k, "–")) for k in columns) + " |" for row in rows]
        lines.append("")
    return lines


def markdown(report):
    """The report's markdown: provenance, every problem's table and diagram, the extras."""
    env = report["environment"]
    extras_env = report.get("extras_environment")
    lines = [
        "# What accuracy costs in time",
        "",
        *provenance_lines(report),
        f"Measured {env['date']} on {env['machine']}, Python {env['python']}, "
        f"XLA_FLAGS=`{env['xla_flags']}`.",
        f"Versions: {versions(env)}.",
        "",
        *(
            [f"Throughput, gradients and compile times measured {extras_env['date']}.", ""]
            if extras_env
            else []
        ),
        "Times are medians of the runs after compilation (min–max in brackets); errors are",
        "the largest deviation of the state at t1 from the reference (`benchmarks/_errors.py`).",
        "",
    ]
    for result in report["problems"]:
        lines += _problem_section(result)
    return "\n".join(lines + _extras_section(report))
