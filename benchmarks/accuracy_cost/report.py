"""The accuracy–cost report: work–precision diagrams and the markdown of a run's JSON."""

from benchmarks._errors import time_at_error as _time_at_error
from benchmarks._report import fmt, provenance_lines, versions
from benchmarks.accuracy_cost.digits import (
    DIGIT_SHARE,
    ERROR_CEILING,
    FLOOR_MARGIN,
    MIN_POINTS,
    STEP_GROWTH,
)
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


def time_at_error(series, target):
    """Interpolated (log–log) wall time at which a method reaches `target` error, or None."""
    return _time_at_error([p for p in series["points"] if p["ok"]], target)


def _time_cell(series, target):
    t = time_at_error(series, target)
    if t is not None:
        return f"{t * 1e3:.3g}"
    reached = [p["time"]["median"] for p in series["points"] if p["ok"] and p["error"] <= target]
    return f"≤ {min(reached) * 1e3:.3g}" if reached else "–"  # ≤: below target when loosest


def time_to_error_table(series_list, default):
    """Milliseconds each method needs to reach each target error, and the default solver's
    time over MuJoCo RK4's."""
    header = "| time [ms] to reach error | " + " | ".join(f"{e:.0e}" for e in TARGETS) + " |"
    lines = [header, "|---|" + "---|" * len(TARGETS)]
    for series in series_list:
        cells = [_time_cell(series, target) for target in TARGETS]
        lines.append(f"| {series['method']} | " + " | ".join(cells) + " |")
    by_name = {s["method"]: s for s in series_list}
    peer, ours = by_name.get("MuJoCo RK4"), by_name.get(default)
    if peer and ours:
        ratios = []
        for target in TARGETS:
            a, b = time_at_error(ours, target), time_at_error(peer, target)
            ratios.append("–" if a is None or b is None else f"{a / b:.2g}")
        lines.append(f"| **{default} / MuJoCo RK4** | " + " | ".join(ratios) + " |")
    return lines


def _digit_row(series):
    cost, p = series["per_digit"], series["order"]
    predicted = f"{p} | ×{10 ** (1 / p):.2f}"
    if cost is None:
        return f"| {series['method']} | {predicted} | – | – | fewer than {MIN_POINTS} points in range |"
    loose, tight = cost["settings"]
    return (
        f"| {series['method']} | {predicted} | ×{cost['time']:.2f} | ×{cost['steps']:.2f} "
        f"| {cost['errors'][0]:.0e} → {cost['errors'][1]:.0e} (rtol {loose:.0e} → {tight:.0e}, "
        f"{cost['points']} points) |"
    )


def digit_cost_table(result):
    """Each adaptive method's cost per extra digit of error against what its order predicts."""
    lines = [
        "| method | order p | 10^(1/p) | time per digit | steps per digit | fitted over errors |",
        "|---|---|---|---|---|---|",
    ]
    return lines + [_digit_row(s) for s in result["series"] if not s["fixed"]]


def _setting(series, point):
    return f"dt={point['setting']:.1e}" if series["fixed"] else f"rtol={point['setting']:.0e}"


def _point_row(series, p):
    if "raised" in p:
        return f"| {series['method']} | {_setting(series, p)} | raised | – | – | – | – | – |"
    energy = p.get("energy_drift", float("nan"))
    momentum = p.get("momentum_drift", float("nan"))
    return (
        f"| {series['method']} | {_setting(series, p)} | {p['error']:.1e} | {fmt(p['time'], 1e3)} "
        f"| {p['steps']} | {p['evaluations']} | {energy:.1e} | {momentum:.1e} |"
    )


def _raised_lines(result):
    """Each message a solve raised with, and the points that raised it."""
    raised = {}
    for series in result["series"]:
        for p in series["points"]:
            if "raised" in p:
                raised.setdefault(p["raised"], []).append(
                    f"{series['method']} {_setting(series, p)}"
                )
    return [f"Raised ({', '.join(points)}): {message}" for message, points in raised.items()]


def _points_table(result):
    lines = [
        "| method | setting | error | time [ms] | steps | evals | energy drift | momentum drift |",
        "|---|---|---|---|---|---|---|---|",
    ]
    lines += [_point_row(series, p) for series in result["series"] for p in series["points"]]
    raised = _raised_lines(result)
    return lines + (["", *raised] if raised else [])


def _problem_section(result, default):
    lines = [f"## {result['title']}", ""]
    if result.get("figure"):
        lines += [f"![work–precision]({result['figure']})", ""]
    return lines + [
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
        *time_to_error_table(result["series"], default),
        "",
        "Cost per extra digit of accuracy:",
        "",
        *digit_cost_table(result),
        "",
    ]


def _cell(v):
    if isinstance(v, dict):
        return f"{v['median']:.3g} ({v['min']:.3g}–{v['max']:.3g})"
    return f"{v:.3g}" if isinstance(v, float) else str(v)


EXTRAS = (  # measured with `bundledyn.simulate`'s default solver
    ("throughput", "Throughput of vmapped rollouts ({solver}, chain, 1 s, rtol 1e-6)"),
    ("gradients", "Gradient cost ({solver}, chain, 1 s, rtol 1e-8)"),
    ("compile", "Compile time of `simulate` ({solver}) against the number of bodies"),
)


def _extras_section(report):
    lines = []
    for key, title in EXTRAS:
        rows = report.get(key)
        if not rows:
            continue
        columns = list(dict.fromkeys(k for row in rows for k in row))
        lines += [
            f"## {title.format(solver=report['default_solver'])}",
            "",
            "| " + " | ".join(columns) + " |",
            "|" + "---|" * len(columns),
        ]
        lines += ["| " + " | ".join(_cell(row.get(k, "–")) for k in columns) + " |" for row in rows]
        lines.append("")
    return lines


def _digit_cost_legend():
    sentences = (
        "Cost per extra digit: for each adaptive method, the time (and step) ratio per decade "
        "of error, 10^-slope of a least-squares line of log time (log steps) against log error "
        f"over the sweep's asymptotic range: errors from {FLOOR_MARGIN:g}× the reference floor "
        f"up to {ERROR_CEILING:.0e}, the longest run of successive tolerances each taking "
        f"≥ {STEP_GROWTH:g}× the steps of the one before and gaining ≥ {DIGIT_SHARE:g} of the "
        "digits it asks for (flat steps are bound by stability, a stalled error by rounding).",
        "An order-p method's error goes as h^p, so its steps grow by 10^(1/p) per digit: the "
        "column of what the order predicts, p as the solver class declares it. Its time grows "
        "alike once the fixed cost of a solve is small.",
    )
    return [" ".join(sentences), ""]


def markdown(report):
    """The report's markdown: provenance, every problem's table and diagram, the extras."""
    env, default = report["environment"], report["default_solver"]
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
        f"`bundledyn.simulate`'s default solver, **{default}**, is swept first and comes first",
        "in every table and diagram.",
        "",
        "Times are medians of the runs after compilation (min–max in brackets); errors are",
        "the largest deviation of the state at t1 from the reference (`benchmarks/_errors.py`).",
        "",
        *_digit_cost_legend(),
    ]
    for result in report["problems"]:
        lines += _problem_section(result, default)
    return "\n".join(lines + _extras_section(report))
