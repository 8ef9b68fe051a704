"""`family.md`: each target's worst case over the family beside its median, then every
member's figures; redrawn from `family.json` alone (`--report-only`). Each part of the
run (`cli.PARTS`) has its targets and columns where the JSON holds it."""

import statistics

from benchmarks._report import fmt, provenance_lines
from benchmarks.family.gradient import DEFAULT, LIMITS
from benchmarks.family.measure import FINE_ERROR, REFERENCE_AGREEMENT, SOLVERS, ratio_key
from benchmarks.speed.report import measured

# The targets against MuJoCo: (key, what, limit); the solves' for each solver swept.
TARGETS = (
    ("field", "one field evaluation / mj_forward", 5.0),
    *(
        (ratio_key(solver, part), f"solve to {error}: {solver} / MuJoCo RK4 time", limit)
        for solver in SOLVERS
        for part, error, limit in (
            ("coarse", "MuJoCo RK4 dt = 1e-2's error", 1.0),
            ("fine", f"an error of {FINE_ERROR:.0e}", 0.5),
        )
    ),
)


def adjoint_label(report, name):
    """How the report names adjoint `name` of the gradient part."""
    if name != DEFAULT:
        return name
    named = report["gradient"]["default_adjoint"]
    return "simulate's default" + (f" ({named})" if named else "")


def gradient_targets(report):
    """The gradient part's targets, `(key, what, limit)`: per adjoint, and the VJPs."""
    if "gradient" not in report:
        return ()
    return (
        *(
            (name, f"gradient / forward solve, {adjoint_label(report, name)}", LIMITS["grad"])
            for name in report["gradient"]["adjoints"]
        ),
        ("field_vjp", "body field's VJP / body field (one stage)", LIMITS["vjp"]),
        ("step_vjp", "RKMK87 step's VJP / step", LIMITS["vjp"]),
    )


def has_mujoco(report):
    """Whether the report holds the part against MuJoCo (a gradient-only run's does not)."""
    return any("field" in m for m in report["members"])


def value(member, key):
    """A member's figure for target `key` (None where its sweep did not reach the error,
    or it was not measured)."""
    if key == "field" or key in member.get("ratios", {}):
        if "field" not in member:
            return None
        return member["field"]["ratio"] if key == "field" else member["ratios"][key]
    return (member.get("gradient") or {}).get("ratios", {}).get(key)


def target_rows(report):
    """Per target: (what, median, worst, worst member, limit, met by the worst, members
    measured). A member whose motion is unpredictable over every horizon, or whose MuJoCo
    sweep does not reach the error, or whose adjoint fails, is not measured; one whose
    bundledyn sweep does not reach it counts as infinite."""
    rows = []
    targets = (TARGETS if has_mujoco(report) else ()) + gradient_targets(report)
    for key, what, limit in targets:
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
        *gradient_provenance(report),
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
        *(MUJOCO_COLUMNS_TEXT if has_mujoco(report) else []),
        *(gradient_text(report) if "gradient" in report else []),
        *table(report, columns(report)),
        *failures(report),
    ]
    return "\n".join(lines) + "\n"


MUJOCO_COLUMNS_TEXT = [
    "Field: µs per evaluation, median (min–max), and its ratio to `mj_forward`'s. "
    "Solves, over the horizon (the reference's agreement in brackets): bundledyn's time "
    f"with its default solver ({SOLVERS[0]}), then with "
    f"{', '.join(SOLVERS[1:])}, over MuJoCo's at MuJoCo's error with dt = 1e-2 (that "
    f"error in brackets) and at {FINE_ERROR:.0e}, each interpolated log–log on its sweep "
    "(rtol 1e-2 to 1e-12, atol = rtol / 100); “not reached”: bundledyn's sweep does not "
    "reach the error; “–”: MuJoCo's (dt to 1e-2/32) does not, or no horizon is "
    "predictable.",
    "",
]


def gradient_provenance(report):
    """Where the gradients were measured apart (`--only gradient`): their code and run."""
    g = report.get("gradient")
    if g is None or g["provenance"] == report["provenance"]:
        return []
    return [
        *provenance_lines(g, what="The gradients were measured apart. Code"),
        measured(g, g["environment"]["machine"]),
        "",
    ]


