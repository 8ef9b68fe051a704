"""`family.md`: each target's worst case over the family beside its median, then every
member's figures; redrawn from `family.json` alone (`--report-only`)."""

import statistics

from benchmarks._report import fmt, provenance_lines
from benchmarks.family.measure import FINE_ERROR
from benchmarks.speed.report import measured

# The targets: (key, what, limit), `what` of a run of `t1` seconds.
TARGETS = (
    ("field", "one field evaluation / mj_forward", 5.0),
    ("coarse", "{t1:g} s at MuJoCo RK4 dt = 1e-2's error: RKMK87 / MuJoCo time", 1.0),
    ("fine", f"{{t1:g}} s at error {FINE_ERROR:.0e}: RKMK87 / MuJoCo RK4 time", 0.5),
)


def value(member, key):
    """A member's figure for target `key` (None where its sweep did not reach the error)."""
    return member["field"]["ratio"] if key == "field" else member["ratios"][key]


def target_rows(report):
    """Per target: (what, median, worst, worst member, limit, met by the worst, members
    measured); median and worst are None where no member's sweeps reached the error, and
    a target is met only when every member was measured."""
    rows = []
    for key, what, limit in TARGETS:
        what = what.format(t1=report["t1"])
        pairs = [(value(m, key), m["name"]) for m in report["members"]]
        measured_ = [(v, name) for v, name in pairs if v is not None]
        if not measured_:
            rows.append((what, None, None, "–", limit, False, 0))
            continue
        worst, name = max(measured_)
        median = statistics.median(v for v, _ in measured_)
        met = worst <= limit and len(measured_) == len(pairs)
        rows.append((what, median, worst, name, limit, met, len(measured_)))
    return rows


def _cell(x, digits=3):
    return "not reached" if x is None else f"{x:.{digits}g}"


def markdown(report):
    """The whole report."""
    env = report["environment"]
    n = len(report["members"])
    lines = [
        "# Speed over a family of models",
        "",
        *provenance_lines(report),
        measured(report, env["machine"]) + f" Models: {n} (`benchmarks/family/members.py`), "
        f"float64, CPU, {report['t1']:g} s solves; every ratio is of times taken in "
        "alternation in this run.",
        "",
        "## Targets: the worst case over the family",
        "",
        "| target | median | worst | worst model | limit | met | models |",
        "|---|--:|--:|---|--:|:-:|--:|",
    ]
    for what, median, worst, name, limit, met, count in target_rows(report):
        lines.append(
            f"| {what} | {_cell(median)} | {_cell(worst)} | {name} | {limit:g} "
            f"| {'yes' if met else 'no'} | {count} of {n} |"
        )
    lines += [
        "",
        "## Every model",
        "",
        "Field: µs per evaluation, median (min–max), and its ratio to `mj_forward`'s. "
        "Solves: bundledyn's time over MuJoCo's at MuJoCo's error with dt = 1e-2 (that "
        f"error in brackets) and at {FINE_ERROR:.0e}, each interpolated log–log on its sweep.",
        "",
        "| model | dofs | field [µs] | / mj_forward | at dt = 1e-2's error | at "
        f"{FINE_ERROR:.0e} |",
        "|---|--:|--:|--:|--:|--:|",
    ]
    for m in report["members"]:
        r = m["ratios"]
        lines.append(
            f"| {m['name']} | {m['dofs']} | {fmt(m['field']['field'], 1e6)} "
            f"| {m['field']['ratio']:.3g} | {_cell(r['coarse'])} ({r['coarse_error']:.1e}) "
            f"| {_cell(r['fine'])} |"
        )
    return "\n".join(lines) + "\n"
