"""Scene files: what they build, and the messages for every kind of mistake."""

import textwrap

import jax.numpy as jnp
import numpy as np
import pytest
from systems import CHAIN5_REFS

import bundledyn as bd

RIGID = """
[system]
type = "rigid_body"
mass = 2.0
inertia = [1.0, 2.0, 3.0]
centre = [0.0, 0.1, 0.0]

[time]
t1 = 1.0
"""


def _write(tmp_path, text, name="scene.toml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def test_shipped_falling_cat():
    sf = bd.SceneFile.load(bd.scenes / "falling_cat.toml")
    cat = sf.scene.system
    assert isinstance(cat, bd.Multibody) and cat.num_bodies == 2 and cat.shape_dim == 2
    assert cat.names == ("front", "rear") and cat.joint_types == ("free", "universal")
    for t in (0.0, 0.3, 0.77):
        expected = 0.6 * np.array([np.sin(2 * np.pi * t), 1 - np.cos(2 * np.pi * t)])
        np.testing.assert_allclose(sf.scene.shape.q_of_t(t), expected, atol=1e-15)
    # Zero momentum: U = xi + A qdot = 0.
    U = sf.state.xi + bd.connection(cat, sf.state.q) @ sf.state.qdot
    np.testing.assert_allclose(U, 0.0, atol=1e-15)
    assert all(isinstance(s, bd.Capsule) for s in sf.solids)
    np.testing.assert_allclose(
        cat.inertia[0], jnp.diag(bd.Capsule(0.08, 0.34).principal_moments(1.5))
    )
    assert isinstance(sf.solver, bd.RKMK54) and sf.options["rtol"] == 1e-10
    assert sf.output == {
        "trajectory": "falling_cat.npz",
        "plots": True,
        "animation": True,
        "frames": 60,
    }


def test_rigid_body_with_moments(tmp_path):
    sf = bd.SceneFile.load(_write(tmp_path, RIGID))
    body = sf.scene.system
    np.testing.assert_allclose(body.inertia, np.diag([1.0, 2.0, 3.0]))
    np.testing.assert_allclose(body.com, [0.0, 0.1, 0.0])
    assert sf.state.q.shape == (0,) and sf.solids is None and sf.saves == 101


def test_affine_body_of_a_solid_ellipsoid(tmp_path):
    path = _write(
        tmp_path,
        """
        [system]
        type = "affine_body"
        mass = 3.0
        radii = [0.5, 0.3, 0.2]
        [[effects]]
        type = "shape_spring"
        stiffness = 40.0
        [initial]
        q = [0.1, 0, 0, 0, 0, 0]
        [time]
        t1 = 0.5
        """,
    )
    sf = bd.SceneFile.load(path)
    np.testing.assert_allclose(sf.scene.system.second_moment, 0.6 * np.diag([0.25, 0.09, 0.04]))
    (spring,) = sf.scene.effects
    np.testing.assert_allclose(spring.stiffness, 40.0 * np.ones(6))
    assert isinstance(sf.solids[0], bd.Ellipsoid)


def test_mjcf_model_effects_frame_and_solver(tmp_path):
    path = _write(
        tmp_path,
        """
        [system]
        type = "mjcf"
        model = "chain5.xml"
        [[effects]]
        type = "gravity"
        g = 9.8
        direction = [0, 0, -2]
        [[effects]]
        type = "shape_damper"
        damping = 0.1
        [frame]
        type = "free_falling"
        g = 9.8
        [initial]
        position = [0, 0, 1]
        rotation = [0, 0, 1.5707963267948966]
        xi = [0, 0, 1, 0, 0, 0]
        [time]
        t1 = 2.0
        saves = 11
        [solver]
        method = "RKMK4"
        dt0 = 0.01
        """,
    )
    with pytest.warns(UserWarning, match=CHAIN5_REFS):
        sf = bd.SceneFile.load(path)
    with pytest.warns(UserWarning, match=CHAIN5_REFS):
        chain = bd.Multibody.from_mjcf(bd.models / "chain5.xml")
    assert sf.scene.system.shape_dim == chain.shape_dim
    np.testing.assert_allclose(sf.scene.system.mass, chain.mass)
    gravity, damper = sf.scene.effects
    assert isinstance(gravity, bd.Gravity) and isinstance(damper, bd.ShapeDamper)
    np.testing.assert_allclose(gravity.direction, [0, 0, -1])
    assert isinstance(sf.scene.frame, bd.FreeFalling)
    np.testing.assert_allclose(sf.state.g[:3, 0], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(sf.state.g[:3, 3], [0, 0, 1])
    assert isinstance(sf.solver, bd.RKMK4) and sf.options["dt0"] == 0.01


def test_multibody_by_names_and_placements(tmp_path):
    path = _write(
        tmp_path,
        """
        [system]
        type = "multibody"
        [[system.bodies]]
        name = "base"
        mass = 1.0
        solid = "box"
        size = [0.5, 0.1, 0.1]
        [[system.bodies]]
        name = "arm"
        joint = "revolute"
        axis = [0, 0, 1]
        anchor = [-0.2, 0, 0]
        offset = [0.45, 0, 0]
        mass = 0.5
        solid = "ellipsoid"
        radii = [0.2, 0.05, 0.05]
        [[system.bodies]]
        name = "hand"
        parent = "base"
        joint = "spherical"
        rotation = [0, 1.5707963267948966, 0]
        mass = 0.2
        inertia = [0.001, 0.001, 0.001]
        [time]
        t1 = 1.0
        """,
    )
    mb = bd.SceneFile.load(path).scene.system
    assert mb.parents == (-1, 0, 0) and mb.names == ("base", "arm", "hand")
    assert mb.joint_types == ("free", "revolute", "spherical")
    np.testing.assert_allclose(mb.placement[1, :3, 3], [0.45, 0, 0])
    np.testing.assert_allclose(
        mb.placement[2, :3, :3], [[0, 0, 1], [0, 1, 0], [-1, 0, 0]], atol=1e-15
    )


def test_a_urdf_model_takes_standard_gravity(tmp_path):
    """`gravity = "model"` on a URDF is MuJoCo's default gravity (URDF states none)."""
    text = '[system]\ntype = "urdf"\nmodel = "arm.urdf"\ngravity = "model"\n[time]\nt1 = 1.0\n'
    path = _write(tmp_path, text)
    with pytest.warns(UserWarning, match="ignored"):
        (gravity,) = bd.SceneFile.load(path).scene.effects
    np.testing.assert_allclose(gravity.g * gravity.direction, [0.0, 0.0, -9.81], rtol=1e-15)


def test_load_system_reads_models_and_scenes(tmp_path):
    with pytest.warns(UserWarning, match=CHAIN5_REFS):
        assert bd.load_system(bd.models / "chain5.xml").shape_dim == 9
    with pytest.warns(UserWarning, match="ignored"):
        assert bd.load_system(bd.models / "arm.urdf").num_bodies >= 2
    assert isinstance(bd.load_system(_write(tmp_path, RIGID)), bd.RigidBody)
    with pytest.raises(bd.SceneFileError, match=r"unknown model format '\.txt'"):
        bd.load_system(_write(tmp_path, "", "model.txt"))


def _replace(text, old, new):
    assert old in text
    return text.replace(old, new)


# (how the valid RIGID scene is broken, what the message must say)
MISTAKES = {
    "unknown effect": (
        RIGID + '[[effects]]\ntype = "magnetism"\n',
        ["effects[0].type", "'magnetism'", "gravity, gravity_gradient"],
    ),
    "wrong vector length": (
        RIGID + "[initial]\nxi = [1, 2, 3, 4, 5]\n",
        ["initial.xi", "[1, 2, 3, 4, 5]", "shape (6,), got shape (5,)"],
    ),
    "non-SPD inertia": (
        _replace(
            RIGID, "inertia = [1.0, 2.0, 3.0]", "inertia = [[1, 0, 0], [0, -1, 0], [0, 0, 1]]"
        ),
        ["`[system]`", "positive definite", "-1."],
    ),
    "impossible moments": (
        _replace(RIGID, "inertia = [1.0, 2.0, 3.0]", "inertia = [1.0, 1.0, 3.0]"),
        ["`[system]`", "triangle inequality"],
    ),
    "missing model file": (
        '[system]\ntype = "mjcf"\npath = "missing.xml"\n[time]\nt1 = 1.0\n',
        ["system.path", "'missing.xml'", "no such file"],
    ),
    "typo in a field": (
        _replace(RIGID, "t1 = 1.0", "t1 = 1.0\nt2 = 2.0"),
        ["unknown field `time.t2`"],
    ),
    "missing required field": (
        _replace(RIGID, "mass = 2.0\n", ""),
        ["system.mass", "<missing>", "required"],
    ),
    "fixed step without dt0": (
        RIGID + '[solver]\nmethod = "RKMK4"\n',
        ["solver.dt0", "fixed steps"],
    ),
    "unknown solver": (
        RIGID + '[solver]\nmethod = "Euler"\n',
        ["solver.method", "'Euler'", "RKMK54"],
    ),
    "not TOML": (RIGID + "[time\n", ["not valid TOML"]),
    "shape vector of the wrong length": (
        '[system]\ntype = "affine_body"\nmass = 1.0\nradii = [1, 1, 1]\n[[effects]]\n'
        'type = "shape_spring"\nstiffness = [1, 2]\n[time]\nt1 = 1.0\n',
        ["effects[0].stiffness", "[1, 2]", "list of 6 numbers"],
    ),
    "backwards time": (_replace(RIGID, "t1 = 1.0", "t1 = -1.0"), ["time.t1", "later than t0"]),
    "a mode the system cannot take": (
        '[system]\ntype = "affine_body"\nmass = 1.0\nradii = [1, 1, 1]\n'
        '[rolling]\nsurface = "sphere"\nradius = 0.5\n[time]\nt1 = 1.0\n',
        ["broken.toml: the scene: `RollingMode`", "rigid body"],
    ),
    "a time that is not a number": (
        _replace(RIGID, "t1 = 1.0", "t1 = nan"),
        ["time.t1", "nan", "finite"],
    ),
    "a misspelt field": (
        _replace(RIGID, "mass = 2.0", "mas = 2.0"),
        ["system.mass", "required", "`system.mas`", "misspelling"],
    ),
    "a relative tolerance above 1": (
        RIGID + "[solver]\nrtol = 10\n",
        ["solver.rtol", "10", "between 0 and 1"],
    ),
    "a negative tolerance": (
        RIGID + "[solver]\nrtol = -1e-8\n",
        ["solver.rtol", "-1e-08", "between 0 and 1"],
    ),
    "tolerances below rounding": (
        RIGID + "[solver]\nrtol = 1e-20\natol = 1e-20\n",
        ["solver.rtol", "rounding error"],
    ),
    "no steps": (RIGID + "[solver]\nmax_steps = 0\n", ["solver.max_steps", "whole number ≥ 1"]),
    "a negative step": (
        RIGID + '[solver]\nmethod = "RKMK4"\ndt0 = -0.1\n',
        ["solver.dt0", "positive"],
    ),
    "no frames": (
        RIGID + "[output]\nanimation = true\nframes = 0\n",
        ["output.frames", "whole number ≥ 2"],
    ),
    "a trajectory in a folder": (
        RIGID + '[output]\ntrajectory = "sub/dir/x.npz"\n',
        ["output.trajectory", "'sub/dir/x.npz'", "without folders"],
    ),
}


@pytest.mark.parametrize("mistake", MISTAKES)
def test_mistakes_name_file_field_and_value(tmp_path, mistake):
    text, fragments = MISTAKES[mistake]
    path = _write(tmp_path, text, "broken.toml")
    with pytest.raises(bd.SceneFileError) as info:
        bd.SceneFile.load(path)
    message = str(info.value)
    assert str(path) in message
    for fragment in fragments:
        assert fragment in message, (fragment, message)


def test_missing_scene_file(tmp_path):
    with pytest.raises(bd.SceneFileError, match="cannot read the file"):
        bd.SceneFile.load(tmp_path / "nowhere.toml")


def test_shipped_rolling_disc_rolls_and_touches_the_plane():
    sf = bd.SceneFile.load(bd.scenes / "rolling_disc.toml")
    mode = sf.scene.mode
    assert isinstance(mode, bd.RollingMode) and isinstance(mode.surface, bd.DiscContact)
    np.testing.assert_allclose(mode.surface.radius, 0.2)
    # placed on the plane, with the rolling twist (omega, c x omega)
    g, omega = sf.state.g, sf.state.xi[:3]
    c = mode.contact(g[:3, :3])
    np.testing.assert_allclose((g[:3, :3] @ c + g[:3, 3])[2], 0.0, atol=1e-15)
    np.testing.assert_allclose(sf.state.xi[3:], jnp.cross(c, omega), atol=1e-15)
    np.testing.assert_allclose(omega, [0.0, 6.0, 0.7])


def test_shipped_sleigh_skates_on_its_blade():
    sf = bd.SceneFile.load(bd.scenes / "skating_sleigh.toml")
    mode = sf.scene.mode
    assert isinstance(mode, bd.SkatingMode) and isinstance(mode.surface, bd.PointContact)
    np.testing.assert_allclose(mode.surface.point, [-0.4, 0.0, 0.0])
    np.testing.assert_allclose(mode.blade_axis, [0.0, 1.0, 0.0])
    # spun from rest: the blade's tip at rest, the centre of mass moving sideways
    np.testing.assert_allclose(sf.state.xi, [0.0, 0.0, 1.5, 0.0, 0.6, 0.0], atol=1e-15)
    assert float(jnp.max(jnp.abs(mode.constraint_residual(sf.scene, sf.state)))) == 0.0


@pytest.mark.parametrize(
    "table, message",
    [
        ('[rolling]\nsurface = "cone"\n', "must be one of"),
        ('[rolling]\nsurface = "sphere"\nradius = -1.0\n', "positive"),
        (
            '[rolling]\nsurface = "sphere"\nradius = 0.1\n[initial]\nxi = [0, 0, 0, 0, 0, 0]\n',
            "omega",
        ),
        ('[rolling]\nsurface = "ellipsoid"\n', "semi_axes"),
        ('[skating]\nsurface = "sphere"\nradius = 0.1\n', "must be one of"),
        ('[skating]\nsurface = "point"\n', "point"),
        (
            '[rolling]\nsurface = "sphere"\nradius = 0.1\n[skating]\nsurface = "point"\n'
            "point = [0, 0, 0]\n",
            "one of",
        ),
        (
            '[rolling]\nindependent = "all"\n[[rolling.wheels]]\nbody = "wheel"\n'
            'surface = "disc"\nradius = 0.2\n',
            "list of whole numbers",
        ),
        ('[rolling]\nwheel = "wheel"\nsurface = "disc"\nradius = 0.2\n', "multibody tree"),
        ('[rolling]\n[[rolling.wheels]]\nsurface = "disc"\nradius = 0.2\n', "body"),
    ],
    ids=[
        "surface",
        "radius",
        "xi",
        "semi-axes",
        "blade surface",
        "blade point",
        "both",
        "independent",
        "wheel of a rigid body",
        "wheel without a body",
    ],
)
def test_a_rolling_table_names_its_mistakes(tmp_path, table, message):
    with pytest.raises(bd.SceneFileError, match=message):
        bd.SceneFile.load(_write(tmp_path, RIGID + table))