def gradient_text(report):
    """The gradient part's settings and columns."""
    g = report["gradient"]
    adjoints = ", ".join(adjoint_label(report, name) for name in g["adjoints"])
    return [
        "Gradients, over the horizon: `jax.grad` of |p(t1)|² + |q(t1)|² (the base's final "
        "position and the final shape) with respect to the initial base twist, with "
        f"bundledyn's default solver ({g['solver']}) at rtol {g['rtol']:.0e} (atol "
        f"{g['atol']:.0e}), over the forward solve (the loss) timed in alternation with it "
        f"(forward: ms, median): for {adjoints}; “–”: the adjoint failed (below) or no "
        "horizon is predictable. VJPs in compiled loops: the body field the stages "
        "evaluate (`SceneTerm.body_vf`) and one RKMK87 step at the solve's mean step, "
        "each over itself, their VJPs as the default adjoint takes them (the field's "
        "written-out reverse pass, the field's values at the stages kept by the forward "
        "solve, so that the field's VJP is that pass alone).",
        "",
    ]


def columns(report):
    """The per-model table's columns, `(header, alignment, cell(member))`, of the parts
    the report holds."""
    mujoco, gradient = has_mujoco(report), "gradient" in report
    cols = [("model", "---", lambda m: m["name"]), ("dofs", "--:", lambda m: str(m["dofs"]))]
    if mujoco:
        cols += [
            ("field [µs]", "--:", lambda m: fmt(m["field"]["field"], 1e6) if "field" in m else "–"),
            (
                "/ mj_forward",
                "--:",
                lambda m: f"{m['field']['ratio']:.3g}" if "field" in m else "–",
            ),
        ]
    cols.append(("horizon [s] (agreement)", "--:", _horizon))
    if mujoco:
        cols += [
            ("at dt = 1e-2's error", "--:", _coarse),
            (f"at {FINE_ERROR:.0e}", "--:", lambda m: _cell(value(m, "fine"))),
        ]
        cols += [
            (f"{solver} at {error}", "--:", _ratio_cell(ratio_key(solver, part)))
            for solver in SOLVERS[1:]
            for part, error in (("coarse", "dt = 1e-2's error"), ("fine", f"{FINE_ERROR:.0e}"))
        ]
    if gradient:
        cols.append(("forward [ms]", "--:", _forward))
        cols += [
            (f"grad: {name}", "--:", lambda m, k=name: _cell(value(m, k)))
            for name in report["gradient"]["adjoints"]
        ]
        cols += [
            (f"{unit} VJP / {unit}", "--:", lambda m, k=f"{unit}_vjp": _cell(value(m, k)))
            for unit in ("field", "step")
        ]
    return cols


def table(report, cols):
    """The per-model table's lines."""
    lines = [
        "| " + " | ".join(header for header, _, _ in cols) + " |",
        "|" + "|".join(align for _, align, _ in cols) + "|",
    ]
    for m in report["members"]:
        lines.append("| " + " | ".join(cell(m) for _, _, cell in cols) + " |")
    return lines


def failures(report):
    """The adjoints that failed, and why."""
    lines = [
        f"- {m['name']}, {name}: {result['error']}"
        for m in report["members"]
        for name, result in ((m.get("gradient") or {}).get("adjoints") or {}).items()
        if "error" in result
    ]
    return ["", "Failed adjoints:", "", *lines] if lines else []


def _horizon(m):
    horizon = "none" if m["horizon"] is None else f"{m['horizon']:g}"
    return f"{horizon} ({m['reference_agreement']:.0e})"


def _ratio_cell(key):
    return lambda m: _cell(value(m, key))


def _coarse(m):
    if "ratios" not in m or m["ratios"]["coarse_error"] is None:
        return "–"
    r = m["ratios"]
    return f"{_cell(r['coarse'])} ({r['coarse_error']:.1e})"


def _forward(m):
    g = m.get("gradient")
    return "–" if not g else f"{g['forward']['median'] * 1e3:.3g}"
