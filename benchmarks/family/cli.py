"""`python -m benchmarks.family`: the run, `--quick` and `--report-only`."""

from benchmarks import _output
from benchmarks._provenance import report_header

DESCRIPTION = "Speed against MuJoCo over a family of models the benchmark was not tuned on."
RTOLS = tuple(10.0**-k for k in range(3, 13))
DTS = tuple(1e-2 / 2**k for k in range(6))


def measure(quick, repeats):
    """Every member, in order: a list of their measurements. None without MuJoCo."""
    from benchmarks._mujoco import float64_cpu_run_with_mujoco
    from benchmarks.family.measure import HORIZONS, measure_member
    from benchmarks.family.members import members
    from benchmarks.speed.config import PACKAGES

    if not float64_cpu_run_with_mujoco():
        return None
    horizons = (1.0,) if quick else HORIZONS
    rtols, dts = ((1e-4, 1e-8), DTS[:2]) if quick else (RTOLS, DTS)
    report = report_header(PACKAGES, quick, repeats=repeats, horizons=horizons, members=[])
    options = dict(horizons=horizons, rtols=rtols, dts=dts, repeats=repeats)
    for seed, member in enumerate(members(quick)):
        result = measure_member(member, seed, **options)
        report["members"].append(result)
        r = result["ratios"]
        solves = " and ".join(_ratio(x) for x in (r["coarse"], r["fine"]))
        print(
            f"  {member.name}: field {result['field']['ratio']:.2f}× mj_forward; over "
            f"{result['horizon']} s, solves {solves} MuJoCo's time",
            flush=True,
        )
    return report


def _ratio(x):
    if x is None:
        return "unmeasured"
    return "not reached" if x == float("inf") else f"{x:.2f}×"


def main(argv=None):
    from benchmarks.family.report import markdown

    parser = _output.parser(DESCRIPTION, "one small model, 1 s, 2 repeats")
    parser.add_argument("--repeats", type=int, help="timed repeats (default 3; quick 2)")
    args = parser.parse_args(argv)
    where = _output.destination(args, "family", markdown)
    if where is None:
        return 0
    out, name = where
    report = measure(args.quick, args.repeats or (2 if args.quick else 3))
    if report is None:
        return 1
    text = markdown(report)
    print(text)
    _output.write(out, name, report, text)
    return report
