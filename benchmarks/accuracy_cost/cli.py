"""`python -m benchmarks.accuracy_cost`: the sweep, `--report-only` and `--extras-only`
(see the package's docstring)."""

import json

from benchmarks import _output
from benchmarks._provenance import environment, provenance, report_header
from benchmarks.accuracy_cost.problems import PROBLEMS

DESCRIPTION = "What accuracy costs in time: work–precision of every solver, with peers."
NAME = "accuracy_cost"
PACKAGES = (
    "bundledyn",
    "jax",
    "jaxlib",
    "diffrax",
    "equinox",
    "numpy",
    "scipy",
    "mujoco",
    "matplotlib",
)
MUJOCO_STEPS = (100, 200, 400, 800, 1600, 3200, 6400, 12800)
SCIPY_RTOLS = (1e-4, 1e-6, 1e-8, 1e-10)


def measure_problem(name, quick, repeats, default):
    """One problem's reference, every method's sweep (`default` first) and, on the chain,
    the peers; each adaptive series with its cost per extra digit."""
    from benchmarks.accuracy_cost.peers import mujoco_peer, scipy_peer
    from benchmarks.accuracy_cost.sweep import METHODS, methods_for, reference, sweep

    problem = PROBLEMS[name]()
    print(problem.title, flush=True)
    ref, agreement = reference(problem)
    print(f"  reference agreement (RKMK54 vs Dopri8): {agreement:.1e}", flush=True)
    methods = methods_for(problem, quick, default)
    series = [sweep(problem, METHODS[m], ref, quick, repeats) for m in methods]
    if name == "chain" and not quick:
        series += mujoco_peer(problem, ref, repeats, MUJOCO_STEPS)
        series += scipy_peer(problem, ref, repeats, SCIPY_RTOLS)
    return fit_digits(
        {"name": name, "title": problem.title, "reference_agreement": agreement, "series": series}
    )


def fit_digits(result):
    """`result` with each adaptive series' cost per extra digit (`digits.digit_cost`)."""
    from benchmarks.accuracy_cost.digits import digit_cost

    for series in result["series"]:
        if not series["fixed"]:
            series["per_digit"] = digit_cost(series, result["reference_agreement"])
    return result


def measure_extras(report, repeats):
    """Throughput, gradient cost and compile time against bodies, on the chain."""
    from benchmarks.accuracy_cost.extras import compile_times, gradient_cost, throughput

    chain = PROBLEMS["chain"]()
    print("throughput, gradients, compile times", flush=True)
    report["extras_environment"] = environment(PACKAGES)
    report["throughput"] = throughput(chain, (1, 64, 1024), repeats)
    report["gradients"] = gradient_cost(chain, repeats)
    report["compile"] = compile_times((1, 2, 5, 10, 20))


def write_report(report, out):
    from benchmarks.accuracy_cost.report import markdown

    _output.write(out, _output.stem(NAME, report["quick"]), report, markdown(report))


def redraw(out, quick):
    """Costs per digit, diagrams and markdown again from a results JSON, without measuring
    anything."""
    from benchmarks.accuracy_cost.report import plot

    report = json.loads((out / f"{_output.stem(NAME, quick)}.json").read_text())
    for result in report["problems"]:
        fit_digits(result)
        result["figure"] = plot(result, out / f"{NAME}_{result['name']}.png")
    write_report(report, out)
    return report


def main(argv=None):
    parser = _output.parser(DESCRIPTION, "one scene, three or four points per method")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--problems", nargs="*", help="subset of " + ", ".join(PROBLEMS))
    parser.add_argument(
        "--extras-only",
        action="store_true",
        help="measure throughput, gradient cost and compile times into the existing JSON",
    )
    args = parser.parse_args(argv)
    import bundledyn as bd
    from benchmarks.accuracy_cost.report import plot
    from benchmarks.accuracy_cost.sweep import default_solver

    bd.enable_x64()
    out = _output.folder(args.out, args.quick, NAME, args.report_only)
    if args.report_only:
        return redraw(out, args.quick)
    if args.extras_only:
        report = json.loads((out / f"{NAME}.json").read_text())
        report["provenance"] = provenance()
        measure_extras(report, args.repeats)
        write_report(report, out)
        return report
    names = args.problems or (["dzhanibekov"] if args.quick else list(PROBLEMS))
    out.mkdir(parents=True, exist_ok=True)
    default = default_solver().__name__
    report = report_header(PACKAGES, args.quick, default_solver=default, problems=[])
    for name in names:
        result = measure_problem(name, args.quick, args.repeats, default)
        result["figure"] = plot(result, out / f"{NAME}_{name}.png")
        report["problems"].append(result)
        write_report(report, out)  # after every scene: a long run keeps what it measured
    if not args.quick and args.problems is None:
        measure_extras(report, args.repeats)
        write_report(report, out)
    return report
