"""Diagnostics against time, and work–precision diagrams."""

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import NullFormatter

from .._trajectory import Diagnostics, Trajectory
from ._attitude import attitude_quaternions
from ._canvas import new_figure, save_figure
from ._frame_names import GALILEAN, frame_name

_TWIST_LABELS = ("$L_x$", "$L_y$", "$L_z$", "$p_x$", "$p_y$", "$p_z$")


def _finite(trajectory: Trajectory):
    """Indices of the saved times that were reached (diffrax pads the rest with inf)."""
    return np.flatnonzero(np.isfinite(np.asarray(trajectory.ts)))


def _maybe_save(fig, path):
    if path is not None:
        save_figure(fig, path)
    return fig


def plot_drift(
    trajectory: Trajectory, *, path=None, diagnostics: Diagnostics | None = None
) -> Figure:
    r"""Energy and spatial momentum minus their initial values, against time.

    Both are conserved by a free system with conservative effects (seed 004, (2.6) with
    $\mathbf F = 0$): the curves show the integrator's error. Both are in the Galilean
    frame whatever the scene's frame, and the title says so.

    **Arguments:**

    - `trajectory`: a `Trajectory` with several saved times.
    - `path`: if given, the figure is also written there (PNG, SVG, PDF by suffix).
    - `diagnostics`: the trajectory's `diagnostics()`, if already computed.

    **Returns:**

    The matplotlib `Figure`.
    """
    diagnostics = trajectory.diagnostics() if diagnostics is None else diagnostics
    keep = _finite(trajectory)
    t = np.asarray(trajectory.ts)[keep]
    energy = np.asarray(diagnostics.energy)[keep]
    momentum = np.asarray(diagnostics.spatial_momentum)[keep]
    fig = new_figure(7.0, 4.0)
    top, bottom = fig.subplots(2, 1, sharex=True)
    top.plot(t, energy - energy[0], color="k")
    top.set_ylabel("$E(t) - E(0)$ [J]")
    top.set_title(
        f"energy and spatial momentum in {GALILEAN}, minus their start "
        f"($E(0)$ = {energy[0]:.6g} J)",
        fontsize=9,
    )
    for k, label in enumerate(_TWIST_LABELS):
        bottom.plot(t, momentum[:, k] - momentum[0, k], label=label)
    bottom.set_ylabel("spatial momentum\n(about the origin)\nminus its start")
    bottom.set_xlabel("t [s]")
    bottom.legend(fontsize=7, ncol=6)
    for ax in (top, bottom):
        ax.ticklabel_format(axis="y", style="sci", scilimits=(-2, 3))
        ax.grid(alpha=0.3)
    return _maybe_save(fig, path)


def plot_motion(trajectory: Trajectory, *, path=None) -> Figure:
    """Shape coordinates, attitude (Euler parameters) and position of the section frame.

    The attitude and position are in the scene's frame (the title names it).

    **Arguments:**

    - `trajectory`: a `Trajectory` with several saved times.
    - `path`: if given, the figure is also written there.

    **Returns:**

    The matplotlib `Figure`.
    """
    keep = _finite(trajectory)
    t = np.asarray(trajectory.ts)[keep]
    g = np.asarray(trajectory.g)[keep]
    q = np.asarray(trajectory.q)[keep]
    panels = 3 if q.shape[1] else 2
    fig = new_figure(7.0, 2.0 * panels + 0.5)
    axes = fig.subplots(panels, 1, sharex=True)
    if q.shape[1]:
        axes[0].plot(t, q)
        axes[0].set_ylabel("shape q")
        if q.shape[1] <= 12:
            axes[0].legend([f"$q_{{{k + 1}}}$" for k in range(q.shape[1])], fontsize=7, ncol=6)
    quats = attitude_quaternions(g)
    for k, label in enumerate(("$w$", "$x$", "$y$", "$z$")):
        axes[-2].plot(t, quats[:, k], label=label)
    axes[-2].set_ylabel("attitude\n(Euler parameters)")
    axes[-2].legend(fontsize=7, ncol=4)
    for k, label in enumerate(("x", "y", "z")):
        axes[-1].plot(t, g[:, k, 3], label=label)
    axes[-1].set_ylabel("position [m]")
    axes[-1].set_xlabel("t [s]")
    axes[-1].legend(fontsize=7, ncol=3)
    pose = f"the section frame's pose in {frame_name(trajectory.scene)}"
    axes[0].set_title(f"shape, and {pose}" if q.shape[1] else pose, fontsize=9)
    for ax in axes:
        ax.grid(alpha=0.3)
    return _maybe_save(fig, path)


_STYLES = {"Lie group": "-o", "embedded": "--s", "peer": ":^"}


def plot_work_precision(series, *, title="", floor=None, path=None) -> Figure:
    """A work–precision diagram: error at $t_1$ against wall time, log–log, a line per method.

    **Arguments:**

    - `series`: a sequence of dicts as in `benchmarks/results/accuracy_cost.json`:
      `{"method": name, "family": "Lie group" | "embedded" | "peer", "points": [{"ok":
      bool, "error": float, "time": {"median": seconds}}, ...]}`.
    - `title`: the diagram's title.
    - `floor`: the error below which the reference cannot tell (drawn as a line).
    - `path`: if given, the figure is also written there.

    **Returns:**

    The matplotlib `Figure`.
    """
    fig = new_figure(7.0, 4.8, dpi=110)
    ax = fig.subplots()
    for s in series:
        points = [p for p in s["points"] if p["ok"] and np.isfinite(p["error"])]
        if points:
            ax.loglog(
                [p["time"]["median"] for p in points],
                [max(p["error"], 1e-16) for p in points],
                _STYLES.get(s.get("family"), "-o"),
                ms=4,
                label=s["method"],
            )
    if floor is not None:
        ax.axhline(floor, color="grey", lw=0.8, ls="-.", label="reference floor")
    ax.set_xlabel("wall time per solve [s] (median of runs)")
    ax.set_ylabel("error of the state at t1")
    ax.set_title(title, fontsize=9)
    ax.grid(True, which="major", alpha=0.3)
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.legend(fontsize=7, ncol=2)
    return _maybe_save(fig, path)
