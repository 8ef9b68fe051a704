"""The growth benchmark's markdown: the issue's targets over the members, each time's fitted
growth in the bodies, and every member."""

import statistics

import numpy as np

from benchmarks._report import fmt, provenance_lines, versions

TARGET_MOST_DOFS = 150  # the field and gradient targets hold up to this size
GROWN = (  # (key, what): the times whose growth in the bodies is fitted
    ("field", "field (recursions)"),
    ("dense", "dense field"),
    ("mj_forward", "mj_forward"),
    ("field_vjp", "field's VJP"),
)


def exponent(members, key, least_bodies=0) -> float:
    """The least-squares slope of log time against log bodies over `members` with at least
    `least_bodies` bodies: time growing as bodies to this power (NaN over one size)."""
    chosen = [m for m in members if m["bodies"] >= least_bodies]
    if len({m["bodies"] for m in chosen}) < 2:
        return float("nan")
    x = np.log([m["bodies"] for m in chosen])
    y = np.log([m["times"][key]["median"] for m in chosen])
    return float(np.polyfit(x, y, 1)[0])


def _ratio(member, numerator, denominator):
    times = member["times"]
    return times[numerator]["median"] / times[denominator]["median"]


def _row(name, values, target):
    """A target's row: median and worst (with its member) of `(value, label)`s, the worst
    judged as shown, to two decimals."""
    if not values:
        return f"| {name} | – | – | – | {target} | – |"
    worst, label = max(values)
    median = statistics.median(v for v, _ in values)
    met = "yes" if round(worst, 2) <= target else "no"
    return f"| {name} | {median:.2f} | {worst:.2f} | {label} | {target:g} | {met} |"


def _targets(members):
    within = [m for m in members if m["dofs"] <= TARGET_MOST_DOFS]
    kinds = sorted({m["kind"] for m in members})
    rows = [
        _row(
            f"field / mj_forward, up to {TARGET_MOST_DOFS} DoF",
            [(_ratio(m, "field", "mj_forward"), m["label"]) for m in within],
            5,
        ),
        _row(
            f"`jax.grad` / forward solve, up to {TARGET_MOST_DOFS} DoF",
            [(m["gradient"]["ratio"], m["label"]) for m in within if m["gradient"]],
            4,
        ),
    ]
    for kind in kinds:
        of_kind = [m for m in members if m["kind"] == kind]
        rows.append(
            _row(
                f"field's growth exponent in the bodies, {kind} trees",
                [(exponent(of_kind, "field"), f"{len(of_kind)} trees")],
                1,
            )
        )
    return rows


def _or_dash(value):
    return "–" if np.isnan(value) else f"{value:.2f}"


def _per_body(members, bodies):
    return statistics.median(
        m["times"]["field"]["median"] / bodies for m in members if m["bodies"] == bodies
    )


def _growth_rows(members):
    rows = []
    for kind in sorted({m["kind"] for m in members}):
        of_kind = [m for m in members if m["kind"] == kind]
        sizes = sorted({m["bodies"] for m in of_kind})
        cells = " | ".join(
            f"{exponent(of_kind, key):.2f} ({_or_dash(exponent(of_kind, key, sizes[len(sizes) // 2]))})"
            for key, _ in GROWN
        )
        least, most = sizes[0], sizes[-1]
        per_body = f"{_per_body(of_kind, least) * 1e6:.2f} / {_per_body(of_kind, most) * 1e6:.2f}"
        rows.append(f"| {kind} | {least}–{most} | {cells} | {per_body} |")
    return rows


def _gradient_cells(member):
    gradient = member["gradient"]
    if gradient is None:
        return "– | –"
    if "error" in gradient:
        return f"{gradient['error']} | –"
    return f"{gradient['ratio']:.2f} | {gradient['forward']['median'] * 1e3:.3g}"


def _member_row(m):
    t = m["times"]
    agreed = m["agreement"]
    return (
        f"| {m['label']} | {m['dofs']} | {m['depth']} | {m['condition']:.1e} | "
        f"{m['metric_error']:.1e} | "
        f"{agreed['field']:.1e} / {agreed['vjp']:.1e} | {fmt(t['field'], 1e6)} | "
        f"{fmt(t['dense'], 1e6)} | {fmt(t['mj_forward'], 1e6)} | "
        f"{_ratio(m, 'field', 'mj_forward'):.2f} | {_ratio(m, 'field_vjp', 'field'):.2f} | "
        f"{_gradient_cells(m)} |"
    )


def markdown(report):
    members = report["members"]
    lines = ["# How the field's cost grows with the bodies", ""]
    lines += provenance_lines(report)
    lines += [
        f"Environment: {report['environment']['machine']}; {versions(report['environment'])}.",
        "",
        f"{len(members)} random free-floating trees (`benchmarks/growth/members.py`), float64, "
        f"one CPU core, gravity off, each at a tumbling start; per evaluation inside a "
        f"compiled loop, {report['repeats']} rounds in alternation, median (min–max). Before "
        "timing, each member's metric is compared with MuJoCo's mass matrix (`mj_fullM`) and "
        "its recursive field with the dense one (values, and VJPs at one cotangent, each "
        "relative to the largest entry; the mass matrix's condition number beside them). Gradients: `jax.grad` of the survey's loss "
        f"(`benchmarks/survey/gradient.py`) over {report['horizon']} s with `simulate`'s "
        f"default solver ({report['solver']}) and adjoint, over the forward solve timed in "
        "alternation with it.",
        "",
        "## Targets: median and worst case over the members",
        "",
        "| target | median | worst | worst member | limit | met |",
        "|---|--:|--:|---|--:|:-:|",
        *_targets(members),
        "",
        "## Growth in the bodies",
        "",
        "Each time's exponent in the number of bodies: the least-squares slope of log time "
        "against log bodies over every tree of a kind, and in brackets over the larger half "
        "of the sizes alone (1 is linear, 2 quadratic); then the field's time per body at the "
        "smallest and largest size (µs, median over the seeds).",
        "",
        "| kind | bodies | " + " | ".join(what for _, what in GROWN) + " | µs per body |",
        "|---|---|" + "--:|" * len(GROWN) + "--:|",
        *_growth_rows(members),
        "",
        "## Every member (µs per evaluation)",
        "",
        "| model | DoF | depth | cond(M) | metric vs mj_fullM | recursive vs dense (field / VJP) | field | "
        "dense field | mj_forward | field / mj_forward | VJP / field | grad / forward | "
        "forward [ms] |",
        "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
        *map(_member_row, members),
        "",
    ]
    if report.get("figure"):
        lines += [f"![The field's time against the bodies]({report['figure']})", ""]
    return "\n".join(lines)
