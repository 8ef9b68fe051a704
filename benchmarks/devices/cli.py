"""`python -m benchmarks.devices`: a worker process per device count, then the report."""

import argparse
import json
import os

from benchmarks import _output
from benchmarks._provenance import report_header
from benchmarks._timing import run_worker

DESCRIPTION = "Throughput of the speed benchmark's batch over 1, 2 and 4 devices."
DEVICE_COUNTS = (1, 2, 4)
PACKAGES = ("bundledyn", "jax", "jaxlib", "diffrax", "equinox", "numpy", "mujoco")


def batch_settings():
    """The settings at MuJoCo RK4's error on the batch, from the committed speed results:
    `(name -> setting, the speed run's provenance)`."""
    speed = json.loads((_output.RESULTS / "speed.json").read_text())
    return speed["batch_setting"], speed["provenance"]


def measure(quick, repeats):
    """Each device count in its own worker."""
    import bundledyn as bd

    settings, calibrated = batch_settings()
    if quick:
        settings = {"RKMK87": settings["RKMK87"]}
    batch, counts = (64, DEVICE_COUNTS[:2]) if quick else (1024, DEVICE_COUNTS)
    report = report_header(
        PACKAGES, quick, repeats=repeats, batch=batch, cores=len(os.sched_getaffinity(0)),
        settings=settings, settings_from=calibrated, counts=[],
    )  # fmt: skip
    for count in counts:
        flags = [*bd.CPU_XLA_FLAGS, f"--xla_force_host_platform_device_count={count}"]
        args = [json.dumps(settings), str(batch), str(repeats)]
        entry = run_worker("benchmarks.devices", "worker", args, flags)
        print(f"  {count} device(s): {_line(entry)}", flush=True)
        report["counts"].append(entry)
    return report


def _line(entry):
    return ", ".join(
        f"{name} {m['rollouts_per_second']:.0f} rollouts/s" for name, m in entry["methods"].items()
    )


def main(argv=None):
    from benchmarks._mujoco import float64_cpu_run_with_mujoco
    from benchmarks.devices.report import markdown

    parser = _output.parser(DESCRIPTION, "64 rollouts, 1 and 2 devices, 2 repeats")
    parser.add_argument("--repeats", type=int, help="timed repeats (default 5; quick 2)")
    parser.add_argument("--worker", nargs=3, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        from benchmarks.devices.measure import measure_worker

        settings, batch, repeats = args.worker
        print(json.dumps(measure_worker(json.loads(settings), int(batch), int(repeats))))
        return 0
    return _output.run(
        args,
        "devices",
        markdown,
        lambda: measure(args.quick, args.repeats or (2 if args.quick else 5)),
        ready=float64_cpu_run_with_mujoco,
    )
