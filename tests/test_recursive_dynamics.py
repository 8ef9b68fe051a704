"""The recursive accelerations of a tree (articulated bodies) against the dense field.

`_recursive_dynamics` solves (2.6)–(2.7) without the metric; here it meets the dense terms
(`bundle_geometry`, `locked_acceleration`, `shape_acceleration`, the driven shape equation)
and the modes' whole field on imported trees with hinges, slides, balls, welds, composite
joints, rotor inertia, springs, dampers and gravity, floating and held: values to 1e-12,
forward-mode Jacobians and a reverse-mode gradient to 1e-10, finite values and
derivatives where a ball joint is at its home pose or half a turn from it, and no more
rounding noise than the dense field where a joint's $D = S^TI^AS$ is ill-conditioned.
"""

import functools
import importlib.util
import pathlib
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import bundledyn as bd
from bundledyn._systems._recursive_dynamics import (
    body_twist,
    driven_accelerations,
    floating_accelerations,
    tree_motion,
)

pytest.importorskip("mujoco")

MODELS = pathlib.Path(bd.__file__).parent / "models"

# A floating tree: a hinge, a ball, welds with mass in the middle of a chain (one alone at
# its depth: a level of welds), a slide, two hinges on one body (a universal joint), a hinge
# and a slide on one body (composite), rotor inertia, springs and dampers.
FLOATING = """
<mujoco model="floating">
  <option gravity="0.3 -0.2 -9.81"/>
  <default><geom contype="0" conaffinity="0"/></default>
  <worldbody>
    <body name="base" pos="0 0 1">
      <freejoint/>
      <inertial pos="0.02 -0.01 0.03" mass="4" fullinertia="0.12 0.1 0.08 0.01 -0.004 0.002"/>
      <body name="upper" pos="0.2 0 0">
        <joint name="hip" type="hinge" axis="0 1 0.3" pos="-0.05 0 0" damping="0.4"
               stiffness="3" springref="0.2" armature="0.02"/>
        <inertial pos="0.1 0.01 0" mass="1.2" diaginertia="0.01 0.02 0.015"/>
        <body name="plate" pos="0.25 0 0">
          <inertial pos="0.02 0 0.01" mass="0.5" diaginertia="0.002 0.003 0.004"/>
          <body name="fore" pos="0.05 0 0">
            <joint name="knee" type="ball" pos="0 0.01 0"/>
            <inertial pos="0.1 0 -0.02" mass="0.8" diaginertia="0.004 0.006 0.005"/>
            <body name="hand" pos="0.2 0 0">
              <joint name="reach" type="slide" axis="1 0.2 0" damping="0.3"/>
              <inertial pos="0.03 0 0" mass="0.3" diaginertia="0.001 0.0012 0.0008"/>
              <body name="tool" pos="0.05 0 0" euler="0.3 0 0.2">
                <inertial pos="0.02 0 0" mass="0.2" diaginertia="0.0004 0.0005 0.0006"/>
                <body name="tip" pos="0.05 0 0">
                  <joint name="snap" type="hinge" axis="0 1 0"/>
                  <inertial pos="0.01 0 0" mass="0.05" diaginertia="0.0001 0.0001 0.0001"/>
                </body>
              </body>
            </body>
          </body>
        </body>
      </body>
      <body name="neck" pos="-0.2 0 0.1">
        <joint name="yaw" type="hinge" axis="0 0 1" armature="0.01"/>
        <joint name="pitch" type="hinge" axis="0 1 0"/>
        <inertial pos="-0.05 0 0.05" mass="0.7" diaginertia="0.003 0.002 0.004"/>
        <body name="head" pos="-0.1 0 0.1">
          <joint name="turn" type="hinge" axis="1 0 0" pos="0 0.02 0" stiffness="1"/>
          <joint name="push" type="slide" axis="0 0 1" damping="0.2"/>
          <inertial pos="0 0.01 0.02" mass="0.4" diaginertia="0.001 0.001 0.002"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""

# A root welded to the world (held at its pose), two branches.
WELDED = """
<mujoco model="welded">
  <default><geom contype="0" conaffinity="0"/></default>
  <worldbody>
    <body name="base" pos="0.1 -0.2 1.0" quat="0.95 0.1 0.2 -0.2">
      <inertial pos="0 0 0" mass="5" diaginertia="0.1 0.1 0.1"/>
      <body name="upper" pos="0 0 -0.05">
        <joint name="shoulder" type="hinge" axis="0 1 0.2" damping="0.5"/>
        <inertial pos="0.02 0.01 -0.2" mass="1.3" diaginertia="0.02 0.021 0.004"/>
        <body name="fore" pos="0.01 0 -0.4">
          <joint name="wrist" type="ball" pos="0 0 0.01"/>
          <inertial pos="0.01 0 -0.05" mass="0.3" diaginertia="0.001 0.0012 0.0008"/>
        </body>
      </body>
      <body name="side" pos="0.1 0 0">
        <joint name="lift" type="slide" axis="0 0 1" stiffness="20" armature="0.1"/>
        <inertial pos="0.05 0 0" mass="0.6" diaginertia="0.002 0.002 0.002"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""

