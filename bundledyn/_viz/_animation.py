"""An animation of the bodies of a trajectory, saved as a GIF."""

import pathlib
from typing import TYPE_CHECKING, NamedTuple, cast

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from matplotlib.animation import FuncAnimation, PillowWriter

from .._effects import mass_and_centre
from .._files import atomic_path
from .._solids import AbstractSolid, Box, Ellipsoid
from .._systems._affine_body import AffineBody, stretch
from .._systems._multibody import AbstractMultibody
from .._systems._rigid_body import RigidBody
from .._trajectory import Trajectory
from ._canvas import new_figure

if TYPE_CHECKING:
    from mpl_toolkits.mplot3d import Axes3D


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


def animate(
    trajectory: Trajectory,
    path,
    *,
    solids=None,
    frames: int = 60,
    fps: int = 20,
    trail: bool = True,
    size: float = 4.0,
    dpi: int = 80,
) -> pathlib.Path:
    """Animate the bodies of a trajectory in 3D and save the animation as a GIF.

    Each body is drawn as its solid (see `drawn_bodies`), with the section frame's axes
    (red, green, blue for x, y, z) and the trail of the centre of mass.

    **Arguments:**

    - `trajectory`: a `Trajectory` with several saved times (e.g. `SaveAt(ts=...)`).
    - `path`: the GIF to write (written whole or not at all).
    - `solids`: optional solid per body; default: inertia boxes (an affine body: its ellipsoid).
    - `frames`: at most this many frames, evenly spaced over the saved times.
    - `fps`: frames per second of the GIF.
    - `trail`: draw the path of the centre of mass.
    - `size`, `dpi`: picture size in inches and dots per inch (the GIF is `size·dpi` pixels
      square).

    **Returns:**

    The path written.
    """
    system = trajectory.scene.system
    index = _frame_indices(trajectory, frames)
    maps, centres = map(np.asarray, _world_frames(system, trajectory.g[index], trajectory.q[index]))
    g = np.asarray(trajectory.g)[index]
    ts = np.asarray(trajectory.ts)[index]
    bodies = drawn_bodies(system, solids)
    local = [(b.placement, b.solid.surface(8)) for b in bodies]

    def world_surfaces(k):
        out = []
        for (placement, surface), T in zip(local, maps[k], strict=False):
            A = T @ placement
            out.append(surface @ A[:3, :3].T + A[:3, 3])
        return out

    everything = [centres] + [
        s.reshape(-1, 3) for k in range(len(index)) for s in world_surfaces(k)
    ]
    points = np.concatenate(everything)
    middle = 0.5 * (points.min(0) + points.max(0))
    half = 0.5 * max(float(np.max(points.max(0) - points.min(0))), 1e-3)
    axis_length = 0.3 * half

    fig = new_figure(size, size, dpi=dpi)
    fig.set_layout_engine(None)
    ax = cast("Axes3D", fig.add_axes((0.0, 0.0, 1.0, 1.0), projection="3d"))
    colours = [f"C{k % 10}" for k in range(len(bodies))]

    def draw(k):
        ax.cla()
        for surface, colour in zip(world_surfaces(k), colours, strict=True):
            ax.plot_surface(*np.moveaxis(surface, -1, 0), color=colour, alpha=0.85, linewidth=0)
        origin = g[k, :3, 3]
        for j, colour in enumerate("rgb"):
            tip = origin + axis_length * g[k, :3, j]
            ax.plot(*np.stack([origin, tip], axis=1), color=colour, lw=2)
        if trail:
            ax.plot(*centres[: k + 1].T, color="k", lw=1)
        ax.set(
            xlim=(middle[0] - half, middle[0] + half),
            ylim=(middle[1] - half, middle[1] + half),
            zlim=(middle[2] - half, middle[2] + half),
            xlabel="x",
            ylabel="y",
            zlabel="z",
        )
        ax.set_box_aspect((1, 1, 1))
        ax.set_title(f"t = {ts[k]:.3f} s", fontsize=9, y=0.95)

    path = pathlib.Path(path)
    movie = FuncAnimation(fig, draw, frames=len(index))
    with atomic_path(path) as tmp:
        movie.save(tmp, writer=PillowWriter(fps=fps), dpi=dpi)
    return path
