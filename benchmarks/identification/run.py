"""One data set, fitted by both methods on every (seed, noise level), timed in alternation,
scored, and summarised per noise level."""

import dataclasses
import statistics
import time

from benchmarks.identification import metric, records, sysid
from benchmarks.identification.cases import nominal_spec
from benchmarks.identification.ours import Bundledyn


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


def run_case(case, seeds, levels, sysid_iters, log=print):
    """Fit every (seed, level) of `case` with both methods, timed in alternation."""
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
    first = recorded[(seeds[0], levels[0])]
    begin = time.perf_counter()
    ours.fit(first)  # compiles, then fits: timed as a whole
    out["bundledyn_first_fit"] = time.perf_counter() - begin
    log(f"  {case.name}: bundledyn's first fit (compiling) {out['bundledyn_first_fit']:.1f} s")
    for i, (seed, level) in enumerate(recorded):
        record = recorded[(seed, level)]

        def ours_fit(record=record):
            return ours.fit(record)

        def theirs_fit(record=record):
            return sysid.fit(case, record, nominal_spec(case), sysid_iters)

        order = [("bundledyn", ours_fit), ("sysid", theirs_fit)]
        fits = dict(order[::-1] if i % 2 else order)  # alternate who goes first
        results = {name: fn() for name, fn in fits.items()}
        b, s = results["bundledyn"], results["sysid"]
        b_model = metric.model_with(case, b.pop("P"))
        s_model = s.pop("model")
        entry = {
            "seed": seed,
            "level": level,
            "first": next(iter(fits)),
            "bundledyn": b | _scored(case, b_model, P_true, directions, unseen[seed], level),
            "sysid": s | _scored(case, s_model, P_true, directions, unseen[seed], level),
        }
        out["fits"].append(entry)
        log(
            f"  {case.name} seed {seed} noise {level:.1%}: error {entry['bundledyn']['error']:.2e} "
            f"vs {entry['sysid']['error']:.2e}, {b['seconds']:.1f} s vs {s['seconds']:.1f} s"
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
        for method in ("bundledyn", "sysid"):
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
        row["sysid"]["rollouts"] = _stats([f["sysid"]["rollouts"] for f in fits])
        row["sysid"]["iterations"] = _stats([f["sysid"]["iterations"] for f in fits])
        row["sysid"]["infinite"] = _stats([f["sysid"]["infinite_intervals"] for f in fits])
        row["sysid"]["undetermined"] = _stats(
            [f["sysid"]["intervals_wider_than_bounds"] for f in fits]
        )
        row["ratio"] = _stats([f["bundledyn"]["seconds"] / f["sysid"]["seconds"] for f in fits])
        b_err, s_err = row["bundledyn"]["error"], row["sysid"]["error"]
        row["lower_error"] = b_err["median"] < s_err["median"]
        row["lower_worst_error"] = b_err["max"] < s_err["max"]
        row["fifth_of_time"] = row["ratio"]["median"] <= 0.2
        row["fifth_of_time_worst"] = row["ratio"]["max"] <= 0.2
        rows[f"{level:g}"] = row
    return rows