# Two trees hanging from the world (its stand-in is the held base): a cart-pole on a slide
# and a hinge, and a free ball (three slides and a ball joint on one body: a block of six).
HANGING = """
<mujoco model="hanging">
  <default><geom contype="0" conaffinity="0"/></default>
  <worldbody>
    <body name="cart" pos="0 0 0.5">
      <joint name="rail" type="slide" axis="1 0 0" damping="0.1"/>
      <joint name="swivel" type="hinge" axis="0 0 1"/>
      <inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>
      <body name="pole" pos="0 0 0.1">
        <joint name="tilt" type="hinge" axis="0 1 0" stiffness="2"/>
        <inertial pos="0 0 0.3" mass="0.2" diaginertia="0.006 0.006 0.0002"/>
      </body>
    </body>
    <body name="ball" pos="1 0 1">
      <freejoint/>
      <inertial pos="0.01 0 0" mass="0.5" diaginertia="0.002 0.003 0.0025"/>
      <body name="tail" pos="0.1 0 0">
        <joint name="flap" type="hinge" axis="0 0 1"/>
        <inertial pos="0.05 0 0" mass="0.1" diaginertia="0.0001 0.0002 0.0002"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def _package_file(package, path):
    """A model file shipped inside an installed package, or None (without importing it)."""
    spec = importlib.util.find_spec(package)
    if spec is None or not spec.submodule_search_locations:
        return None
    file = pathlib.Path(next(iter(spec.submodule_search_locations))) / path
    return file if file.is_file() else None


SOURCES = {
    "floating": FLOATING,
    "welded": WELDED,
    "hanging": HANGING,
    "chain5": MODELS / "chain5.xml",
    "tree4": MODELS / "tree4.xml",
    "bicycle": MODELS / "bicycle.xml",
}
# Larger published trees, where installed: held (the dog, 85 coordinates, a free joint
# on the held world) and floating (gymnasium's humanoid).
PUBLISHED = {
    "dm_control dog": ("dm_control", "suite/dog.xml"),
    "gymnasium humanoid": ("gymnasium", "envs/mujoco/assets/humanoid.xml"),
}


# The published trees compile for half a minute each: in the slow part.
NAMES = [*SOURCES, *(pytest.param(name, marks=pytest.mark.slow) for name in PUBLISHED)]


@functools.cache
def scene(name) -> bd.Scene:
    """The scene of a model, as `Scene.from_mjcf` imports it with its passive forces and gravity."""
    if name in PUBLISHED:
        file = _package_file(*PUBLISHED[name])
        if file is None:
            pytest.skip(f"{PUBLISHED[name][0]} is not installed")
        source = str(file)
    else:
        source = str(SOURCES[name]) if isinstance(SOURCES[name], pathlib.Path) else SOURCES[name]
    with warnings.catch_warnings():
        # The import lists what it leaves out (contacts, actuators, limits): not what is tested.
        warnings.simplefilter("ignore")
        return bd.Scene.from_mjcf(source, passive=True, gravity=True)


# Both errors in numpy: in jax.numpy each would run op by op, compiling each op per shape.
def relative_error(actual, expected):
    """$|a - e| / |e|$ over all entries."""
    actual, expected = np.asarray(actual), np.asarray(expected)
    return float(np.linalg.norm(actual - expected) / np.linalg.norm(expected))


def largest_error(actual, expected):
    r"""$\max|a - e|$ over the largest $|e|$ (or over 1 where the expected array is zero: a
    held base's field does not depend on the pose)."""
    actual, expected = np.asarray(actual), np.asarray(expected)
    scale = float(np.max(np.abs(expected)))
    return float(np.max(np.abs(actual - expected))) / (scale if scale > 0 else 1.0)


def random_motion(d, seed):
    """A shape well inside the balls' charts, velocities, and forces: `(q, U, qdot, F, Q,
    xi, xi_dot)`."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(-1.0, 1.0, d)
    U, F, xi, xi_dot = rng.normal(size=(4, 6))
    qdot, Q = rng.normal(size=(2, d))
    return tuple(jnp.asarray(v) for v in (q, U, qdot, F, Q, xi, xi_dot))


@eqx.filter_jit
def dense_floating(system, q, U, qdot, F, Q):
    geo = bd.bundle_geometry(system, q, U, qdot)
    xi = U - geo.A @ qdot
    return xi, bd.locked_acceleration(geo, F), bd.shape_acceleration(geo, F, Q)


@eqx.filter_jit
def recursive_floating(system, q, U, qdot, F, Q):
    motion = tree_motion(system, q, qdot)
    xi = body_twist(motion, U)
    return (xi, *floating_accelerations(system, motion, U, xi, F, Q))


# The dense reference compiled as one program, not run op by op.
dense_driven = eqx.filter_jit(bd.driven_shape_acceleration)


@eqx.filter_jit
def recursive_driven(system, q, qdot, xi, xi_dot, Q):
    return driven_accelerations(system, tree_motion(system, q, qdot), xi, xi_dot, Q)


@pytest.mark.parametrize("name", NAMES)
def test_accelerations_equal_the_dense_terms(name):
    r"""For random states and forces, $(\xi, \dot U, \ddot q)$ of a floating base equal
    the dense (2.6)–(2.7) terms and $\ddot q$ of a driven base the driven shape equation's
    (`driven_shape_acceleration`), to 1e-12."""
    system = scene(name).system
    for seed in range(2):
        q, U, qdot, F, Q, xi, xi_dot = random_motion(system.shape_dim, seed)
        dense = dense_floating(system, q, U, qdot, F, Q)
        ours = recursive_floating(system, q, U, qdot, F, Q)
        for what, a, e in zip(("xi", "Udot", "qddot"), ours, dense, strict=True):
            assert relative_error(a, e) < 1e-12, (name, what, relative_error(a, e))
        expected = dense_driven(system, q, xi, xi_dot, qdot, Q)
        driven = recursive_driven(system, q, qdot, xi, xi_dot, Q)
        assert relative_error(driven, expected) < 1e-12, relative_error(driven, expected)


def with_algorithm(scene: bd.Scene, algorithm) -> bd.Scene:
    """`scene` with its field computed by `algorithm`."""
    return bd.Scene(
        scene.system, scene.effects, frame=scene.frame, mode=scene.mode, algorithm=algorithm
    )


def random_integration_state(scene: bd.Scene, seed, scale=1.0):
    """A random `y` of the scene's mode at t = 0.3 (a turned and displaced pose)."""
    rng = np.random.default_rng(seed)
    d = scene.system.shape_dim
    g = bd.lie.se3_exp(jnp.asarray(rng.normal(size=6)))
    q = jnp.asarray(scale * rng.uniform(-1.0, 1.0, d))
    state = bd.State(g, q, jnp.asarray(rng.normal(size=6)), jnp.asarray(rng.normal(size=d)))
    return bd.SceneTerm(scene).encode(0.3, state)


@eqx.filter_jit
def both_fields(scene, y):
    """The field at `y` by the articulated-body recursions and by the dense metric."""
    fields = []
    for algorithm in (bd.ArticulatedBodyField(), bd.DenseField()):
        s = with_algorithm(scene, algorithm)
        fields.append(jnp.concatenate(s.mode.body_field(s, 0.3, y)))
    return fields


@pytest.mark.parametrize("name", NAMES)
def test_the_scenes_field_is_the_dense_one(name):
    r"""The whole field of the scene, with springs, dampers and gravity (a field for the
    recursions, forces read off the metric for the dense terms): equal to the dense field
    (floating: $(\xi, \dot q, \dot U, \ddot q)$; held: $(\xi, \dot q, \ddot q)$) to 1e-12."""
    s = scene(name)
    assert isinstance(s.algorithm, bd.ArticulatedBodyField)
    for seed in range(2):
        ours, dense = both_fields(s, random_integration_state(s, seed))
        assert relative_error(ours, dense) < 1e-12, relative_error(ours, dense)


@pytest.mark.parametrize(
    "variant",
    [
        lambda s: bd.Scene(s.system, s.effects, frame=bd.FreeFalling(9.81)),
        lambda s: bd.Scene(s.system, s.effects, frame=bd.Boosted(jnp.array([0.3, -0.2, 0.5]))),
        lambda s: bd.Scene(s.system, [*s.effects, bd.Gravity(2.0, gravitational_mass=0.5)]),
        lambda s: bd.Scene(s.system, [bd.Gravity(centre_offset=jnp.array([0.01, 0.0, 0.02]))]),
    ],
    ids=["falling frame", "boosted frame", "gravitational mass", "centre offset"],
)
def test_frames_and_gravity_apart_from_the_inertial_mass(variant):
    r"""Seen from a falling or a boosted frame (the mode's frame terms around the
    recursions), and with a `Gravity` that is not a field on the inertial mass (its forces
    then enter the recursions as forces): the field equals the dense one to 1e-12."""
    s = variant(scene("floating"))
    assert isinstance(s.algorithm, bd.ArticulatedBodyField)
    ours, dense = both_fields(s, random_integration_state(s, 6))
    assert relative_error(ours, dense) < 1e-12, relative_error(ours, dense)


# tree4 spinning at 100 rad/s (the stress cases' `high_spin`) at t = 0.8 s, rounded:
# `(q, xi, qdot)` with its slide flung 18.7 m out, where the ball joint above it has
# $D = S^TI^AS$ with eigenvalues from 9.5e-3 to 457.
FLUNG = (
    (-1.918, 0.674, 1.799, -1.354, 1.576, 18.726),
    (-15.37, 82.04, -2.71, -6.09, 2.02, 2.91),
    (-57.14, 14.4, -106.07, -149.91, 147.63, 21.39),
)


def test_no_noisier_than_the_dense_field_where_a_joint_is_ill_conditioned():
    r"""Where a joint's $D$ is ill-conditioned (`FLUNG`), the field's rounding noise, its
    largest change under one-ulp nudges of the integration state over its largest entry,
    is below the dense field's (with $D^{-1}$ formed explicitly it was five to ten times
    the dense field's, and an adaptive solve through such states took ten times the
    steps), and the two fields agree to the dense one's noise."""
    s = scene("tree4")
    g, x = bd.SceneTerm(s).encode(0.3, bd.State(jnp.eye(4), *(jnp.asarray(v) for v in FLUNG)))
    x = np.asarray(x)
    at_x = both_fields(s, (g, jnp.asarray(x)))
    rng = np.random.default_rng(0)
    changes = []
    for _ in range(32):
        up = rng.random(x.size) < 0.5
        nudged = np.where(up, np.nextafter(x, np.inf), np.nextafter(x, -np.inf))
        fields = both_fields(s, (g, jnp.asarray(nudged)))
        changes.append([largest_error(f, f0) for f, f0 in zip(fields, at_x, strict=True)])
    ours, dense = np.max(changes, axis=0)
    assert ours < dense, (ours, dense)
    assert largest_error(*at_x) < 10 * dense, (largest_error(*at_x), dense)


@pytest.mark.parametrize("name", ["floating", "welded", "hanging", "chain5"])
def test_forward_jacobians_equal_the_dense_ones(name):
    """`jax.jacfwd` of the field in the integration state $x$ and the pose: equal to the
    dense field's to 1e-10 (relative to its largest entry)."""
    y = random_integration_state(scene(name), 3)
    expected, actual = (compiled_field(name, dense)[1](*y) for dense in (True, False))
    for a, e in zip(actual, expected, strict=True):
        assert largest_error(a, e) < 1e-10, largest_error(a, e)


def field(name, algorithm):
    """The field of the scene `name` by `algorithm`, as a function of the pose and `x`."""
    s = with_algorithm(scene(name), algorithm)

    def f(g, x):
        return jnp.concatenate(s.mode.body_field(s, 0.3, (g, x)))

    return f


@functools.cache
def compiled_field(name, dense):
    """The field of the scene `name`, by `DenseField` or by the recursions, and its forward
    Jacobian in the pose and `x`, each compiled once for the tests that use them."""
    f = field(name, bd.DenseField() if dense else bd.ArticulatedBodyField())
    return jax.jit(f), jax.jit(jax.jacfwd(f, argnums=(0, 1)))


def test_gradient_equals_the_dense_one():
    """`jax.grad` of a function of the field (reverse mode through the passes' gathers and
    barriers) equals the dense field's to 1e-10."""
    y = random_integration_state(scene("floating"), 4)

    def gradient(algorithm):
        f = field("floating", algorithm)
        return jax.jit(jax.grad(lambda x: jnp.sum(jnp.sin(f(y[0], x)))))(y[1])

    ours, dense = gradient(bd.ArticulatedBodyField()), gradient(bd.DenseField())
    assert largest_error(ours, dense) < 1e-10


def test_the_passes_reverse_mode_scatters_nothing_per_level():
    """Reverse mode through the passes has as many scatter-adds (a loop of kernels each on
    XLA's CPU) for a tree of 10 levels as for one of 3, each level two bodies hanging from
    the same parent: each level's parents and children are taken through a 0/1 matrix,
    and the levels split apart in one `split`."""
    from systems import box_body

    def scatters(levels):
        links = [
            bd.Link(box_body(1.0, (0.3, 0.1, 0.1)), bd.Revolute((0.0, 0.0, 1.0)), parent, np.eye(4))
            for level in range(levels)
            for parent in [max(2 * level - 1, 0)] * 2
        ]
        system = bd.Multibody(box_body(2.0, (0.5, 0.2, 0.1)), links)
        d = system.shape_dim
        motion = tree_motion(system, jnp.full(d, 0.2), jnp.full(d, 0.3))
        xi, xi_dot = jnp.full(6, 0.1), jnp.full(6, 0.2)

        def passes(motion):
            return driven_accelerations(system, motion, xi, xi_dot, jnp.zeros(d))

        vjp = lambda m: jax.vjp(passes, m)[1](jnp.ones(d))  # noqa: E731
        return str(jax.make_jaxpr(vjp)(motion)).count("scatter")

    assert scatters(10) == scatters(3)


@pytest.mark.parametrize("turn", [0.0, np.pi])
def test_finite_where_a_ball_joint_is_home_or_half_a_turn_away(turn):
    r"""At $\varphi = 0$ (the exponential coordinates' removable singularity, where
    $\operatorname{dexp}$ and its derivative take their Taylor branches) and at
    $|\varphi| = \pi$, with the ball turning: the field and its forward Jacobian are
    finite and equal to the dense ones."""
    s = scene("floating")
    system = s.system
    assert isinstance(system, bd.Multibody)
    d = system.shape_dim
    kinds, starts = np.array(system.tables.kinds), np.array(system.tables.q_start)
    ball = (starts[kinds == "ball"][:, None] + np.arange(3)).reshape(-1)
    rng = np.random.default_rng(5)
    q = np.zeros(d)
    q[ball] = turn * np.array([0.6, 0.0, 0.8])
    state = bd.State(
        jnp.eye(4), jnp.asarray(q), jnp.asarray(rng.normal(size=6)), jnp.asarray(rng.normal(size=d))
    )
    g, x = bd.SceneTerm(s).encode(0.3, state)
    (ours, ours_jacobian), (dense, dense_jacobian) = (
        compiled_field("floating", dense) for dense in (False, True)
    )
    value, (_, jacobian) = ours(g, x), ours_jacobian(g, x)
    assert np.all(np.isfinite(value)) and np.all(np.isfinite(jacobian))
    assert relative_error(value, dense(g, x)) < 1e-12
    assert largest_error(jacobian, dense_jacobian(g, x)[1]) < 1e-10


COUPLED = """
<mujoco model="coupled">
  <default><geom contype="0" conaffinity="0"/></default>
  <worldbody>
    <body name="base"><freejoint/><inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/>
      <body name="a" pos="0.2 0 0"><joint name="j1" type="hinge" axis="0 0 1"/>
        <inertial pos="0.1 0 0" mass="0.5" diaginertia="0.01 0.01 0.01"/>
        <body name="b" pos="0.2 0 0"><joint name="j2" type="hinge" axis="0 0 1"/>
          <inertial pos="0.1 0 0" mass="0.5" diaginertia="0.01 0.01 0.01"/>
        </body>
      </body>
    </body>
  </worldbody>
  <equality><joint joint1="j2" joint2="j1" polycoef="0 1 0 0 0"/></equality>
</mujoco>
"""


@pytest.mark.parametrize(
    "system",
    [
        lambda: scene("floating").system.with_section(2),  # pyright: ignore[reportAttributeAccessIssue]
        lambda: bd.Scene.from_mjcf(COUPLED).system,
        lambda: bd.RigidBody(1.0, np.zeros(3), np.eye(3)),
    ],
    ids=["resectioned", "coupled", "rigid body"],
)
def test_refuses_what_it_does_not_cover(system):
    """A tree whose section is not its base, coupled coordinates and other systems are
    refused by name, not computed wrongly: by the recursions, and by a scene asked for
    them at construction; a scene of such a system takes the dense field by default."""
    with pytest.raises(ValueError, match="recursive accelerations need a `Multibody`"):
        tree_motion(system(), jnp.zeros(2), jnp.zeros(2))
    with pytest.raises(ValueError, match="Use `DenseField\\(\\)`"):
        bd.Scene(system(), algorithm=bd.ArticulatedBodyField())
    assert isinstance(bd.Scene(system()).algorithm, bd.DenseField)


def test_an_import_takes_the_algorithm_it_is_asked_for():
    """`Scene.from_mjcf(..., algorithm=)` keeps the model's base and effects with the
    algorithm asked for, and refuses the recursions where its section is not the base."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        dense = bd.Scene.from_mjcf(WELDED, passive=True, gravity=True, algorithm=bd.DenseField())
        with pytest.raises(ValueError, match="Use `DenseField"):
            bd.Scene.from_mjcf(FLOATING, section=2, algorithm=bd.ArticulatedBodyField())
    assert isinstance(dense.algorithm, bd.DenseField)
    assert isinstance(dense.mode, bd.PrescribedBaseMode)
    assert len(dense.effects) == len(scene("welded").effects)
