"""`python -m benchmarks.nonholonomic`, with `--quick` (one member of each problem over half
a second, one cold round) and `--report-only`."""

import numpy as np

from benchmarks import _output
from benchmarks._provenance import report_header
from benchmarks.nonholonomic import bicycle, bicycle_tree, disc
from benchmarks.nonholonomic.measure import first_answers, member_runs, model_sides
from benchmarks.nonholonomic.report import markdown

DESCRIPTION = (
    "Rolling bodies (the leaning disc, the Whipple bicycle, the bicycle as a tree) against "
    "sympy's KanesMethod."
)
PACKAGES = ("bundledyn", "jax", "jaxlib", "diffrax", "equinox", "sympy", "scipy", "numpy")
PROBLEMS = (disc, bicycle, bicycle_tree)


def measure(quick, repeats):
    """Both problems' figures (`measure.first_answers`, `measure.member_runs`)."""
    import jax

    import bundledyn as bd

    bd.use_cpu_xla_flags()
    bd.enable_x64()
    # Every first answer compiles from scratch: no programs from an on-disk cache.
    jax.config.update("jax_enable_compilation_cache", False)
    horizon = 0.5 if quick else 5.0
    ts = np.linspace(0.0, horizon, 6 if quick else 51)
    report = report_header(PACKAGES, quick, problems=[])
    for problem in PROBLEMS:
        members = problem.members(quick)
        print(f"{problem.NAME}:", flush=True)
        sides = {m["variant"]: model_sides(problem, m["variant"]) for m in members}
        first = members[0]
        report["problems"].append({
            "name": problem.NAME,
            "horizon": horizon,
            "repeats": 1 if quick else repeats,
            "first_answer": first_answers(
                problem, first, sides[first["variant"]], ts, 1 if quick else repeats
            ),
            "members": member_runs(problem, members, sides, ts, repeats),
        })  # fmt: skip
    return report


def main(argv=None):
    parser = _output.parser(DESCRIPTION, "one member of each problem, half a second")
    parser.add_argument("--repeats", type=int, default=3, help="cold rounds and timed runs")
    args = parser.parse_args(argv)
    return _output.run(args, "nonholonomic", markdown, lambda: measure(args.quick, args.repeats))
