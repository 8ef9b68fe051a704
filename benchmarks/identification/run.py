"""One data set, fitted by every method on every (seed, noise level), timed in alternation,
scored, and summarised per noise level; first, the check that each method poses the
problem that made the record."""

import dataclasses
import statistics
import time

from benchmarks.identification import metric, records, sysid
from benchmarks.identification.cases import nominal_spec
from benchmarks.identification.ours import Bundledyn

SEGMENTS = 8  # mujoco.sysid's pieces in its multiple-shooting variant
METHODS = ("bundledyn", "sysid", "sysid_segments")  # the last two: single shooting, 8 pieces
# The cost at the truth over the cost at the start, noise-free: at most this. Measured at
# most 5e-14 where the method fits the record's problem; the arm's torque log read as a
# cubic instead of linearly gives 3.6e-9.
ROUNDING = 1e-11


def _scored(case, fitted_model, P_true, directions, unseen, level):
    import numpy as np

    P = metric.model_pseudo_inertias(fitted_model, case.bodies)
    errors = metric.relative_errors(P, P_true, directions)
    prediction = records.prediction_error(case, fitted_model, unseen)
    worst = max(prediction.values())
    return {
        "body_errors": [float(e) for e in errors],
        "error": float(np.max(errors)),
        "prediction": prediction,
        "prediction_in_noise": worst / level if level > 0 else None,
        "prediction_relative": worst,
    }


def costs_at_truth(case, ours, record, P_true, P_nominal):
    """Each method's cost at the true parameters over its cost at the start, on the
    noise-free `record`: at rounding level when the method fits exactly the problem that
    made the record. Raises otherwise, before any fit is timed."""
    import mujoco

    truth = mujoco.MjSpec.from_string(case.mjcf)
    ratios = {"bundledyn": ours.cost_at(record, P_true) / ours.cost_at(record, P_nominal)}
    for method, segments in (("sysid", 1), ("sysid_segments", SEGMENTS)):
        at_truth = sysid.cost_at(case, record, truth, segments)
        ratios[method] = at_truth / sysid.cost_at(case, record, nominal_spec(case), segments)
    wrong = {m: r for m, r in ratios.items() if not r <= ROUNDING}
    if wrong:
        raise RuntimeError(
            f"{case.name}: the cost at the true parameters is not at rounding level "
            f"(over the start's: {wrong}); the method does not fit the record's problem."
        )
    return ratios


def run_case(case, seeds, levels, sysid_iters, log=print):
    """Fit every (seed, level) of `case` with every method, timed in alternation."""
    import mujoco
    import numpy as np

    truth = mujoco.MjModel.from_xml_string(case.mjcf)
    P_true = metric.model_pseudo_inertias(truth, case.bodies)
    P_nominal = metric.model_pseudo_inertias(nominal_spec(case).compile(), case.bodies)
    directions = metric.null_directions(case, P_true)
    ours = Bundledyn(case, P_nominal)
    start = metric.relative_errors(P_nominal, P_true, directions)
    out = {
        "case": dataclasses.asdict(case) | {"mjcf": None},
        "null_directions": int(np.linalg.matrix_rank(directions)) if directions.size else 0,
        "start_error": float(np.max(start)),
        "fits": [],
    }
    recorded = {(s, lv): records.noisy_record(case, s, lv) for s in seeds for lv in levels}
    unseen = {s: records.held_out(case, s) for s in seeds}
    clean = records.noisy_record(case, seeds[0], 0.0)
    begin = time.perf_counter()
    out["cost_at_truth"] = costs_at_truth(case, ours, clean, P_true, P_nominal)
    out["bundledyn_first_fit"] = time.perf_counter() - begin
    log(f"  {case.name}: cost at the truth over the start's {out['cost_at_truth']}; "
        f"bundledyn's compiling {out['bundledyn_first_fit']:.1f} s")  # fmt: skip
    for i, (seed, level) in enumerate(recorded):
        record = recorded[(seed, level)]
        fits = {
            "bundledyn": lambda record=record: ours.fit(record),
            "sysid": lambda record=record: sysid.fit(case, record, nominal_spec(case), sysid_iters),
            "sysid_segments": lambda record=record: sysid.fit(
                case, record, nominal_spec(case), sysid_iters, SEGMENTS
            ),
        }
        order = METHODS[i % 3 :] + METHODS[: i % 3]  # each method goes first in turn
        results = {name: fits[name]() for name in order}
        entry = {"seed": seed, "level": level, "first": order[0]}
        for name, result in results.items():
            model = metric.model_with(case, result.pop("P")) if "P" in result else None
            model = result.pop("model") if model is None else model
            scored = _scored(case, model, P_true, directions, unseen[seed], level)
            entry[name] = result | scored
        out["fits"].append(entry)
        out["bundledyn_compile_seconds"] = ours.compile_seconds
        log(
            f"  {case.name} seed {seed} noise {level:.1%}: error "
            + ", ".join(
                f"{m} {entry[m]['error']:.2e} ({entry[m]['seconds']:.1f} s)" for m in METHODS
            )  # fmt: skip
        )
    return out


