"""Pictures of simulations: diagnostics against time, work–precision diagrams, animations.

Needs matplotlib (`pip install "bundledyn[viz]"`). Every function returns a matplotlib
`Figure` (shown as a cell's value in Jupyter) and, given `path=`, also writes it; files
are written whole or not at all. Figures are built without pyplot, so they render
headless.

- `plot_drift(trajectory)`: energy and spatial momentum minus their initial values.
- `plot_motion(trajectory)`: shape coordinates, attitude (Euler parameters), position.
- `plot_work_precision(series)`: error against wall time, one line per method.
- `plot_identification(result)`: an identification's residuals before and after, the
  information's singular values, and the estimates' errors or intervals.
- `animate(trajectory, path)`: the bodies in 3D, marked so that their turn shows, seen along
  the axis the motion turns about, with the angle turned against time, as a GIF.
- `turn_axis(g)`, `turn_angles(g, axis)`: the axis a motion turns about and the angle turned.

Every title names the frame its quantities are in (`frame_name`): poses in the scene's
frame, energy and spatial momentum in the Galilean frame.
"""

try:
    import matplotlib  # noqa: F401
except ImportError as error:  # pragma: no cover - depends on the environment
    raise ImportError(
        "bundledyn.viz needs matplotlib: pip install 'bundledyn[viz]' (or pip install matplotlib)."
    ) from error

from ._viz._animation import DrawnBody, animate, body_maps, drawn_bodies
from ._viz._attitude import attitude_quaternions, turn_angles, turn_axis
from ._viz._canvas import new_figure, save_figure
from ._viz._frame_names import frame_name
from ._viz._identification import plot_identification
from ._viz._plots import plot_drift, plot_motion, plot_work_precision

__all__ = [
    "DrawnBody",
    "animate",
    "attitude_quaternions",
    "body_maps",
    "drawn_bodies",
    "frame_name",
    "new_figure",
    "plot_drift",
    "plot_identification",
    "plot_motion",
    "plot_work_precision",
    "save_figure",
    "turn_angles",
    "turn_axis",
]
