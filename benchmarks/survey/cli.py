"""`python -m benchmarks.survey`: the run, `--quick` and `--report-only`."""

import traceback

from benchmarks import _output
from benchmarks._provenance import report_header

DESCRIPTION = "Every MJCF model of dm_control and gymnasium, imported and compared with MuJoCo."
HORIZON = 1.0  # seconds of motion compared with MuJoCo's
PACKAGES = ("bundledyn", "jax", "jaxlib", "diffrax", "numpy", "mujoco", "dm_control", "gymnasium")


def ready(quick) -> bool:
    """Whether MuJoCo is there and, for a full run, the packages that hold the models."""
    from benchmarks._mujoco import float64_cpu_run_with_mujoco
    from benchmarks.survey.models import missing_packages

    if not float64_cpu_run_with_mujoco():
        return False
    if not quick and missing_packages():
        print(
            f"{', '.join(missing_packages())} not installed: their model files are the survey "
            "(pip install --no-deps dm_control gymnasium)"
        )
        return False
    return True


def measure(quick, repeats):
    """Every model in a report."""
    from benchmarks.accuracy_cost.sweep import default_solver
    from benchmarks.family.cli import one_core
    from benchmarks.survey.measure import survey
    from benchmarks.survey.models import model_files, quick_files

    one_core()
    t1 = 0.1 if quick else HORIZON
    report = report_header(
        PACKAGES, quick, horizon=t1, repeats=repeats, solver=default_solver().__name__, models=[]
    )
    for seed, file in enumerate(quick_files() if quick else model_files()):
        try:
            entry = survey(file, t1=t1, seed=seed, repeats=repeats)
        except Exception:  # a model the survey cannot run is a finding, not the end of the run
            entry = {"name": file.name, "status": "failed", "reason": traceback.format_exc(limit=3)}
        print(f"  {file.name}: {_line(entry)}", flush=True)
        report["models"].append(entry)
    return report


def _line(entry):
    if entry["status"] != "imported":
        return f"{entry['status']}: {entry['reason'].splitlines()[-1][:120]}"
    return (
        f"{entry['nv']} DoF, metric {entry['metric_error']:.1e}, rollout "
        f"{entry['rollout_error']:.1e} / {entry['fine_rollout_error']:.1e} (RK4's own "
        f"{entry['rk4_error']:.1e}), field {entry['field']['ratio']:.1f}x mj_forward, "
        f"{entry['seconds'][1]:.1f} s ({entry['steps']} steps) vs MuJoCo {entry['mujoco_seconds']:.1f} s, "
        f"at RK4's error {entry['solves']['ratio']:.2f}x, grad/forward "
        f"{entry['gradient'].get('ratio', float('nan')):.1f}"
    )


def main(argv=None):
    from benchmarks.survey.plot import draw
    from benchmarks.survey.report import markdown

    parser = _output.parser(DESCRIPTION, "bundledyn's two floating MJCF models, 0.1 s")
    parser.add_argument("--repeats", type=int, help="timed repeats of the field (default 3)")
    args = parser.parse_args(argv)
    return _output.run(
        args,
        "survey",
        markdown,
        lambda: measure(args.quick, args.repeats or 3),
        ready=lambda: ready(args.quick),
        draw=draw,
    )
