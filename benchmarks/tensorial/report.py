"""The tensorial benchmark's markdown: field costs and rollouts per member, ratios over the
family with the worst beside the median, and the errors they were taken at."""

from benchmarks._report import fmt, provenance_lines, versions
from benchmarks.tensorial.measure import ERROR_TIME, RTOL, ratio_summary

TARGET = 2.0  # the tensorial field within 2× the Multibody field


def _ratio(stats):
    return f"{stats['median']:.2f} ({stats['min']:.2f}–{stats['max']:.2f})"


def markdown(report):
    members = report["members"]
    horizon = report["horizon"]
    lines = ["# Chains of Lagrange gyroscopes in tensor coordinates", ""]
    lines += provenance_lines(report)
    lines += [
        "",
        f"Environment: {report['environment']['machine']}; {versions(report['environment'])}.",
        "",
        f"{len(members)} chains (2–4 bodies, random bodies and spinning starts), each timed in "
        f"alternation over {report['repeats']} rounds. Tensor formulations: (44) in the rotation "
        "tensors and in the axes and spin angles, `TensorialRKMK87`; the Multibody from the "
        "chain's MJCF, `simulate` with its default solver `RKMK87`; MuJoCo RK4 at the largest "
        f"step whose error at t = {ERROR_TIME:g} s is no larger than (44)'s in rotations. Errors "
        f"are of the bodies' axes against (44) in rotations at rtol 1e-13.",
        "",
        "## One field evaluation (µs): median (min–max)",
        "",
        "| member | (44) in rotations | (44) in axes | Multibody | mj_forward |",
        "|---|---:|---:|---:|---:|",
    ]
    for m in members:
        f = m["field"]
        lines.append(
            f"| {m['label']} | {fmt(f['rotations'], 1e6)} | {fmt(f['axes'], 1e6)} | "
            f"{fmt(f['tree'], 1e6)} | {fmt(f['mj_forward'], 1e6)} |"
        )
    lines += [
        "",
        "| over the family, median (min–max) | ratio |",
        "|---|---:|",
        f"| (44) in rotations / Multibody (target ≤ {TARGET:g}) | {_ratio(ratio_summary(members, 'rotations', 'tree', 'field'))} |",
        f"| (44) in axes / Multibody | {_ratio(ratio_summary(members, 'axes', 'tree', 'field'))} |",
        f"| (44) in rotations / mj_forward | {_ratio(ratio_summary(members, 'rotations', 'mj_forward', 'field'))} |",
        "",
        f"## A rollout of {horizon:g} s at rtol {RTOL:g} (ms): median (min–max)",
        "",
        f"| member | (44) in rotations | (44) in axes | Multibody | MuJoCo RK4 (dt) | error at {ERROR_TIME:g} s: rotations, axes, Multibody, MuJoCo | at {horizon:g} s |",
        "|---|---:|---:|---:|---:|---|---|",
    ]
    for m in members:
        r, e = m["rollout"], m["errors"]
        at = lambda k, e=e: ", ".join(
            f"{e[name][k]:.1e}" for name in ("rotations", "axes", "tree", "mujoco_rk4")
        )
        lines.append(
            f"| {m['label']} | {fmt(r['rotations'], 1e3)} | {fmt(r['axes'], 1e3)} | "
            f"{fmt(r['tree'], 1e3)} | {fmt(r['mujoco_rk4'], 1e3)} ({m['mujoco_dt']:g}) | {at(0)} | {at(1)} |"
        )
    lines += [
        "",
        "| over the family, median (min–max) | ratio |",
        "|---|---:|",
        f"| (44) in rotations / Multibody | {_ratio(ratio_summary(members, 'rotations', 'tree', 'rollout'))} |",
        f"| (44) in axes / Multibody | {_ratio(ratio_summary(members, 'axes', 'tree', 'rollout'))} |",
        f"| (44) in rotations / MuJoCo RK4 at equal error | {_ratio(ratio_summary(members, 'rotations', 'mujoco_rk4', 'rollout'))} |",
        "",
        f"The errors at {horizon:g} s are those at {ERROR_TIME:g} s grown by the chains' sensitivity to "
        "their state (the spinning chains are chaotic): they compare the integrators only early on.",
        "",
    ]
    return "\n".join(lines)
