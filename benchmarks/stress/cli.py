"""`python -m benchmarks.stress`: `bundledyn.stress.battery()` and `model_battery` on each
shipped model, with `--quick` (the suite's settings, no models) and `--report-only`."""

from benchmarks import _output
from benchmarks._provenance import report_header
from benchmarks._report import provenance_lines
from bundledyn._stress._row import table_cell
from bundledyn.stress import StressReport, StressRow

DESCRIPTION = "The stress battery: hard cases, each against its bound."
MODELS = ("floating_chain.xml", "tree4.xml", "chain5.xml", "arm.urdf")
# A published model with joint springs (gymnasium's, vendored with the tests).
HUMANOID = _output.ROOT / "tests" / "models" / "gymnasium" / "humanoid.xml"
PACKAGES = ("bundledyn", "jax", "jaxlib", "diffrax", "equinox")


def _rows(report):
    return [
        {"case": r.case, "shows": r.shows, "measured": r.measured, "bound": r.bound,
         "note": r.note, "passed": r.passed}
        for r in report.rows
    ]  # fmt: skip


def measure(quick):
    """The battery's rows, and each shipped model's (none with `quick`)."""
    import bundledyn as bd

    bd.use_cpu_xla_flags()
    bd.enable_x64()
    report = report_header(PACKAGES, quick, reports=[])
    batteries = [bd.stress.battery(quick=quick)]
    paths = () if quick else (*(bd.models / name for name in MODELS), HUMANOID)
    for path in paths:
        name = path.name
        batteries.append(bd.stress.model_battery(bd.load_scene(path, passive=True), name))
        print(f"  {name}: {'passed' if batteries[-1].passed else 'FAILED'}", flush=True)
    for battery in batteries:
        report["reports"].append({"model": battery.model, "rows": _rows(battery)})
    return report


def markdown(report):
    """The results as markdown: one table per battery, each row its figure and bound."""
    lines = ["# The stress battery", "", *provenance_lines(report)]
    lines += [
        "Each row: what a hard case measures, the figure, and the bound it must stay within "
        "(`bundledyn stress`, `bundledyn stress MODEL`; each case's docstring in "
        "`bundledyn.stress` cites the peer failure it guards against).",
        "",
    ]
    fields = ("case", "shows", "measured", "bound", "note")
    for battery in report["reports"]:
        rows = tuple(StressRow(*(r[f] for f in fields)) for r in battery["rows"])
        stress = StressReport(battery["model"], rows)
        verdict = "passed" if stress.passed else f"{len(stress.failed)} FAILED"
        lines += [f"## {battery['model']}: {verdict}", "", stress.markdown(), ""]
    return "\n".join(lines)


def main(argv=None):
    parser = _output.parser(DESCRIPTION, "the suite's settings, the shipped cases only")
    args = parser.parse_args(argv)
    where = _output.destination(args, "stress", markdown)
    if where is None:
        return 0
    out, name = where
    report = measure(args.quick)
    text = markdown(report)
    print(text)
    _output.write(out, name, report, text)
    return 0 if all(r["passed"] for b in report["reports"] for r in b["rows"]) else 1


def _nearest_bound(rows):
    """The row whose figure is nearest its bound (relative; a zero bound counts the figure)."""
    return max(rows, key=lambda r: r["measured"] / r["bound"] if r["bound"] else r["measured"])


def summary_table(report):
    """The hard-cases guide's table (docs/how-to/stress.md): each case of the shipped battery and each model, with the row
    nearest its bound."""
    shipped, *models = report["reports"]
    cases = {}
    for r in shipped["rows"]:
        cases.setdefault(r["case"], []).append(r)
    groups = [(f"`{case}`", rows) for case, rows in cases.items()]
    groups += [(f"model `{m['model']}` ({len(m['rows'])} rows)", m["rows"]) for m in models]
    lines = ["| case | its row nearest the bound | measured | bound |", "|---|---|---:|---:|"]
    for name, rows in groups:
        r = _nearest_bound(rows)
        lines.append(
            f"| {name} | {table_cell(r['shows'])} | {r['measured']:.1e} | {r['bound']:.0e} |"
        )
    return "\n".join(lines)
