"""Pictures: written headless at the expected size, drawing the right bodies, and every
plot and animation working on every kind of system and scene."""

import functools

import diffrax
import jax.numpy as jnp
import numpy as np
import pytest
from PIL import Image, ImageSequence
from systems import affine_body, chain, picture_size, tree4

import bundledyn as bd
from bundledyn import lie, viz

BOX = bd.Box((0.6, 0.4, 0.2))


def _drawn(scene, state, t1, saves):
    """A short motion to draw, by a cheap fixed-step solver: these tests draw motions and do
    not check them, and RKMK87's thirteen stages made compiling most of their time."""
    saveat = diffrax.SaveAt(ts=jnp.linspace(0.0, t1, saves))
    return bd.simulate(scene, state, t1, solver=bd.LieEuler(), dt0=0.01, saveat=saveat)


@functools.cache
def _spin():
    """A box tumbling near its intermediate axis."""
    state = bd.State(jnp.eye(4), (), jnp.array([0.05, 6.0, 0.05, 0.2, 0.0, 0.1]))
    return _drawn(bd.Scene(BOX.rigid_body(1.0)), state, 3.0, 31)


def _tree():
    """A branching tree of four boxes, its joints moving freely."""
    state = bd.State(jnp.eye(4), jnp.zeros(6), jnp.array([0.4, -0.3, 0.8, 0.0, 0.1, 0.0]),
                     jnp.array([2.0, -1.0, 1.5, 0.5, 1.0, -1.0]))  # fmt: skip
    return _drawn(bd.Scene(tree4()), state, 0.5, 6)


def _affine():
    """An affine body turning and stretching."""
    state = bd.State(jnp.eye(4), jnp.zeros(6), jnp.array([0.0, 2.0, 0.5, 0.0, 0.0, 0.0]),
                     jnp.array([0.3, -0.2, 0.1, 0.0, 0.2, 0.0]))  # fmt: skip
    return _drawn(bd.Scene(affine_body()), state, 1.0, 6)


def _falling_cat():
    """The demo's falling cat: a prescribed loop of shapes turns it at zero momentum."""
    scene_file = bd.SceneFile.load(bd.scenes / "falling_cat.toml")
    return _drawn(scene_file.scene, scene_file.state, 1.0, 11)


def _falling_frame():
    """A box spinning in gravity, seen from a frame falling with it (Theorem 3.4)."""
    scene = bd.Scene(BOX.rigid_body(1.0), [bd.Gravity()], frame=bd.FreeFalling())
    state = bd.State(jnp.eye(4), (), jnp.array([2.0, 0.5, 0.0, 0.0, 0.3, 0.0]))
    return _drawn(scene, state, 0.5, 6)


# Every kind of system and scene that the pictures must draw: one battery runs on each.
MOTIONS = {
    "rigid_body": _spin,
    "multibody_tree": _tree,
    "affine_body": _affine,
    "prescribed_shape": _falling_cat,
    "falling_frame": _falling_frame,
}


@pytest.fixture(scope="module", params=list(MOTIONS))
def motion(request):
    return request.param, MOTIONS[request.param]()


@pytest.fixture(scope="module")
def spin():
    return _spin()


def test_plots_are_written_in_the_format_of_their_suffix(spin, tmp_path):
    viz.plot_motion(spin, path=tmp_path / "motion.svg")
    assert (tmp_path / "motion.svg").read_text().lstrip().startswith("<?xml")


def test_figures_show_as_pictures_where_no_backend_is_set_up(spin):
    # What a fresh notebook (no `%matplotlib inline`) asks of a cell's value.
    from IPython.core.formatters import DisplayFormatter

    data, _ = DisplayFormatter().format(viz.plot_motion(spin))
    assert data["image/png"][:8] == b"\x89PNG\r\n\x1a\n"


def test_work_precision_diagram(tmp_path):
    def points(errors):
        return [{"ok": True, "error": e, "time": {"median": 1e-3 / e**0.2}} for e in errors]

    series = [
        {"method": "RKMK54", "family": "Lie group", "points": points([1e-3, 1e-6, 1e-9])},
        {"method": "MuJoCo RK4", "family": "peer", "points": points([1e-2, 1e-8])},
        {"method": "failed", "family": "embedded", "points": [{"ok": False, "error": 1.0}]},
    ]
    fig = viz.plot_work_precision(series, title="t", floor=1e-13, path=tmp_path / "wp.png")
    (ax,) = fig.axes
    assert [line.get_label() for line in ax.get_lines()] == [
        "RKMK54",
        "MuJoCo RK4",
        "reference floor",
    ]
    assert picture_size(tmp_path / "wp.png") == (770, 528, 1)


def test_inertia_boxes_carry_each_bodys_inertia():
    system = chain(5)
    for drawn, body in zip(viz.drawn_bodies(system), system.bodies(), strict=True):
        R, c = drawn.placement[:3, :3], drawn.placement[:3, 3]
        inertia = R @ np.diag(drawn.solid.principal_moments(float(body.mass))) @ R.T
        np.testing.assert_allclose(inertia, body.inertia, atol=1e-14)
        np.testing.assert_allclose(c, body.com)
        np.testing.assert_allclose(np.linalg.det(R), 1.0)


def test_affine_body_is_drawn_as_its_deformed_ellipsoid():
    body = affine_body()
    (drawn,) = viz.drawn_bodies(body)
    R = drawn.placement[:3, :3]
    E = R @ np.diag(np.asarray(drawn.solid.radii) ** 2) @ R.T * float(body.mass) / 5.0
    np.testing.assert_allclose(E, body.second_moment, atol=1e-14)
    q = jnp.array([0.1, -0.2, 0.05, 0.03, 0.0, 0.1])
    (F,) = viz.body_maps(body, q)  # one map per body, as for every system
    np.testing.assert_allclose(F[:3, :3], bd._systems._affine_body.stretch(q))


