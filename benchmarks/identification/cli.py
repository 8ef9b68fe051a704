"""`python -m benchmarks.identification`: the run, `--quick` and `--report-only` (see the
package's docstring)."""

import dataclasses
import json
import time

from benchmarks import _output
from benchmarks._provenance import report_header

DESCRIPTION = "Identification against mujoco.sysid, on the same MuJoCo-generated data sets."
NAME = "identification"
PACKAGES = ("bundledyn", "jax", "jaxlib", "equinox", "diffrax", "numpy", "mujoco")
LEVELS = (0.0, 0.001, 0.01)
SYSID_ITERS = 200  # mujoco.sysid's own default
FAMILY = 3  # generated members of each kind (`family.py`): seeds 0, 1, 2


def _parser():
    parser = _output.parser(
        DESCRIPTION, "the tumbling body only, short record, one seed and noise level"
    )
    parser.add_argument("--seeds", type=int, help="seeds per case (default 2; quick 1)")
    parser.add_argument(
        "--cases",
        help="comma-separated subset of chain,arm,tumble and generated members (tree0, arm1, ...)",
    )
    parser.add_argument(
        "--family", type=int, help=f"generated members per kind (default {FAMILY}; quick 0)"
    )
    parser.add_argument("--sysid-iters", type=int, help=f"default {SYSID_ITERS}; quick 8")
    parser.add_argument(
        "--part",
        action="store_true",
        help="write each case as its own part (parts.py), skipping cases whose part measured "
        "this code with these settings",
    )
    parser.add_argument(
        "--merge", action="store_true", help="merge the parts into the report (parts.py)"
    )
    return parser


def one_device_per_core() -> int:
    """Give JAX one CPU device per core, before it starts, and return the count.

    mujoco.sysid rolls out on one thread per core (`os.cpu_count()`); bundledyn's fit
    spreads its shooting windows over the local devices (`over_devices`), which on a CPU
    are the ones `--xla_force_host_platform_device_count` makes. A count already in
    `XLA_FLAGS` is kept."""
    import os

    flags = os.environ.get("XLA_FLAGS", "")
    name = "--xla_force_host_platform_device_count"
    if name not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} {name}={os.cpu_count() or 1}".strip()
    import jax

    return jax.local_device_count()


def measure(args, out):
    """Every case's fits by both methods, with provenance; None without mujoco.sysid. With
    `--part`, each case is also written to its part in `out` as it finishes, and a case
    whose part measured this code is skipped."""
    devices = one_device_per_core()
    import bundledyn as bd
    from benchmarks.identification import parts, sysid
    from benchmarks.identification.cases import CASES
    from benchmarks.identification.family import family
    from benchmarks.identification.run import summarize_family

    bd.enable_x64()
    if not sysid.available():
        print("mujoco.sysid is not importable (pip install '.[bench]')")
        return None
    settings = _settings(args, devices, sysid.threads())
    cases = CASES | {case.name: case for case in family(max(_count(args), 10))}
    names = args.cases.split(",") if args.cases else _default_cases(args)
    report = report_header(PACKAGES, args.quick, **settings, cases={})
    began = time.perf_counter()
    for name in names:
        if args.part and parts.current(out, name, settings | {"quick": args.quick}):
            print(f"{name}: its part measured this code; kept", flush=True)
            continue
        report["cases"][name] = _run(cases[name], args.quick, settings)
        if args.part:
            part = report_header(PACKAGES, args.quick, **settings)
            parts.write(out, name, part | {"cases": {name: report["cases"][name]}})
    report["family"] = summarize_family(report["cases"])
    report["seconds"] = time.perf_counter() - began
    return report


def _merged(args, out):
    """The report of every part in `out` (`parts.merged`), its family summarized."""
    from benchmarks.identification import parts
    from benchmarks.identification.run import summarize_family

    report = parts.merged(out, _default_cases(args))
    report["family"] = summarize_family(report["cases"])
    return report


def _count(args):
    return args.family if args.family is not None else (0 if args.quick else FAMILY)


def _default_cases(args):
    from benchmarks.identification.cases import CASES
    from benchmarks.identification.family import family

    return ["tumble"] if args.quick else [*CASES, *(c.name for c in family(_count(args)))]


def _settings(args, devices, sysid_threads):
    """What every fit of a run shares (and every merged part must)."""
    return {
        "seeds": args.seeds or (1 if args.quick else 2),
        "levels": [0.01] if args.quick else list(LEVELS),
        "sysid_iters": args.sysid_iters or (8 if args.quick else SYSID_ITERS),
        "devices": devices,
        "sysid_threads": sysid_threads,
    }


def _run(case, quick, settings):
    """One case's fits by both methods, with its summary and wall seconds."""
    from benchmarks.identification.run import run_case, summarize

    if quick:
        case = dataclasses.replace(case, t1=1.5, held_out_t1=1.0)
    print(f"{case.name}: {case.description}", flush=True)
    began = time.perf_counter()
    result = run_case(
        case, tuple(range(settings["seeds"])), tuple(settings["levels"]),
        settings["sysid_iters"], log=lambda s: print(s, flush=True),
    )  # fmt: skip
    result["summary"] = summarize(result)
    result["seconds"] = time.perf_counter() - began
    return result


def main(argv=None):
    from benchmarks.identification.report import markdown

    args = _parser().parse_args(argv)
    out = _output.folder(args.out, args.quick, NAME, args.report_only)
    stem = _output.stem(NAME, args.quick)
    if args.report_only:
        report = json.loads((out / f"{stem}.json").read_text())
        (out / f"{stem}.md").write_text(markdown(report))
        return report
    report = _merged(args, out) if args.merge else measure(args, out)
    if report is None or (args.part and not args.merge):
        return report
    text = markdown(report)
    print(text)
    _output.write(out, stem, report, text)
    return report
