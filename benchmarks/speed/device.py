"""`--device-batch`: part 3 on JAX's default device (a GPU where there is one) over growing
batches, at the settings of a CPU run, with MuJoCo on the host's CPU beside it."""

import json
import os
import sys

from benchmarks import _output
from benchmarks._provenance import report_header
from benchmarks._report import fmt, provenance_lines
from benchmarks.speed.batch import batch_rollout, batch_throughput
from benchmarks.speed.config import DEVICE_BATCHES, PACKAGES, setting_label
from benchmarks.speed.report import batch_cells, measured


def device_agreement(batch_settings, t1, batch=64):
    """The same batch on JAX's default device and on the CPU: the largest difference of the
    final poses, and whether every rollout took the same number of steps."""
    import jax
    import numpy as np

    out = {}
    for method, setting in batch_settings.items():
        run, xi = batch_rollout(method, setting, t1, batch)
        g, steps = run(xi)
        with jax.default_device(jax.devices("cpu")[0]):
            run_cpu, xi_cpu = batch_rollout(method, setting, t1, batch)
            g_cpu, steps_cpu = run_cpu(xi_cpu)
        out[method] = {
            "batch": batch,
            "max_pose_difference": float(np.max(np.abs(np.asarray(g) - np.asarray(g_cpu)))),
            "same_steps": bool(np.array_equal(steps, steps_cpu)),
        }
    return out


def device_batches(sizes, batch_settings, t1, repeats):
    """Part 3 on JAX's default device over growing batches.

    MuJoCo runs on this machine's CPU beside the first size only, on 2 threads and on all
    cores: `mujoco.rollout`'s throughput does not grow with the batch once its threads are
    busy, and the larger batches would take minutes per repeat on 2 threads. MJX, where
    installed, runs on the device beside every size.
    """
    import jax

    cores = len(os.sched_getaffinity(0))
    rows = []
    for i, batch in enumerate(sizes):
        threads = tuple(dict.fromkeys((2, cores))) if i == 0 else ()
        bundledyn, mujoco, mjx = batch_throughput(
            batch_settings, t1, repeats, batch, threads, with_mjx=True
        )
        rows.append({"batch": batch, "bundledyn": bundledyn, "mujoco": mujoco, "mjx": mjx})
        print(f"  batch {batch}: {bundledyn}", file=sys.stderr, flush=True)
    device = jax.devices()[0]
    return {
        "device": f"{device.platform}: {device.device_kind}",
        "rows": rows,
        "agreement_with_cpu": device_agreement(batch_settings, t1),
    }


def device_markdown(report):
    """The report of `--device-batch`: bundledyn's batches on a device, MuJoCo on its host."""
    env, rows = report["environment"], report["device_batches"]["rows"]
    (baseline,) = (m for m in rows[0]["mujoco"] if m["threads"] == 2)
    # Results written before the fixed-step method name the settings `batch_rtol`.
    batch_settings = report.get("batch_setting") or report["batch_rtol"]
    settings = ", ".join(f"{m} {setting_label(m, x)}" for m, x in batch_settings.items())
    lines = [
        f"# Batches on {report['device_batches']['device']}",
        "",
        *provenance_lines(report),
        measured(report, f"{report['device_batches']['device']}, host {env['machine']}"),
        "",
        f"bundledyn: `jax.vmap(simulate)` of {report['t1']:g} s of the 5-body chain of "
        f"`speed.md`, float64, on the device, each method at the setting of the CPU run's "
        f"part 3 ({settings}). MuJoCo: `mujoco.rollout`, RK4, dt = 1e-2, on the host's CPU, timed "
        "in alternation with bundledyn at the first batch size only (its throughput does "
        "not grow with the batch once its threads are busy). The last column divides "
        "rollouts/s by MuJoCo's on 2 threads.",
        "",
        "| batch | simulator | time per batch [s] | rollouts/s | instance-steps/s "
        "| compile [s] | × MuJoCo, 2 threads |",
        "|--:|---|--:|--:|--:|--:|--:|",
    ]
    for row in rows:
        for method, b in row["bundledyn"].items():
            lines.append(
                f"| {row['batch']} | bundledyn {method} | {batch_cells(b, method)} | {b['compile']:.1f} "
                f"| {b['rollouts_per_second'] / baseline['rollouts_per_second']:.3g} |"
            )
        for m in row["mujoco"]:
            lines.append(
                f"| {row['batch']} | MuJoCo rollout, {m['threads']} threads | {fmt(m['time'], 1)} "
                f"| {m['rollouts_per_second']:.3g} | {m['instance_steps_per_second']:.3g} | "
                f"| {m['rollouts_per_second'] / baseline['rollouts_per_second']:.3g} |"
            )
        m = row.get("mjx")
        if m:
            lines.append(
                f"| {row['batch']} | MJX, dt = 1e-2 | {fmt(m['time'], 1)} "
                f"| {m['rollouts_per_second']:.3g} | {m['instance_steps_per_second']:.3g} "
                f"| {m['compile']:.1f} | {m['rollouts_per_second'] / baseline['rollouts_per_second']:.3g} |"
            )
    lines.append("")
    matched = report.get("mjx_at_equal_accuracy")
    if matched and any(row.get("mjx") for row in rows):
        steps = round(report["t1"] / matched["dt"])
        lines += [
            "MJX on the device at dt = 1e-2 is less accurate than the others; at equal accuracy "
            f"it takes dt = {matched['dt']:.1e} (from the CPU run's calibration), {steps} steps "
            f"per rollout, so its rollouts/s there are its instance-steps/s over {steps}: "
            + ", ".join(
                f"{r['mjx']['instance_steps_per_second'] / steps:.3g} at batch {r['batch']}"
                for r in rows
                if r.get("mjx")
            )
            + ".",
            "",
        ]
    for method, a in report["device_batches"]["agreement_with_cpu"].items():
        lines.append(
            f"- {method}: the first {a['batch']} rollouts, run again on the host's CPU, end "
            f"in poses that differ by at most {a['max_pose_difference']:.1e} from the "
            f"device's; same step counts: {'yes' if a['same_steps'] else 'no'}."
        )
    return "\n".join(lines) + "\n"


def device_batch_main(out, quick, repeats):
    """`--device-batch`: part 3 on JAX's default device at the settings of the CPU run in
    `out` (the committed one where `out` has none); writes `speed_<platform>[_quick]`."""
    import jax

    import bundledyn as bd

    bd.enable_x64()
    source = out / "speed.json"
    source = source if source.exists() else _output.RESULTS / "speed.json"
    print(f"the CPU run's settings from {source}", flush=True)
    cpu = json.loads(source.read_text())
    sizes = (256, 1024) if quick else DEVICE_BATCHES
    t1 = 0.2 if quick else 1.0
    report = report_header(
        PACKAGES, quick, repeats=repeats, t1=t1, batch_setting=cpu["batch_setting"],
        mjx_at_equal_accuracy=(cpu["batch_calibration"].get("mjx") or {}).get("at_target"),
        device_batches=device_batches(sizes, cpu["batch_setting"], t1, repeats),
    )  # fmt: skip
    text = device_markdown(report)
    print(text)
    _output.write(out, _output.stem(f"speed_{jax.devices()[0].platform}", quick), report, text)
    return report
