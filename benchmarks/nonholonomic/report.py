"""The nonholonomic benchmark's markdown: per problem, the time to the first answer, the time
per simulated second member by member, and the agreement, with the issue's targets."""

import statistics

from benchmarks._report import fmt, provenance_lines, versions

TARGETS = {"first": 100.0, "per_second": 10.0, "agreement": 1e-8}


def _ratios(members):
    """sympy's time over bundledyn's, member by member (medians of each)."""
    return [m["sympy"]["median"] / m["bundledyn"]["median"] for m in members]


def problem_summary(problem):
    """The figures judged against the targets: `(first-answer ratio, median and worst
    per-second ratio, worst agreement)`; a ratio above 1 is bundledyn faster."""
    first = problem["first_answer"]
    ratios = _ratios(problem["members"])
    worst_agreement = max(m["agreement"] for m in problem["members"])
    return (
        first["sympy"]["median"] / first["bundledyn"]["median"],
        statistics.median(ratios),
        min(ratios),
        worst_agreement,
    )


def _problem_lines(problem):
    first = problem["first_answer"]
    speedup, median, worst, agreement = problem_summary(problem)
    lines = [
        f"## {problem['name']}",
        "",
        f"Horizon {problem['horizon']:g} s, {len(problem['members'])} members; "
        f"first answer for `{problem['members'][0]['label']}`, {problem['repeats']} cold rounds.",
        "",
        "| time to the first answer (s) | median (min–max) |",
        "|---|---:|",
        f"| sympy: `KanesMethod` and `mass_matrix_full`/`forcing_full` | {fmt(first['derive'], 1)} |",
        f"| sympy: `lambdify` (cse) | {fmt(first['lambdify'], 1)} |",
        f"| sympy: first `DOP853` solve | {fmt(first['solve'], 1)} |",
        f"| **sympy, in all** | {fmt(first['sympy'], 1)} |",
        f"| **bundledyn**: model, trace, compile, solve | {fmt(first['bundledyn'], 1)} |",
        "",
        f"sympy's time over bundledyn's: **{speedup:.2g}×** (target {TARGETS['first']:g}×).",
        "",
        "| member | bundledyn (s per simulated s) | sympy (s per simulated s) | ratio | agreement at rtol 1e-10 | at 1e-12 |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for m, ratio in zip(problem["members"], _ratios(problem["members"]), strict=True):
        lines.append(
            f"| {m['label']} | {fmt(m['bundledyn'], 1)} | {fmt(m['sympy'], 1)} | "
            f"{ratio:.3g}× | {m['agreement']:.1e} | {m['agreement_tight']:.1e} |"
        )
    lines += [
        "",
        f"Per simulated second, sympy's time over bundledyn's: median **{median:.3g}×**, worst "
        f"**{worst:.3g}×** (target {TARGETS['per_second']:g}×). Largest disagreement at "
        f"rtol 1e-10: **{agreement:.1e}** (target {TARGETS['agreement']:g}).",
        "",
    ]
    return lines


def markdown(report):
    """The results as markdown."""
    lines = ["# Rolling bodies against sympy.physics.mechanics", "", *provenance_lines(report)]
    lines += [f"Packages: {versions(report['environment'])}.", ""]
    lines += [
        "The peer is what a sympy user runs: `KanesMethod` with velocity constraints and "
        "dependent speeds, `lambdify` with common subexpressions, scipy's `DOP853`; bundledyn "
        "runs `RollingMode` (the disc, `simulate`'s `RKMK87`), `WhippleBicycle` "
        "(`NonholonomicTerm`, diffrax's `Dopri8`) and the same bicycle as a tree on two "
        "rolling wheels (the shipped scene `bicycle.toml`, `RollingWheelMode`, `simulate`'s "
        "`RKMK87`). Both at rtol = atol = 1e-10; times per "
        "simulated second in alternation, the first answer cold (`benchmarks/nonholonomic`).",
        "",
    ]
    for problem in report["problems"]:
        lines += _problem_lines(problem)
    return "\n".join(lines)
