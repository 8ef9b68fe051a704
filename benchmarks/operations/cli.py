"""`python -m benchmarks.operations`: the operations of `simulate`'s and its gradient's
compiled programs over a family of scenes, with `--quick` and `--report-only`."""

import os

from benchmarks import _output
from benchmarks._provenance import report_header
from benchmarks._report import provenance_lines

DESCRIPTION = "Operations in the compiled forward and gradient programs, by scene."
PACKAGES = ("bundledyn", "jax", "jaxlib", "diffrax", "equinox")


def markdown(report):
    """The counts as a markdown table, one row per scene."""
    lines = ["# Operations of the compiled programs", "", *provenance_lines(report)]
    lines += [
        f"`simulate` with its default solver, {report['default_solver']} (rtol = atol = 1e-8, "
        "1 s), and its `jax.grad` through the default adjoint, compiled with XLA's full "
        "optimization; each count is the number of instructions in the optimized program. "
        "A change that leaves these alone has lost no speed; compare them between commits.",
        "",
        "| scene | simulate | jax.grad |",
        "|---|--:|--:|",
    ]
    lines += [f"| {name} | {r['simulate']} | {r['grad']} |" for name, r in report["rows"].items()]
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = _output.parser(DESCRIPTION, "the 3-body chain and its modes only")
    args = parser.parse_args(argv)
    where = _output.destination(args, "operations", markdown)
    if where is None:
        return 0
    out, name = where
    # Users' programs are compiled with every optimization: count those.
    os.environ["JAX_DISABLE_MOST_OPTIMIZATIONS"] = "0"
    import bundledyn as bd
    from benchmarks.operations.count import count
    from bundledyn._simulate import DEFAULT_SOLVER

    bd.use_cpu_xla_flags()
    bd.enable_x64()
    report = report_header(PACKAGES, args.quick, default_solver=DEFAULT_SOLVER.__name__)
    report["rows"] = count(args.quick)
    text = markdown(report)
    print(text)
    _output.write(out, name, report, text)
    return 0
