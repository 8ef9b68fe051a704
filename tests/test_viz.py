"""Pictures: written headless at the expected size, and drawing the right bodies."""

import diffrax
import jax.numpy as jnp
import numpy as np
import pytest
from systems import affine_body, chain, picture_size

import bundledyn as bd
from bundledyn import lie, viz


@pytest.fixture(scope="module")
def spin():
    body = bd.Box((0.6, 0.4, 0.2)).rigid_body(1.0)
    state = bd.State(jnp.eye(4), (), jnp.array([0.05, 6.0, 0.05, 0.2, 0.0, 0.1]))
    saveat = diffrax.SaveAt(ts=jnp.linspace(0.0, 3.0, 31))
    return bd.simulate(bd.Scene(body), state, 3.0, saveat=saveat)


def test_diagnostic_plots(spin, tmp_path):
    fig = viz.plot_drift(spin, path=tmp_path / "drift.png")
    assert len(fig.axes) == 2
    assert picture_size(tmp_path / "drift.png") == (700, 400, 1)
    fig = viz.plot_motion(spin, path=tmp_path / "motion.svg")
    assert len(fig.axes) == 2  # a rigid body has no shape panel
    assert (tmp_path / "motion.svg").read_text().lstrip().startswith("<?xml")


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


def test_animation_gif(spin, tmp_path):
    path = viz.animate(spin, tmp_path / "spin.gif", frames=5, size=3.0, dpi=60)
    assert picture_size(path) == (180, 180, 5)
    assert [p.name for p in tmp_path.iterdir()] == ["spin.gif"]  # no temporary left


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


def test_an_affine_bodys_motion_is_animated(tmp_path):
    """The whole path for an affine body: simulate, animate (it raised an IndexError on
    every affine trajectory), and the picture changes as the body turns and stretches."""
    body = affine_body()
    state = bd.State(jnp.eye(4), jnp.zeros(6), jnp.array([0.0, 2.0, 0.5, 0.0, 0.0, 0.0]),
                     jnp.array([0.3, -0.2, 0.1, 0.0, 0.2, 0.0]))  # fmt: skip
    saveat = diffrax.SaveAt(ts=jnp.linspace(0.0, 1.0, 6))
    traj = bd.simulate(bd.Scene(body), state, 1.0, saveat=saveat)
    path = viz.animate(traj, tmp_path / "affine.gif", frames=3, size=2.0, dpi=50)
    assert picture_size(path) == (100, 100, 3)
    from PIL import Image, ImageSequence

    with Image.open(path) as image:
        first, *_, last = [
            np.asarray(f.convert("RGB"), float) for f in ImageSequence.Iterator(image)
        ]
    assert np.mean(np.any(first != last, axis=-1)) > 0.01  # the body moved in the picture


def test_attitude_quaternions_are_continuous():
    angles = jnp.linspace(0.0, 4.0 * np.pi, 200)
    axis = jnp.array([1.0, 2.0, 2.0]) / 3.0
    g = jnp.zeros((200, 4, 4)).at[:, 3, 3].set(1.0)
    g = g.at[:, :3, :3].set(lie.so3_exp(angles[:, None] * axis))
    quats = viz.attitude_quaternions(g)
    assert np.abs(np.diff(quats, axis=0)).max() < 0.04  # no sign jumps
    np.testing.assert_allclose(quats[-1], [1.0, 0.0, 0.0, 0.0], atol=1e-12)  # 4π: back to +1
    np.testing.assert_allclose(lie.rotation_from_quaternion(quats), g[:, :3, :3], atol=1e-12)
