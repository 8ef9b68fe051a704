"""What one more digit of accuracy costs an adaptive method: a fit over its sweep.

An order-$p$ method's error goes as $h^p$, so its steps, and its time once per-solve costs
are small, grow by $10^{1/p}$ per digit of error. Where the sweep shows that regime, a
least-squares line of $\\log_{10}$ time against $\\log_{10}$ error has slope $-s$, and a digit
costs $\\times 10^{s}$.
"""

import numpy as np

FLOOR_MARGIN = 10.0  # errors within a digit of the reference floor measure the reference
ERROR_CEILING = 1e-4  # looser, a few long steps: the error does not yet go as h^p
STEP_GROWTH = 1.1  # a tighter setting whose steps grow less is bound by stability, not accuracy
# A tighter setting that gains less than this share of the digits its tolerance asks for no
# longer follows it: rounding, or too few steps for the order to show.
DIGIT_SHARE = 0.5
MIN_POINTS = 3  # fewer, and one noisy time sets the slope


def _follows(looser, tighter):
    """Whether a tighter tolerance bought accuracy with steps: `STEP_GROWTH` times the
    steps and `DIGIT_SHARE` of the digits it asked for."""
    asked = np.log10(looser["setting"] / tighter["setting"])
    gained = np.log10(looser["error"] / tighter["error"])
    return tighter["steps"] >= STEP_GROWTH * looser["steps"] and gained >= DIGIT_SHARE * asked


def asymptotic_points(series, floor):
    """The points of an adaptive sweep in its asymptotic range: of those with an error
    between `FLOOR_MARGIN` × `floor` and `ERROR_CEILING`, the longest run of successive
    settings each of which `_follows` the one before (of two as long, the tighter)."""
    points = [
        p
        for p in series["points"]
        if p["ok"] and FLOOR_MARGIN * floor <= p["error"] <= ERROR_CEILING
    ]
    best, run = [], []
    for point in points:
        run = [*run, point] if run and _follows(run[-1], point) else [point]
        if len(run) >= len(best):
            best = run
    return best


def _per_digit(errors, values):
    """`10^-slope` of the least-squares line of log10 `values` against log10 `errors`."""
    slope = np.polyfit(np.log10(errors), np.log10(values), 1)[0]
    return float(10.0**-slope)


def digit_cost(series, floor):
    """Time and steps ratio per extra digit of an adaptive `series`, with the range fitted:
    `{"time", "steps", "errors": [loosest, tightest], "settings": [...], "points"}`; None
    when fewer than `MIN_POINTS` points are in its asymptotic range."""
    points = asymptotic_points(series, floor)
    if len(points) < MIN_POINTS:
        return None
    errors = [p["error"] for p in points]
    return {
        "time": _per_digit(errors, [p["time"]["median"] for p in points]),
        "steps": _per_digit(errors, [p["steps"] for p in points]),
        "errors": [errors[0], errors[-1]],
        "settings": [points[0]["setting"], points[-1]["setting"]],
        "points": len(points),
    }
