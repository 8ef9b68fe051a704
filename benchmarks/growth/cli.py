"""`python -m benchmarks.growth`, with `--quick` (two small trees, two rounds, a short
horizon) and `--report-only`."""

from benchmarks import _output
from benchmarks._mujoco import float64_cpu_run_with_mujoco
from benchmarks._provenance import report_header

DESCRIPTION = "How the field's cost grows with the bodies, from 10 to 150, against MuJoCo's."
PACKAGES = ("bundledyn", "jax", "jaxlib", "diffrax", "equinox", "mujoco", "numpy")
HORIZON = 0.2  # seconds of motion under the gradient, as the survey's for its large models


def measure(quick, repeats):
    """Every member, in order, in a report."""
    from benchmarks.accuracy_cost.sweep import default_solver
    from benchmarks.family.cli import one_core
    from benchmarks.growth.measure import member_run
    from benchmarks.growth.members import members

    one_core()
    t1 = 0.05 if quick else HORIZON
    repeats = 2 if quick else repeats
    report = report_header(
        PACKAGES, quick, repeats=repeats, horizon=t1, solver=default_solver().__name__, members=[]
    )
    for member in members(quick):
        entry = member_run(member, repeats, t1)
        report["members"].append(entry)
        print(f"  {member.name}: {_line(entry)}", flush=True)
    return report


def _line(entry):
    times = entry["times"]
    gradient = entry["gradient"] or {}
    return (
        f"{entry['dofs']} DoF, depth {entry['depth']}, metric {entry['metric_error']:.1e}, "
        f"field {times['field']['median'] * 1e6:.1f} µs "
        f"({times['field']['median'] / times['mj_forward']['median']:.2f}x mj_forward), "
        f"dense {times['dense']['median'] * 1e6:.1f} µs, grad/forward "
        f"{gradient.get('ratio', float('nan')):.2f}"
    )


def main(argv=None):
    from benchmarks.growth.plot import draw
    from benchmarks.growth.report import markdown

    parser = _output.parser(DESCRIPTION, "two small trees, two rounds, 0.05 s")
    parser.add_argument("--repeats", type=int, default=5, help="rounds of alternated timings")
    args = parser.parse_args(argv)
    return _output.run(
        args,
        "growth",
        markdown,
        lambda: measure(args.quick, args.repeats),
        ready=float64_cpu_run_with_mujoco,
        draw=draw,
    )
