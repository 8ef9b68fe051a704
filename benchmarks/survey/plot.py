"""The survey's diagram: each imported model's cost ratios against its degrees of freedom,
log–log, with the issue's limits as lines."""

import math

from benchmarks._figures import pyplot

FIGURE = "survey.png"
# (key, what, limit): the ratios drawn, read off an entry by `ratios`.
SERIES = (
    ("field", "field / mj_forward", 5.0),
    ("solve", "solve to RK4's error / MuJoCo RK4", 1.0),
    ("grad", "jax.grad / forward solve", 4.0),
)


def ratios(entry) -> dict:
    """An imported model's `SERIES` ratios; a series the run did not measure (or a sweep
    that did not reach RK4's error) is left out."""
    out = {"field": entry["field"]["ratio"]}
    if math.isfinite(entry.get("solves", {}).get("ratio", math.inf)):
        out["solve"] = entry["solves"]["ratio"]
    if "ratio" in entry.get("gradient", {}):
        out["grad"] = entry["gradient"]["ratio"]
    return out


def draw(report, out):
    """`survey.png` in `out`, named in `report["figure"]` (None without matplotlib)."""
    plt = pyplot()
    if plt is None:
        report["figure"] = None
        return
    imported = [m for m in report["models"] if m["status"] == "imported"]
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for (key, label, limit), colour in zip(SERIES, ("C0", "C1", "C2"), strict=True):
        points = [(m["nv"], ratios(m)[key]) for m in imported if key in ratios(m)]
        if points:
            ax.scatter(*zip(*points, strict=True), s=18, color=colour, label=label)
        ax.axhline(limit, color=colour, linestyle=":", linewidth=1)
    ax.set(xscale="log", yscale="log", xlabel="degrees of freedom (MuJoCo's nv)")
    ax.set(ylabel="time ratio", title="bundledyn against MuJoCo, every imported model")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / FIGURE, dpi=110)
    plt.close(fig)
    report["figure"] = FIGURE