# ------------------------------------------------------------------------------ summaries


def _stats(values):
    values = [v for v in values if v is not None]
    if not values:
        return None
    return {"median": statistics.median(values), "min": min(values), "max": max(values)}


def summarize(case_result):
    """Per noise level: each method's error, prediction, time, rollouts and undetermined
    over the seeds, and the time ratio."""
    rows = {}
    levels = sorted({f["level"] for f in case_result["fits"]})
    for level in levels:
        fits = [f for f in case_result["fits"] if f["level"] == level]
        row = {"seeds": len(fits)}
        for method in METHODS:
            rs = [f[method] for f in fits]
            row[method] = {
                "error": _stats([r["error"] for r in rs]),
                "prediction": _stats(
                    [
                        r["prediction_in_noise"] if level > 0 else r["prediction_relative"]
                        for r in rs
                    ]
                ),
                "seconds": _stats([r["seconds"] for r in rs]),
                "converged": sum(bool(r["converged"]) for r in rs),
            }
        row["bundledyn"]["evaluations"] = _stats([f["bundledyn"]["evaluations"] for f in fits])
        row["bundledyn"]["trials"] = _stats([f["bundledyn"]["trials"] for f in fits])
        row["bundledyn"]["undetermined"] = _stats(
            [len(f["bundledyn"]["undetermined"]) for f in fits]
        )
        for method in METHODS[1:]:
            peer = row[method]
            peer["rollouts"] = _stats([f[method]["rollouts"] for f in fits])
            peer["iterations"] = _stats([f[method]["iterations"] for f in fits])
            peer["infinite"] = _stats([f[method]["infinite_intervals"] for f in fits])
            peer["undetermined"] = _stats([f[method]["intervals_wider_than_bounds"] for f in fits])
            peer["ratio"] = _stats([f["bundledyn"]["seconds"] / f[method]["seconds"] for f in fits])
            peer["lower_error"] = row["bundledyn"]["error"]["median"] < peer["error"]["median"]
            peer["fifth_of_time"] = peer["ratio"]["median"] <= 0.2
        rows[f"{level:g}"] = row
    return rows


def summarize_family(cases):
    """Over the generated members (`family.py`): bundledyn's compiling per member (all its
    fits of the member), and per noise level bundledyn's time over each mujoco.sysid
    variant's (with and without the compiling) and both held-out errors, median and worst."""
    members = [c for c in cases.values() if c["case"].get("member") is not None]
    rows = {"compile_seconds": _stats([c["bundledyn_compile_seconds"] for c in members])}
    for level in sorted({f["level"] for c in members for f in c["fits"]}):
        fits = [f for c in members for f in c["fits"] if f["level"] == level]
        row = {
            "fits": len(fits),
            "bundledyn_prediction": _stats([_held_out(f["bundledyn"], level) for f in fits]),
        }
        for method in METHODS[1:]:
            row[method] = {
                "ratio": _stats([f["bundledyn"]["seconds"] / f[method]["seconds"] for f in fits]),
                "fit_ratio": _stats(
                    [
                        (f["bundledyn"]["seconds"] - f["bundledyn"]["compile_seconds"])
                        / f[method]["seconds"]
                        for f in fits
                    ]
                ),  # fmt: skip
                "prediction": _stats([_held_out(f[method], level) for f in fits]),
            }
        rows[f"{level:g}"] = row
    return rows


def _held_out(result, level):
    return result["prediction_in_noise"] if level > 0 else result["prediction_relative"]
