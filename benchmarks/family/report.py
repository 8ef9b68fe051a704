"""`family.md`: each target's worst case over the family beside its median, then every
member's figures; redrawn from `family.json` alone (`--report-only`)."""

import statistics

from benchmarks._report import fmt, provenance_lines
from benchmarks.family.measure import FINE_ERROR, REFERENCE_AGREEMENT
from benchmarks.speed.report import measured

# The targets: (key, what, limit).
TARGETS = (
    ("field", "one field evaluation / mj_forward", 5.0),
    ("coarse", "solve to MuJoCo RK4 dt = 1e-2's error: RKMK87 / MuJoCo time", 1.0),
    ("fine", f"solve to an error of {FINE_ERROR:.0e}: RKMK87 / MuJoCo RK4 time", 0.5),
)


def value(member, key):
    """A member's figure for target `key` (None where its sweep did not reach the error)."""
    return member["field"]["ratio"] if key == "field" else member["ratios"][key]


def target_rows(report):
    """Per target: (what, median, worst, worst member, limit, met by the worst, members
    measured). A member whose motion is unpredictable over every horizon, or whose MuJoCo
    sweep does not reach the error, is not measured; one whose bundledyn sweep does not
    reach it counts as infinite."""
    rows = []
    for key, what, limit in TARGETS:
        pairs = [(value(m, key), m["name"]) for m in report["members"]]
        measured_ = [(v, name) for v, name in pairs if v is not None]
        if not measured_:
            rows.append((what, None, None, "–", limit, False, 0))
            continue
        worst, name = max(measured_)
        median = statistics.median(v for v, _ in measured_)
        met = worst <= limit
        rows.append((what, median, worst, name, limit, met, len(measured_)))
    return rows


def _cell(x, digits=3):
    if x is None:
        return "–"
    return "not reached" if x == float("inf") else f"{x:.{digits}g}"


def markdown(report):
    """The whole report."""
    env = report["environment"]
    n = len(report["members"])
    lines = [
        "# Speed over a family of models",
        "",
        *provenance_lines(report),
        measured(report, env["machine"]) + f" Models: {n} (`benchmarks/family/members.py`), "
        "float64, CPU; every ratio is of times taken in alternation in this run. Each "
        "model is solved over its predictable horizon: the longest of "
        + ", ".join(f"{h:g}" for h in report["horizons"])
        + f" s over which RKMK87 and diffrax's Dopri8, both at rtol 1e-13, agree to "
        f"{REFERENCE_AGREEMENT:.0e} (RKMK87's state there is the reference); over 10 s "
        "many of them are chaotic, and a final state's error would measure nothing.",
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
        "Solves, over the horizon (the reference's agreement in brackets): bundledyn's time "
        "over MuJoCo's at MuJoCo's error with dt = 1e-2 (that error in brackets) and at "
        f"{FINE_ERROR:.0e}, each interpolated log–log on its sweep; “not reached”: "
        "bundledyn's sweep (rtol to 1e-12) does not reach the error; “–”: MuJoCo's "
        "(dt to 1e-2/32) does not, or no horizon is predictable.",
        "",
        "| model | dofs | field [µs] | / mj_forward | horizon [s] (agreement) "
        f"| at dt = 1e-2's error | at {FINE_ERROR:.0e} |",
        "|---|--:|--:|--:|--:|--:|--:|",
    ]
    for m in report["members"]:
        r = m["ratios"]
        horizon = "none" if m["horizon"] is None else f"{m['horizon']:g}"
        coarse = (
            "–" if r["coarse_error"] is None else f"{_cell(r['coarse'])} ({r['coarse_error']:.1e})"
        )
        lines.append(
            f"| {m['name']} | {m['dofs']} | {fmt(m['field']['field'], 1e6)} "
            f"| {m['field']['ratio']:.3g} | {horizon} ({m['reference_agreement']:.0e}) "
            f"| {coarse} | {_cell(r['fine'])} |"
        )
    return "\n".join(lines) + "\n"
