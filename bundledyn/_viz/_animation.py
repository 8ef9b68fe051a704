"""An animation of the bodies of a trajectory, seen along the axis they turn about, as a GIF."""

import pathlib
from typing import TYPE_CHECKING, NamedTuple, cast

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from matplotlib.animation import FuncAnimation, PillowWriter
from matplotlib.colors import to_rgba
from mpl_toolkits.mplot3d import proj3d

from .._effects import mass_and_centre
from .._files import atomic_path
from .._solids import AbstractSolid, Box, Ellipsoid
from .._systems._affine_body import AffineBody, stretch
from .._systems._multibody import AbstractMultibody
from .._systems._rigid_body import RigidBody
from .._trajectory import Trajectory
from ._attitude import turn_angles, turn_axis
from ._canvas import new_figure
from ._frame_names import frame_name

if TYPE_CHECKING:
    from mpl_toolkits.mplot3d import Axes3D

# The share of the figure's height that the turn's panel takes below the bodies.
_PANEL_HEIGHT = 0.22
# How far the camera sits off the axis it looks along (degrees): exactly along it, long
# bodies lying on the axis are seen end-on, as discs with no depth.
_TILT = 15.0
# The figure's width in inches as laid out; saved at `size` by scaling the dots per inch, so
# that the lettering keeps its share of the picture and a small picture clips none of it.
_WIDTH = 4.0
# The share of the 3D panel's half-width and half-height that the drawing reaches.
_FILL = 0.9
_OPACITY = 0.9
# Grid lines of a solid's surface per quarter turn: enough for the belly's edge to read.
_RESOLUTION = 10


class DrawnBody(NamedTuple):
    """A solid and where it sits in its body's frame (4×4)."""

    solid: AbstractSolid
    placement: np.ndarray


def _principal(matrix):
    moments, axes = np.linalg.eigh(np.asarray(matrix))
    if np.linalg.det(axes) < 0:
        axes[:, 0] = -axes[:, 0]
    return moments, axes


def _placement(axes, centre):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = axes, centre
    return T


def _inertia_box(mass, com, inertia) -> DrawnBody:
    moments, axes = _principal(inertia)
    return DrawnBody(Box.equivalent(mass, moments), _placement(axes, np.asarray(com)))


def drawn_bodies(system, solids=None) -> tuple[DrawnBody, ...]:
    r"""What to draw for each body of `system`, in its body frame.

    Given `solids` (one `AbstractSolid` per body, centred at the body's centre of mass and
    aligned with its frame), those; otherwise each rigid body's inertia box (the box with
    its mass and principal moments, along its principal axes) and an affine body's
    ellipsoid of second moment $E$ (semi-axes $\sqrt{5\lambda_i/m}$). A system with no
    bodies (`GenericSystem`) draws nothing but its frame and centre of mass.
    """
    if isinstance(system, AbstractMultibody):
        com, bodies = np.asarray(system.com), system.bodies()
    elif isinstance(system, RigidBody):
        com, bodies = np.asarray(system.com)[None], (system,)
    elif isinstance(system, AffineBody):
        if solids is not None:
            return (DrawnBody(solids[0], np.eye(4)),)
        moments, axes = _principal(system.second_moment)
        radii = np.sqrt(5.0 * moments / float(system.mass))
        return (DrawnBody(Ellipsoid(radii), _placement(axes, np.zeros(3))),)
    else:
        return ()
    if solids is not None:
        if len(solids) != len(bodies):
            raise ValueError(f"`solids` must give one solid per body ({len(bodies)}).")
        return tuple(
            DrawnBody(s, _placement(np.eye(3), c)) for s, c in zip(solids, com, strict=True)
        )
    return tuple(_inertia_box(float(b.mass), b.com, b.inertia) for b in bodies)


def body_maps(system, q):
    """Each body's frame in the section frame at shape `q`, `(bodies, 4, 4)`; an affine
    body's one map is $U(q)$."""
    if isinstance(system, AbstractMultibody):
        return system.body_poses(q)
    if isinstance(system, AffineBody):
        return jnp.eye(4).at[:3, :3].set(stretch(q))[None]
    return jnp.eye(4)[None]


