r"""Pictures of an identification: residuals before and after, singular values, errors."""

import numpy as np
from matplotlib.figure import Figure

from .._identify._fit import FitResult
from .._scene import Scene
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
    direction is undetermined (its standard error exceeds the parameters' own scale). The
    axis spans the determined values and the noise line; the values below it (those at
    rounding level among them) are drawn on its floor."""
    ident = result.identifiability
    values = np.asarray(ident.singular_values)
    blind = values <= ident.noise_scale
    index = np.arange(1, values.size + 1)
    shown = np.append(values[~blind], ident.noise_scale)
    floor, top = shown.min() / 10, shown.max() * 3
    ax.semilogy(index[~blind], values[~blind], "o", ms=4, label="determined")
    ax.semilogy(index[blind], np.maximum(values[blind], floor), "v", ms=5, color="C3",
                label="undetermined (below the axis: on its floor)")  # fmt: skip
    ax.axhline(ident.noise_scale, color="k", lw=0.8, ls="--", label="noise scale")
    ax.set_ylim(floor / 1.5, top)
    ax.set_xlabel("direction")
    ax.set_ylabel("singular value")
    ax.set_title(f"Information (condition {ident.condition_number:.3g})")
    ax.legend(fontsize=7)


def _error_panel(ax, result: FitResult, truth: Scene | None):
    """Each base parameter's error in standard errors (with the truth), or its 95 %
    interval relative to its value (without)."""
    base = result.identifiability.base_parameters
    if not base:
        ax.text(0.5, 0.5, "the data determine no combination:\nsee the report's undetermined\n"
                "directions", ha="center", va="center", transform=ax.transAxes)  # fmt: skip
        ax.set_axis_off()
        return
    y = np.arange(len(base))
    if truth is not None:
        true_values = result.base_values_of(truth)
        scores = np.array([(b.value - v) / b.std for b, v in zip(base, true_values, strict=True)])
        ax.axvspan(-1.96, 1.96, color="0.9", label="95 % interval")
        ax.plot(scores, y, "o", ms=3)
        ax.set_xlabel("(estimate − truth) / standard error")
        ax.set_title("Errors of the base parameters")
        ax.legend(fontsize=7)
    else:
        tiny = np.finfo(float).tiny
        widths = np.array([1.96 * b.std / max(abs(b.value), tiny) for b in base])
        ax.semilogx(widths, y, "o", ms=3)
        ax.set_xlabel("95 % interval / |estimate|")
        ax.set_title("Uncertainty of the base parameters")
    names = [b.name if len(b.name) <= 40 else b.name[:38] + " …" for b in base]
    ax.set_yticks(y, names, fontsize=5)
    ax.invert_yaxis()


def plot_identification(result: FitResult, *, truth: Scene | None = None, path=None) -> Figure:
    """Residuals before and after a fit, the information's singular values, and the base
    parameters' errors (or intervals).

    **Arguments:**

    - `result`: a `bundledyn.identify.FitResult`.
    - `truth`: the true scene (of the fitted one's structure), when known (synthetic data):
      the errors are drawn in standard errors against their 95 % band.
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
