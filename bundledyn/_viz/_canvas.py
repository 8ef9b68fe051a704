"""Figures without pyplot's global state, and saving them whole or not at all."""

import pathlib

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .._files import atomic_path


def new_figure(width: float, height: float, dpi: int = 100) -> Figure:
    """A figure on an Agg canvas: renders headless, and Jupyter shows it as the cell's value."""
    fig = Figure(figsize=(width, height), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig: Figure, path) -> pathlib.Path:
    """Write `fig` to `path` (format from the suffix) atomically; return the path."""
    path = pathlib.Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp)
    return path
