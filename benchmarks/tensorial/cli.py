"""`python -m benchmarks.tensorial`, with `--quick` (one three-body chain over 1 s, one round)
and `--report-only`."""

from benchmarks import _output
from benchmarks._mujoco import float64_cpu_run_with_mujoco
from benchmarks._provenance import report_header
from benchmarks.tensorial.measure import member_run
from benchmarks.tensorial.members import members
from benchmarks.tensorial.report import markdown

DESCRIPTION = (
    "Chains of Lagrange gyroscopes: the tensorial Lagrange equations against the Multibody "
    "and MuJoCo."
)
PACKAGES = ("bundledyn", "jax", "jaxlib", "diffrax", "equinox", "mujoco", "numpy")


def measure(quick, repeats):
    horizon = 1.0 if quick else 10.0
    report = report_header(PACKAGES, quick, horizon=horizon, repeats=1 if quick else repeats)
    report["members"] = []
    for member in members(quick):
        print(member["label"], flush=True)
        report["members"].append(member_run(member, horizon, report["repeats"]))
    return report


def main(argv=None):
    parser = _output.parser(DESCRIPTION, "one three-body chain over 1 s")
    parser.add_argument("--repeats", type=int, default=5, help="rounds of alternated timings")
    args = parser.parse_args(argv)
    return _output.run(
        args,
        "tensorial",
        markdown,
        lambda: measure(args.quick, args.repeats),
        ready=float64_cpu_run_with_mujoco,
    )