@eqx.filter_jit
def _world_frames(system, g, q):
    def one(g_, q_):
        _, c, _ = mass_and_centre(system.metric(q_)[:6, :6])
        return g_ @ body_maps(system, q_), g_[:3, :3] @ c + g_[:3, 3]

    return jax.vmap(one)(g, q)


def _frame_indices(trajectory, frames):
    keep = np.flatnonzero(np.isfinite(np.asarray(trajectory.ts)))
    if len(keep) <= frames:
        return keep
    return keep[np.round(np.linspace(0, len(keep) - 1, frames)).astype(int)]


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def _picture_up(axis) -> np.ndarray:
    """The unit direction perpendicular to `axis` that a picture looking along it shows
    upward: world z (matplotlib's vertical), or x when the axis is nearly vertical."""
    up = np.array([0.0, 0.0, 1.0]) if abs(axis[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    return _unit(up - (up @ axis) * axis)


def _camera(axis) -> tuple[float, float]:
    """Elevation and azimuth (degrees) of a camera looking along `axis`, raised `_TILT`
    degrees off it so that the bodies keep their depth; along its opposite where the camera
    would look up from more than 30° below the horizon (at a scene with gravity, from under
    its floor)."""
    look = -axis if axis[2] > 0.5 else axis
    tilt = np.radians(_TILT)
    eye = -np.cos(tilt) * look + np.sin(tilt) * _picture_up(look)
    return float(np.degrees(np.arcsin(eye[2]))), float(np.degrees(np.arctan2(eye[1], eye[0])))


def _belly_colours(surface, pose, down, colour) -> np.ndarray:
    """Face colours of a solid's surface grid: `colour`, and a light tint on the faces that
    lie below its centre along `down` at the first frame (a body-fixed "belly").

    **Arguments:**

    - `surface`: the solid's surface in its own frame, `(rows, columns, 3)`.
    - `pose`: the solid's pose at the first frame, `(4, 4)` (an affine body's: not rigid).
    - `down`: the side to mark, a direction in the scene's frame.
    - `colour`: a matplotlib colour.

    **Returns:**

    RGBA colours, `(rows - 1, columns - 1, 4)`, one per face.
    """
    corners = surface[:-1, :-1] + surface[1:, :-1] + surface[:-1, 1:] + surface[1:, 1:]
    belly = (corners @ (pose[:3, :3].T @ down) > 0)[..., None]
    back = np.array(to_rgba(colour, alpha=_OPACITY))
    light = 0.35 * back + 0.65 * np.array([1.0, 1.0, 1.0, _OPACITY])
    return np.where(belly, light, back)


def _turn_panel(fig, ts, angles, axis):
    """A panel below the bodies with the angle turned about `axis` against time.

    **Arguments:**

    - `fig`: the animation's figure.
    - `ts`, `angles`: the frames' times and the angles turned by then (radians).
    - `axis`: the unit axis of the turn, named in the panel's title.

    **Returns:**

    A function of a frame's index that draws the curve up to that frame.
    """
    # Inside the figure's bottom strip, with room for the tick labels and the title.
    ax = fig.add_axes((0.2, 0.08, 0.72, _PANEL_HEIGHT - 0.12))
    degrees = np.degrees(angles)
    ax.plot(ts, degrees, color="0.8", lw=1)
    (done,) = ax.plot([], [], color="k", lw=1.5)
    (now,) = ax.plot([], [], "o", color="C3", ms=3)
    x, y, z = np.round(axis, 2) + 0.0  # + 0.0: no "-0.00"
    ax.set_title(f"section frame's turn about ({x:.2f}, {y:.2f}, {z:.2f})", fontsize=7)
    ax.set_xlabel("t [s]", fontsize=7, labelpad=1)
    ax.set_ylabel("[deg]", fontsize=7)
    ax.tick_params(labelsize=6, pad=1)
    ax.grid(alpha=0.3)

    def mark(k):
        done.set_data(ts[: k + 1], degrees[: k + 1])
        now.set_data(ts[k : k + 1], degrees[k : k + 1])

    return mark


def _box(points) -> tuple[np.ndarray, np.ndarray]:
    """The centre and half-widths of the box around `points` `(n, 3)`, each half-width at
    least a tenth of the largest (a flat motion keeps some depth)."""
    middle = 0.5 * (points.min(0) + points.max(0))
    half = 0.5 * (points.max(0) - points.min(0))
    return middle, np.maximum(half, max(0.1 * float(half.max()), 1e-3))


def _filling_zoom(ax, points) -> float:
    """The `zoom` of `ax`'s 3D box at which `points` fill its picture (`_FILL` of it about the
    centre): matplotlib sizes the box to fit seen from any side, which leaves the bodies
    small in a view along one axis.

    **Arguments:**

    - `ax`: 3D axes with their limits, view and box aspect set (at zoom 1).
    - `points`: `(n, 3)` in data coordinates.

    **Returns:**

    The zoom.
    """
    ax.apply_aspect()
    x, y, z = points.T
    xs, ys, _ = proj3d.proj_transform(x, y, z, ax.get_proj())
    pixels = ax.transData.transform(np.column_stack([xs, ys]))
    reach = np.max(np.abs(pixels - ax.bbox.get_points().mean(axis=0)), axis=0)
    return _FILL * float(np.min(0.5 * np.array([ax.bbox.width, ax.bbox.height]) / reach))


class _MovingSolid(NamedTuple):
    """A solid to draw at every frame: its surface grid in its own frame, its poses in the
    scene's frame `(frames, 4, 4)` and its faces' colours."""

    surface: np.ndarray
    poses: np.ndarray
    faces: np.ndarray

    def at(self, k) -> np.ndarray:
        """Its surface at frame `k`, in the scene's frame."""
        return _placed(self.surface, self.poses[k])


def _placed(surface, pose):
    """A surface grid `(rows, columns, 3)` moved by a pose `(4, 4)`."""
    return surface @ pose[:3, :3].T + pose[:3, 3]


def _moving_solids(system, solids, maps, down) -> list[_MovingSolid]:
    """Each drawn body's solid with its poses at the frames and its belly marked.

    **Arguments:**

    - `system`, `solids`: as for `drawn_bodies`.
    - `maps`: each body's frame in the scene's frame at every frame, `(frames, bodies, 4, 4)`.
    - `down`: the side to mark as the belly (see `_belly_colours`).
    """
    moving = []
    for i, body in enumerate(drawn_bodies(system, solids)):
        surface, poses = body.solid.surface(_RESOLUTION), maps[:, i] @ body.placement
        faces = _belly_colours(surface, poses[0], down, f"C{i % 10}")
        moving.append(_MovingSolid(surface, poses, faces))
    return moving


def _viewing_axis(g, view):
    """The unit axis to look along: `view`, else the motion's turn axis, else down."""
    if view is not None:
        return _unit(view)
    axis = turn_axis(g)
    return np.array([0.0, 0.0, -1.0]) if axis is None else axis


def _look_along(ax, axis, limits, points):
    """Set `ax` to look along `axis` orthographically, with equal scales on the three axes
    (a box with the limits' proportions), zoomed so that `points` fill the picture."""
    ax.set_proj_type("ortho")
    ax.set(xlim=limits[0], ylim=limits[1], zlim=limits[2])
    ax.view_init(*_camera(axis))
    aspect = tuple(np.ptp(limits, axis=1))
    ax.set_box_aspect(aspect)
    ax.set_box_aspect(aspect, zoom=_filling_zoom(ax, points))


def _triad(corner, length) -> np.ndarray:
    """The world's x, y, z axes from `corner`, each a segment and where its name goes:
    `(3, 3, 3)`, rows (start, end, label)."""
    corner = np.asarray(corner, dtype=float)
    return np.stack(
        [np.stack([corner, corner + length * e, corner + 1.3 * length * e]) for e in np.eye(3)]
    )


def _draw_triad(ax, triad):
    """The world's axes as a small labelled triad: where x, y and z point, in place of tick
    labels, which a view along an arbitrary axis crowds or pushes out of the picture."""
    for (start, end, label), name in zip(triad, "xyz", strict=True):
        ax.plot(*np.stack([start, end], axis=1), color="0.4", lw=1)
        ax.text(*label, name, fontsize=7, color="0.3", ha="center", va="center")


def animate(
    trajectory: Trajectory,
    path,
    *,
    solids=None,
    view=None,
    frames: int = 60,
    fps: int = 20,
    trail: bool = True,
    size: float = 4.0,
    dpi: int = 80,
) -> pathlib.Path:
    """Animate the bodies of a trajectory in 3D, with the angle they turn, as a GIF.

    Each body is drawn as its solid (see `drawn_bodies`) with a lighter "belly" on one
    body-fixed side, so that a turn about a body's own long axis shows; with the section
    frame's axes (red, green, blue for x, y, z), the trail of the centre of mass and a
    triad of the world's axes. The camera looks along an axis (from slightly above it,
    orthographically) and a panel below plots the angle the section frame has turned about
    that axis: by default the motion's own turn axis (`turn_axis`), so that the turn is
    seen in the picture's plane. The belly is the side facing down in the picture at the
    first frame. Poses are drawn in the scene's frame, named in the title.

    **Arguments:**

    - `trajectory`: a `Trajectory` with several saved times (e.g. `SaveAt(ts=...)`).
    - `path`: the GIF to write (written whole or not at all).
    - `solids`: optional solid per body; default: inertia boxes (an affine body: its ellipsoid).
    - `view`: the direction `(3,)` to look along and to plot the turn about, in the scene's
      frame; default: the motion's turn axis (looked along from its other end where that
      would look up from below), or down ($-z$) for a motion that does not turn.
    - `frames`: at most this many frames, evenly spaced over the saved times.
    - `fps`: frames per second of the GIF.
    - `trail`: draw the path of the centre of mass.
    - `size`, `dpi`: picture width in inches and dots per inch (the GIF is `size·dpi`
      pixels wide and `1.25·size·dpi` high).

    **Returns:**

    The path written.
    """
    index = _frame_indices(trajectory, frames)
    maps, centres = map(
        np.asarray, _world_frames(trajectory.scene.system, trajectory.g[index], trajectory.q[index])
    )
    g, ts = np.asarray(trajectory.g)[index], np.asarray(trajectory.ts)[index]
    axis = _viewing_axis(g, view)
    moving = _moving_solids(trajectory.scene.system, solids, maps, -_picture_up(axis))
    points = np.concatenate(
        [centres, g[:, :3, 3]] + [m.at(k).reshape(-1, 3) for m in moving for k in range(len(g))]
    )
    middle, half = _box(points)
    limits = np.stack([middle - half, middle + half], axis=1)
    triad = _triad(limits[:, 0], 0.25 * half.max())
    length = 0.4 * half.max()  # of the section frame's axes
    tips = [g[:, :3, 3] + length * g[:, :3, j] for j in range(3)]

    fig = new_figure(_WIDTH, 1.25 * _WIDTH, dpi=dpi)
    fig.set_layout_engine(None)
    box = (0.0, _PANEL_HEIGHT, 1.0, 1.0 - _PANEL_HEIGHT)
    ax = cast("Axes3D", fig.add_axes(box, projection="3d"))
    _look_along(ax, axis, limits, np.concatenate([points, triad.reshape(-1, 3), *tips]))
    mark = _turn_panel(fig, ts, turn_angles(g, axis), axis)
    title = fig.suptitle("", fontsize=8, y=0.985)
    frame = frame_name(trajectory.scene)

    def draw(k):
        ax.cla()  # keeps the view and the box; resets the limits
        ax.set(xlim=limits[0], ylim=limits[1], zlim=limits[2])
        ax.set_axis_off()
        for m in moving:
            ax.plot_surface(*np.moveaxis(m.at(k), -1, 0), facecolors=m.faces, linewidth=0)
        for tip, colour in zip(tips, "rgb", strict=True):
            ax.plot(*np.stack([g[k, :3, 3], tip[k]], axis=1), color=colour, lw=2)
        if trail:
            ax.plot(*centres[: k + 1].T, color="k", lw=1)
        _draw_triad(ax, triad)
        title.set_text(f"poses in {frame}, t = {ts[k]:.3f} s")
        mark(k)

    path = pathlib.Path(path)
    movie = FuncAnimation(fig, draw, frames=len(index))
    with atomic_path(path) as tmp:
        movie.save(tmp, writer=PillowWriter(fps=fps), dpi=dpi * size / _WIDTH)
    return path
