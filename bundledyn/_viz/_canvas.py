"""Figures without pyplot's global state, and saving them whole or not at all."""

import io
import pathlib

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .._files import atomic_path


class _PictureFigure(Figure):
    """A figure that IPython and Jupyter display as its PNG wherever it is a cell's value,
    with or without `%matplotlib inline` (which only pyplot's figures otherwise need)."""

    def _repr_png_(self) -> bytes:
        picture = io.BytesIO()
        self.savefig(picture, format="png")
        return picture.getvalue()


def new_figure(width: float, height: float, dpi: int = 100) -> Figure:
    """A figure on an Agg canvas: renders headless, and Jupyter shows it as the cell's value."""
    fig = _PictureFigure(figsize=(width, height), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig: Figure, path) -> pathlib.Path:
    """Write `fig` to `path` (format from the suffix) atomically; return the path."""
    path = pathlib.Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp)
    return path
