"""`python -m benchmarks.gravity`, with `--quick` (the family's first tree, two rounds) and
`--report-only`."""

from benchmarks import _output
from benchmarks._mujoco import float64_cpu_run_with_mujoco
from benchmarks._provenance import report_header
from benchmarks.gravity.members import members
from benchmarks.gravity.report import markdown

DESCRIPTION = "What uniform gravity costs in the field, against the field alone and mj_forward."
PACKAGES = ("bundledyn", "jax", "jaxlib", "diffrax", "equinox", "mujoco", "numpy")


def measure(quick, repeats):
    from benchmarks.gravity.measure import member_run
    from bundledyn._simulate import DEFAULT_SOLVER

    report = report_header(PACKAGES, quick, repeats=2 if quick else repeats)
    report["default_solver"] = DEFAULT_SOLVER.__name__
    report["stages"] = DEFAULT_SOLVER().tableau.step_stages
    report["members"] = []
    for member in members(quick):
        print(member.name, flush=True)
        report["members"].append(member_run(member, report["repeats"]))
    return report


def main(argv=None):
    parser = _output.parser(DESCRIPTION, "the family's first tree, two rounds")
    parser.add_argument("--repeats", type=int, default=7, help="rounds of alternated timings")
    args = parser.parse_args(argv)
    return _output.run(
        args,
        "gravity",
        markdown,
        lambda: measure(args.quick, args.repeats),
        ready=float64_cpu_run_with_mujoco,
    )