def test_attitude_quaternions_are_continuous():
    angles = jnp.linspace(0.0, 4.0 * np.pi, 200)
    axis = jnp.array([1.0, 2.0, 2.0]) / 3.0
    g = jnp.zeros((200, 4, 4)).at[:, 3, 3].set(1.0)
    g = g.at[:, :3, :3].set(lie.so3_exp(angles[:, None] * axis[None]))
    quats = viz.attitude_quaternions(g)
    assert np.abs(np.diff(quats, axis=0)).max() < 0.04  # no sign jumps
    np.testing.assert_allclose(quats[-1], [1.0, 0.0, 0.0, 0.0], atol=1e-12)  # 4π: back to +1
    np.testing.assert_allclose(lie.rotation_from_quaternion(quats), g[:, :3, :3], atol=1e-12)


def _gif_frames(path):
    with Image.open(path) as image:
        return [np.asarray(f.convert("RGB"), float) for f in ImageSequence.Iterator(image)]


def _changed(first, last):
    """The fraction of pixels that differ between two pictures."""
    return float(np.mean(np.any(first != last, axis=-1)))


def _bodies(picture):
    """An animation's 3D panel: below the title, above the panel of the turn."""
    height = picture.shape[0]
    return picture[int(0.04 * height) : int(0.78 * height)]


def test_every_plot_draws_every_kind_of_motion(motion, tmp_path):
    """Simulated, plotted and animated end to end: the files are pictures, each title names
    its frame, and the animation moves (a blank or frozen drawing fails)."""
    name, traj = motion
    frame = "the falling frame" if name == "falling_frame" else "the Galilean frame"
    fig = viz.plot_motion(traj, path=tmp_path / "motion.png")
    assert len(fig.axes) == (3 if traj.q.shape[1] else 2)
    assert frame in fig.axes[0].get_title()
    fig = viz.plot_drift(traj, path=tmp_path / "drift.png")
    assert "in the Galilean frame" in fig.axes[0].get_title()
    width, height, _ = picture_size(tmp_path / "motion.png")
    assert width == 700 and picture_size(tmp_path / "drift.png") == (700, 400, 1)
    path = viz.animate(traj, tmp_path / "motion.gif", frames=3, size=2.0, dpi=60)
    assert picture_size(path) == (120, 150, 3)
    frames = _gif_frames(path)
    assert _changed(_bodies(frames[0]), _bodies(frames[-1])) > 0.05  # the bodies moved
    for picture in frames:  # nothing drawn runs off the picture (labels were clipped)
        border = np.concatenate([picture[0], picture[-1], picture[:, 0], picture[:, -1]])
        assert np.all(border == 255.0)


def test_animation_gif(spin, tmp_path):
    path = viz.animate(spin, tmp_path / "spin.gif", frames=5, size=3.0, dpi=60)
    assert picture_size(path) == (180, 225, 5)
    assert [p.name for p in tmp_path.iterdir()] == ["spin.gif"]  # no temporary left


def _turning(axis, angles):
    """Poses turning about a fixed unit `axis` by `angles`, from a tilted start."""
    start = lie.so3_exp(jnp.array([0.3, -0.2, 0.5]))
    R = lie.so3_exp(jnp.asarray(angles)[:, None] * jnp.asarray(axis)[None]) @ start
    return jnp.zeros((len(angles), 4, 4)).at[:, :3, :3].set(R).at[:, 3, 3].set(1.0)


def test_turn_axis_and_angle_of_a_turn():
    axis = np.array([2.0, -1.0, 2.0]) / 3.0
    angles = np.linspace(0.0, 1.3, 9)
    g = _turning(axis, angles)
    np.testing.assert_allclose(viz.turn_axis(g), axis, atol=1e-12)
    np.testing.assert_allclose(viz.turn_angles(g, axis), angles, atol=1e-12)
    # Turning backwards: the axis flips so that the turn about it is positive.
    np.testing.assert_allclose(viz.turn_axis(g[::-1]), -axis, atol=1e-12)
    assert viz.turn_axis(_turning(axis, np.zeros(3))) is None


def test_turn_axis_of_whole_turns_and_their_angle():
    """Nearly two whole turns end close to the start: the axis is the way's principal
    direction, and the angle adds up past 2π."""
    axis = np.array([0.0, 0.6, 0.8])
    angles = np.linspace(0.0, 3.9 * np.pi, 40)
    g = _turning(axis, angles)
    np.testing.assert_allclose(viz.turn_axis(g), axis, atol=1e-12)
    np.testing.assert_allclose(viz.turn_angles(g, axis), angles, atol=1e-12)


def test_frame_names():
    body = BOX.rigid_body(1.0)
    moving = bd.MovingFrame(lambda t: jnp.eye(4))
    names = [viz.frame_name(bd.Scene(body, frame=f)) for f in (None, bd.FreeFalling(),
             bd.Boosted([1.0, 0.0, 0.0]), moving)]  # fmt: skip
    assert names == [
        "the Galilean frame", "the falling frame", "the boosted frame", "the moving frame"
    ]  # fmt: skip


def test_a_chosen_view(spin, tmp_path):
    """`view` sets the axis looked along (and the turn plotted): another picture."""
    default = viz.animate(spin, tmp_path / "default.gif", frames=2, size=2.0, dpi=50)
    down = viz.animate(spin, tmp_path / "down.gif", frames=2, size=2.0, dpi=50, view=(0, 0, -1))
    assert _changed(_gif_frames(default)[-1], _gif_frames(down)[-1]) > 0.05
