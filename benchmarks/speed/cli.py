"""`python -m benchmarks.speed`: the full run, its workers, `--report-only` and
`--device-batch` (see the package's docstring)."""

import argparse
import json
import os
import sys

from benchmarks import _output
from benchmarks._provenance import report_header
from benchmarks._timing import run_worker

DESCRIPTION = "Speed against MuJoCo, measured in one run on the same MJCF model."


def worker(ns, repeats, batch_settings, batch_t1):
    """Parts 1, 3 and 4 under this process's XLA flags (`batch_settings`: method → setting), with
    MuJoCo's side of parts 1 and 3 timed in alternation with bundledyn's."""
    import bundledyn as bd
    from benchmarks.speed.batch import batch_throughput
    from benchmarks.speed.compile import compile_costs
    from benchmarks.speed.field import field_cost

    bd.enable_x64()
    out = {"xla_flags": os.environ.get("XLA_FLAGS", ""), "field": {}}
    for n in ns:
        out["field"][str(n)] = field_cost(n, repeats)
        print(
            f"  field n={n}: {out['field'][str(n)]['per_evaluation']['median'] * 1e6:.1f} us",
            file=sys.stderr,
            flush=True,
        )
    out["batch"], (out["mujoco_batch"],), out["mjx_batch"] = batch_throughput(
        batch_settings, batch_t1, repeats, split=(1, 2), with_mjx=True
    )
    out["compile"] = compile_costs(tuple(dict.fromkeys((5, ns[-1]))))
    return out


def measure(quick, repeats):
    """The CPU run: parts 2, 3's calibration, 1's MuJoCo step and 5 here, 5b in a process
    of its own, parts 1, 3 and 4 in a worker per XLA setting. None without MuJoCo."""
    import bundledyn as bd
    from benchmarks._mujoco import float64_cpu_run_with_mujoco
    from benchmarks.speed.batch import batch_calibration
    from benchmarks.speed.chain import chain_ten_seconds
    from benchmarks.speed.config import MEMORY_STEPS, PACKAGES
    from benchmarks.speed.field import mujoco_rk4_step
    from benchmarks.speed.gradient import gradient_cost

    if not float64_cpu_run_with_mujoco():
        return None
    ns = (1, 2, 5) if quick else (1, 5, 10, 20)
    report = report_header(PACKAGES, quick, repeats=repeats)
    print("part 2: chain", flush=True)
    report["chain"] = chain_ten_seconds(repeats, quick)
    batch_t1 = 0.2 if quick else 1.0
    print("part 3: batch settings", flush=True)
    report["batch_calibration"] = batch_calibration(batch_t1, quick)
    report["batch_setting"] = {
        method: c["setting"] for method, c in report["batch_calibration"]["methods"].items()
    }
    print("part 1: MuJoCo", flush=True)
    report["mujoco_field"] = {str(n): mujoco_rk4_step(n, repeats) for n in ns}
    print("part 5: gradients", flush=True)
    report["gradient"] = gradient_cost(repeats, report["chain"]["t1"])
    steps = 1000 if quick else MEMORY_STEPS
    report["memory"] = run_worker("benchmarks.speed", "memory", [str(steps)], bd.CPU_XLA_FLAGS)
    report["settings"] = {}
    for key, flags in (("bundledyn", bd.CPU_XLA_FLAGS), ("xla_defaults", ())):
        print(f"parts 1, 3, 4 with {key}", flush=True)
        worker_args = [
            ",".join(map(str, ns)),
            str(repeats),
            json.dumps(report["batch_setting"]),
            str(batch_t1),
        ]
        report["settings"][key] = run_worker("benchmarks.speed", "worker", worker_args, flags)
    return report


def redraw(out, quick):
    """`--report-only`: the markdown of the CPU run and of the device runs in `out` again
    from their JSON."""
    from benchmarks.speed.device import device_markdown
    from benchmarks.speed.report import markdown

    name = _output.stem("speed", quick)
    (out / f"{name}.md").write_text(markdown(json.loads((out / f"{name}.json").read_text())))
    for path in out.glob("speed_*.json"):
        if path.stem != name and path.stem.endswith("_quick") == quick:
            path.with_suffix(".md").write_text(device_markdown(json.loads(path.read_text())))


def main(argv=None):
    parser = _output.parser(DESCRIPTION, "small sizes, 2 repeats")
    parser.add_argument("--repeats", type=int, help="timed repeats (default 5; quick 2)")
    parser.add_argument(
        "--device-batch",
        action="store_true",
        help="part 3 only, on JAX's default device (a GPU), at the settings of --out's "
        "speed.json (else the committed one); writes speed_<platform>.{md,json}",
    )
    parser.add_argument("--worker", nargs=4, help=argparse.SUPPRESS)
    parser.add_argument("--memory", nargs=1, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    repeats = args.repeats or (2 if args.quick else 5)
    if args.worker:
        ns = [int(n) for n in args.worker[0].split(",")]
        batch_settings, t1 = json.loads(args.worker[2]), float(args.worker[3])
        print(json.dumps(worker(ns, int(args.worker[1]), batch_settings, t1)))
        return 0
    if args.memory:
        import bundledyn as bd
        from benchmarks.speed.gradient import gradient_memory

        bd.enable_x64()
        print(json.dumps(gradient_memory(int(args.memory[0]))))
        return 0
    out = _output.folder(args.out, args.quick, "speed", args.report_only)
    if args.report_only:
        redraw(out, args.quick)
        return 0
    if args.device_batch:
        from benchmarks.speed.device import device_batch_main

        return device_batch_main(out, args.quick, repeats)
    report = measure(args.quick, repeats)
    if report is None:
        return 1
    from benchmarks.speed.report import markdown

    text = markdown(report)
    print(text)
    _output.write(out, _output.stem("speed", args.quick), report, text)
    return report
