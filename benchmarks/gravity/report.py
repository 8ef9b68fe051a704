"""The gravity benchmark's markdown: per-member times and ratios, and each ratio's median and
worst case over the members beside its target."""

import statistics

from benchmarks._report import fmt, provenance_lines, versions

# (name, numerator, denominator, target or None)
RATIOS = (
    ("field with `Gravity` / field alone", "gravity", "field", 1.3),
    ("field with `Gravity` / `mj_forward` (gravity on)", "gravity", "mj_forward", 5.0),
    (
        "field with gravity by its potential's autodiff / field alone",
        "potential_gradient",
        "field",
        None,
    ),
    ("field with `GravityGradient` / field alone", "gravity_gradient", "field", None),
    ("field's VJP with `Gravity` / without", "gravity_vjp", "field_vjp", None),
    (
        "field's VJP with gravity by its potential's autodiff / without",
        "potential_gradient_vjp",
        "field_vjp",
        None,
    ),
)


def ratio(member, numerator, denominator):
    times = member["times"]
    return times[numerator]["median"] / times[denominator]["median"]


def _summary_rows(members):
    rows = []
    for name, numerator, denominator, target in RATIOS:
        values = [(ratio(m, numerator, denominator), m["label"]) for m in members]
        worst, worst_label = max(values)
        median = statistics.median(v for v, _ in values)
        met = "–" if target is None else ("yes" if worst <= target else "no")
        limit = "–" if target is None else f"{target:g}"
        rows.append(f"| {name} | {median:.2f} | {worst:.2f} | {worst_label} | {limit} | {met} |")
    return rows


def markdown(report):
    members = report["members"]
    lines = ["# What uniform gravity costs in the field", ""]
    lines += provenance_lines(report)
    lines += [
        f"Environment: {report['environment']['machine']}; {versions(report['environment'])}.",
        "",
        f"{len(members)} models (`benchmarks/gravity/members.py`), float64, CPU, each at a "
        f"tumbling start; per evaluation inside a compiled loop, {report['repeats']} rounds in "
        "alternation, median (min–max). `Gravity`'s generalized forces equal those by autodiff of "
        "its potential at the member's state to the relative difference in the last column. "
        f"A step of `simulate`'s default solver ({report['default_solver']}) evaluates the "
        f"field {report['stages']} times.",
        "",
        "## Over the members",
        "",
        "| ratio | median | worst | worst model | target | met |",
        "|---|--:|--:|---|--:|:-:|",
        *_summary_rows(members),
        "",
        "## Every member (µs per evaluation)",
        "",
        "| model | dofs | field | with `Gravity` | by the potential's autodiff | with `GravityGradient` | field VJP | "
        "with `Gravity` | by the potential's autodiff | mj_forward | `Gravity` / field | / mj_forward | agreement |",
        "|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|",
    ]
    for m in members:
        t = m["times"]
        cells = " | ".join(
            fmt(t[k], 1e6)
            for k in (
                "field",
                "gravity",
                "potential_gradient",
                "gravity_gradient",
                "field_vjp",
                "gravity_vjp",
                "potential_gradient_vjp",
                "mj_forward",
            )
        )
        lines.append(
            f"| {m['label']} | {m['dofs']} | {cells} | {ratio(m, 'gravity', 'field'):.2f} | "
            f"{ratio(m, 'gravity', 'mj_forward'):.2f} | {m['agreement']:.1e} |"
        )
    lines.append("")
    return "\n".join(lines)
