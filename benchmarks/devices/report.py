"""The devices benchmark's markdown from its JSON."""

from benchmarks._report import fmt, provenance_lines, versions


def _efficiency(entry, first, name, cores):
    """Throughput over one device's, divided by the cores the devices can use."""
    gain = (
        entry["methods"][name]["rollouts_per_second"]
        / first["methods"][name]["rollouts_per_second"]
    )
    return gain / min(entry["devices"], cores)


def markdown(report):
    env, counts = report["environment"], report["counts"]
    first = counts[0]
    methods = [name for name in first["methods"] if name != "MuJoCo"]
    calibrated = report["settings_from"]
    lines = [
        "# A batch over devices",
        "",
        *provenance_lines(report),
        f"Packages: {versions(env)}. {report['batch']} rollouts of 1 s of the 5-body chain "
        f"(the speed benchmark's part 3), each method at its setting where its error over the "
        f"batch is MuJoCo RK4's at dt = 1e-2 ({', '.join(f'{k}: {v:g}' for k, v in report['settings'].items())}; "
        f"calibrated by the speed run of commit `{calibrated['commit'][:12]}`), by "
        f"`bd.vmap_over_devices` on each count of CPU devices made from {report['cores']} cores, "
        f"each in its own process, timed in alternation with `mujoco.rollout` on 2 threads "
        f"({report['repeats']} repeats; median (min–max)). Efficiency: throughput over one "
        "device's, divided by the cores the devices can use.",
        "",
        "| devices | method | time [s] | rollouts/s | / MuJoCo's | efficiency | lockstep overhead | difference from one device |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for entry in counts:
        mujoco = entry["methods"]["MuJoCo"]
        for name in methods:
            m = entry["methods"][name]
            lines.append(
                f"| {entry['devices']} | {name} | {fmt(m['time'], 1)} | {m['rollouts_per_second']:.0f} | "
                f"{m['rollouts_per_second'] / mujoco['rollouts_per_second']:.2f} | "
                f"{_efficiency(entry, first, name, report['cores']):.0%} | {m['lockstep_overhead']:.2f} | "
                f"{m['difference_from_one_device']:.1e} |"
            )
        lines.append(
            f"| {entry['devices']} | MuJoCo RK4, 2 threads | {fmt(mujoco['time'], 1)} | "
            f"{mujoco['rollouts_per_second']:.0f} | 1 | | | |"
        )
    lines.append("")
    return "\n".join(lines)
