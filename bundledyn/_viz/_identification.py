r"""Pictures of an identification: residuals before and after, singular values, errors."""

import numpy as np
from matplotlib.figure import Figure

from .._identify._fit import FitResult
from ._canvas import new_figure, save_figure


def _residual_panel(ax, result: FitResult):
    """Histograms of the weighted residuals at the start and at the solution, with the
    unit Gaussian they follow when the model and the noise levels are right."""
    # Rows of samples counted in another window are zero: left out.
    counted = np.asarray(result.residuals) != 0
    after = np.asarray(result.residuals)[counted]
    before = np.asarray(result.initial_residuals)[counted]
    reach = max(4.0, float(np.quantile(np.abs(after), 0.999)))
    bins = np.linspace(-reach, reach, 61)
    shown = np.mean(np.abs(before) <= reach)
    ax.hist(np.clip(before, -reach, reach), bins, density=True, alpha=0.5,
            label=f"start ({100 * shown:.0f} % within the axis)")  # fmt: skip
    ax.hist(after, bins, density=True, alpha=0.6, label="fitted")
    x = np.linspace(-reach, reach, 200)
    ax.plot(x, np.exp(-0.5 * x**2) / np.sqrt(2 * np.pi), "k", lw=1, label="unit Gaussian")
    ax.set_xlabel("residual / noise level")
    ax.set_ylabel("density")
    ax.set_title("Residuals")
    ax.legend(fontsize=7)


def _singular_value_panel(ax, result: FitResult):
    """Singular values of the scaled information, with the noise scale below which a
    direction is undetermined (its standard error exceeds the parameters' own scale)."""
    ident = result.identifiability
    values = np.maximum(np.asarray(ident.singular_values), np.finfo(float).tiny)
    blind = values <= ident.noise_scale
    index = np.arange(1, values.size + 1)
    ax.semilogy(index[~blind], values[~blind], "o", ms=4, label="determined")
    ax.semilogy(index[blind], values[blind], "x", ms=5, color="C3", label="undetermined")
    ax.axhline(ident.noise_scale, color="k", lw=0.8, ls="--", label="noise scale")
    ax.set_xlabel("direction")
    ax.set_ylabel("singular value")
    ax.set_title(f"Information (condition {ident.condition_number:.3g})")
    ax.legend(fontsize=7)


def _error_panel(ax, result: FitResult, truth: dict[str, float] | None):
    """Each determined estimate's error in standard errors (with the truth), or its 95 %
    interval relative to its value (without)."""
    kept = [e for e in result.estimates() if e.determined]
    if not kept:
        ax.text(0.5, 0.5, "no quantity is determined alone:\nsee the report's undetermined\n"
                "directions", ha="center", va="center", transform=ax.transAxes)  # fmt: skip
        ax.set_axis_off()
        return
    names = [e.name for e in kept]
    y = np.arange(len(kept))
    if truth is not None:
        scores = np.array([(e.value - truth[e.name]) / e.std for e in kept])
        ax.axvspan(-1.96, 1.96, color="0.9", label="95 % interval")
        ax.plot(scores, y, "o", ms=3)
        ax.set_xlabel("(estimate − truth) / standard error")
        ax.set_title("Errors of the determined estimates")
        ax.legend(fontsize=7)
    else:
        widths = np.array([1.96 * e.std / max(abs(e.value), np.finfo(float).tiny) for e in kept])
        ax.semilogx(widths, y, "o", ms=3)
        ax.set_xlabel("95 % interval / |estimate|")
        ax.set_title("Uncertainty of the determined estimates")
    ax.set_yticks(y, names, fontsize=6)
    ax.invert_yaxis()


def plot_identification(
    result: FitResult, *, truth: dict[str, float] | None = None, path=None
) -> Figure:
    """Residuals before and after a fit, the information's singular values, and the
    determined estimates' errors (or intervals).

    **Arguments:**

    - `result`: a `bundledyn.identify.FitResult`.
    - `truth`: the true values by estimate name (`Estimate.name`), when known (synthetic
      data): the errors are drawn in standard errors against their 95 % band.
    - `path`: if given, the figure is also written there (PNG, SVG, PDF by suffix).

    **Returns:**

    The matplotlib `Figure`.
    """
    fig = new_figure(13, 4.5)
    axes = fig.subplots(1, 3, gridspec_kw={"width_ratios": [1.2, 1.0, 1.0]})
    _residual_panel(axes[0], result)
    _singular_value_panel(axes[1], result)
    _error_panel(axes[2], result, truth)
    if path is not None:
        save_figure(fig, path)
    return fig
