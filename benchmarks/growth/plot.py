"""The growth benchmark's diagram: each time against the bodies, log–log, with a line of
slope 1 through the smallest trees' field."""

from benchmarks._figures import pyplot

FIGURE = "growth.png"
SERIES = (("field", "field (recursions)"), ("dense", "dense field"), ("mj_forward", "mj_forward"))
MARKERS = {"hinge": "o", "mixed": "s"}


def draw(report, out):
    """`growth.png` in `out`, named in `report["figure"]` (None without matplotlib)."""
    plt = pyplot()
    if plt is None:
        report["figure"] = None
        return
    members = report["members"]
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for (key, what), colour in zip(SERIES, ("C0", "C1", "C2"), strict=True):
        for kind, marker in MARKERS.items():
            points = [
                (m["bodies"], m["times"][key]["median"] * 1e6) for m in members if m["kind"] == kind
            ]
            if points:
                ax.scatter(
                    *zip(*points, strict=True),
                    s=18,
                    color=colour,
                    marker=marker,
                    label=f"{what}, {kind} trees",
                )
    smallest = min(members, key=lambda m: m["bodies"])
    x0, y0 = smallest["bodies"], smallest["times"]["field"]["median"] * 1e6
    most = max(m["bodies"] for m in members)
    ax.plot([x0, most], [y0, y0 * most / x0], color="grey", linestyle=":", label="linear")
    ax.set(xscale="log", yscale="log", xlabel="bodies", ylabel="µs per evaluation")
    ax.set(title="One evaluation against the bodies, random trees")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / FIGURE, dpi=110)
    plt.close(fig)
    report["figure"] = FIGURE
