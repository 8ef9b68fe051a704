"""The speed issue's targets, each with what was measured against it."""

from benchmarks._errors import time_at_error
from benchmarks.speed.config import BATCH, METHODS, TARGET_ERROR, XLA_SETTINGS


def targets(report):
    """Each target of the speed issue: (what, measured, limit, met)."""
    ours = report["settings"]["bundledyn"]
    fields = ours["field"]
    rows = []
    for n in fields:
        ratio = fields[n]["per_evaluation"]["median"] / fields[n]["mj_forward"]["median"]
        rows.append((f"vector field / mj_forward, n = {n}", ratio, 5.0))
    ns = list(fields)
    growth = fields[ns[-1]]["per_evaluation"]["median"] / fields[ns[1]]["per_evaluation"]["median"]
    rows.append((f"field cost growth n = {ns[1]} → {ns[-1]}", growth, int(ns[-1]) / int(ns[1])))
    chain = report["chain"]
    mj_coarse = chain["MuJoCo RK4"][0]
    t_mj = time_at_error(chain["MuJoCo RK4"], TARGET_ERROR)
    for method in METHODS:
        label = f"{method} (default)" if method == next(iter(METHODS)) else method
        t_bd = time_at_error(chain[method], mj_coarse["error"])
        if t_bd is not None:
            rows.append(
                (
                    f"10 s chain at MuJoCo RK4 dt = 1e-2 error ({mj_coarse['error']:.1e}): "
                    f"{label} / MuJoCo time",
                    t_bd / mj_coarse["time"]["median"],
                    1.0,
                )
            )
        t_bd = time_at_error(chain[method], TARGET_ERROR)
        if t_bd is not None and t_mj is not None:
            rows.append((f"10 s chain at error 1e-10: {label} / MuJoCo RK4 time", t_bd / t_mj, 0.5))
    mjb, mjx = ours["mujoco_batch"], fastest_mjx(report)
    for method, batch in ours["batch"].items():
        rows.append(
            (
                f"batch {BATCH}: MuJoCo rollout (2 threads) / bundledyn vmap ({method}) rollouts per s",
                mjb["rollouts_per_second"] / batch["rollouts_per_second"],
                1.0,
            )
        )
        if mjx is not None:
            rows.append(
                (
                    f"batch {BATCH} at equal accuracy: 10 × MJX ({mjx['label']}, dt = "
                    f"{mjx['dt']:.1e}) / bundledyn vmap ({method}) rollouts per s",
                    10 * mjx["rollouts_per_second"] / batch["rollouts_per_second"],
                    1.0,
                )
            )
    last = ns[-1]
    rows.append(
        (f"compile simulate, n = {last} [s]", ours["compile"][last]["simulate"]["total"], 10.0)
    )
    rows.append(
        (
            f"compile jax.grad(simulate), n = {last} [s]",
            ours["compile"][last]["grad"]["total"],
            30.0,
        )
    )
    rows.append(("jax.grad / forward, 10 s rollout", report["gradient"]["ratio"], 4.0))
    memory = report["memory"]
    rows.append(
        (f"gradient memory, {memory['steps']:.0e} steps [GB]", memory["peak_rss_bytes"] / 1e9, 2.0)
    )
    return [(what, value, limit, value <= limit) for what, value, limit in rows]


def fastest_mjx(report):
    """MJX's batch at equal accuracy under the XLA flags where it ran fastest: its
    `rollouts_per_second` at the step `dt` of part 3's calibration, from the instance-steps
    per second measured at dt = 1e-2 (no contacts: a step's work does not depend on dt),
    and the flags' `label`. None where MJX was not measured or no step reached the error."""
    mjx = report["batch_calibration"].get("mjx")
    if not mjx or not mjx["at_target"]:
        return None
    steps = mjx["at_target"]["steps"]
    runs = [
        {
            "label": label,
            "dt": mjx["at_target"]["dt"],
            "rollouts_per_second": report["settings"][key]["mjx_batch"]["instance_steps_per_second"]
            / steps,
        }
        for key, label in XLA_SETTINGS.items()
        if report["settings"][key].get("mjx_batch")
    ]
    return max(runs, key=lambda m: m["rollouts_per_second"], default=None)
