"""`python -m benchmarks.family`: the run, `--quick`, `--only` and `--report-only`."""

import json
import os

from benchmarks import _output
from benchmarks._provenance import report_header

DESCRIPTION = "Speed against MuJoCo over a family of models the benchmark was not tuned on."
RTOLS = tuple(10.0**-k for k in range(2, 13))
DTS = tuple(1e-2 / 2**k for k in range(6))
# The parts a run measures: the field and solves against MuJoCo, and the gradients.
PARTS = ("mujoco", "gradient")


def one_core():
    """Run this process on one core, as MuJoCo runs on one thread; before JAX starts.

    XLA's CPU client sizes its thread pools by the cores a process may use, and on
    bundledyn's many small kernels handing work between pool threads costs more than it
    gains: measured on 2 cores, the 20-body mixed tree's field 45 µs free and 36 µs on one
    core, its 2 s solve 114 ms and 64 ms (the 5-ball tree's field 11.7 µs either way)."""
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})


def measure(quick, repeats, parts=PARTS, previous=None):
    """Every member, in order, in a report; None without MuJoCo. A run of some `parts`
    only keeps what `previous` (the report already written, if any) holds of the others."""
    from benchmarks._mujoco import float64_cpu_run_with_mujoco
    from benchmarks.family.gradient import gradient_header, gradient_member
    from benchmarks.family.measure import HORIZONS, measure_member
    from benchmarks.family.members import members
    from benchmarks.speed.config import PACKAGES

    one_core()
    if not float64_cpu_run_with_mujoco():
        return None
    horizons = (1.0,) if quick else HORIZONS
    rtols, dts = ((1e-4, 1e-8), DTS[:2]) if quick else (RTOLS, DTS)
    fresh = report_header(PACKAGES, quick, repeats=repeats, horizons=horizons, members=[])
    report, known = kept(fresh, previous, parts)
    if "gradient" in parts:
        report["gradient"] = gradient_header(PACKAGES, repeats, horizons)
    for seed, member in enumerate(members(quick)):
        entry = known.get(member.name)
        if "mujoco" in parts:
            gradient = {"gradient": entry["gradient"]} if entry and "gradient" in entry else {}
            options = dict(horizons=horizons, rtols=rtols, dts=dts, repeats=repeats)
            entry = measure_member(member, seed, **options) | gradient
            print(f"  {member.name}: {_mujoco_line(entry)}", flush=True)
        if "gradient" in parts:
            entry = gradient_member(member, seed, entry, horizons=horizons, repeats=repeats)
            print(f"  {member.name}: {_gradient_line(entry)}", flush=True)
        report["members"].append(entry)
    return report


def kept(fresh, previous, parts):
    """`(report, {name: member entry})` that a run of `parts` adds to: `previous` and its
    members where the run measures the gradients only (and `previous` has the same
    horizons), else `fresh`, with `previous`'s gradient part where the run measures no
    gradients."""
    if previous is None or previous["horizons"] != list(fresh["horizons"]):
        return fresh, {}
    known = {m["name"]: m for m in previous["members"]}
    if "mujoco" in parts:
        if "gradient" not in parts and "gradient" in previous:
            fresh["gradient"] = previous["gradient"]
        return fresh, known
    return previous | {"members": []}, known


def _mujoco_line(entry):
    r = entry["ratios"]
    solves = " and ".join(_ratio(x) for x in (r["coarse"], r["fine"]))
    return (
        f"field {entry['field']['ratio']:.2f}× mj_forward; over {entry['horizon']} s, "
        f"solves {solves} MuJoCo's time"
    )


def _gradient_line(entry):
    g = entry["gradient"]
    if g is None:
        return "no predictable horizon: gradients unmeasured"
    r = g["ratios"]
    grads = ", ".join(f"{name} {_ratio(r[name])}" for name in g["adjoints"])
    return (
        f"over {entry['horizon']} s, gradient / forward: {grads}; "
        f"field VJP {_ratio(r['field_vjp'])}, step VJP {_ratio(r['step_vjp'])}"
    )


def _ratio(x):
    if x is None:
        return "unmeasured"
    return "not reached" if x == float("inf") else f"{x:.2f}×"


def _previous(path):
    return json.loads(path.read_text()) if path.exists() else None


def main(argv=None):
    from benchmarks.family.report import markdown

    parser = _output.parser(DESCRIPTION, "one small model, 1 s, 2 repeats")
    parser.add_argument("--repeats", type=int, help="timed repeats (default 3; quick 2)")
    parser.add_argument(
        "--only",
        choices=PARTS,
        help="measure one part (mujoco: the field and solves against MuJoCo; gradient: "
        "the gradients and VJPs) and keep the other from the results JSON already there",
    )
    args = parser.parse_args(argv)
    where = _output.destination(args, "family", markdown)
    if where is None:
        return 0
    out, name = where
    parts = (args.only,) if args.only else PARTS
    previous = _previous(out / f"{name}.json") if args.only else None
    report = measure(args.quick, args.repeats or (2 if args.quick else 3), parts, previous)
    if report is None:
        return 1
    text = markdown(report)
    print(text)
    _output.write(out, name, report, text)
    return report
