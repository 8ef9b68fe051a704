"""Effects (issue: dynamics): generalized forces checked against independent computations."""

import functools
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from systems import affine_body, asymmetric_body, chain, rigid_generic, rotor_chain
from traced import lowerings

import bundledyn as bd
from bundledyn import lie

SYSTEM = chain(3)
D = SYSTEM.shape_dim
KIN = bd.Kinematics(
    jnp.asarray(0.7),
    lie.se3_exp(jnp.array([0.2, -0.4, 0.3, 1.0, 0.5, -0.2])),
    jnp.array([0.3, -0.2, 0.4]),
    jnp.array([0.5, -0.1, 0.2, 0.3, 0.0, -0.4]),
    jnp.array([0.6, -0.3, 0.2]),
)


@functools.partial(jax.jit, static_argnums=(0, 1))  # one program, not one per primitive
def _body_twist_fd(body, h=1e-4):
    """Body twist of one body along the motion, by 4th-order differences of its pose."""

    def pose(t):
        return lie.se3_exp(t * KIN.xi) @ SYSTEM.body_poses(KIN.q + t * KIN.qdot)[body]

    dT = (8 * (pose(h) - pose(-h)) - (pose(2 * h) - pose(-2 * h))) / (12 * h)
    return lie.vee(lie.se3_inv(pose(0.0)) @ dT)


@pytest.mark.parametrize("body", [0, 2])
def test_external_wrench_does_the_right_virtual_work(body):
    """Generalized force · [ξ; q̇] equals the wrench · the body's own twist (finite differences)."""

    def fn(t, g, q, xi, qdot):  # time- and state-dependent
        return jnp.array([0.3, -0.2, 0.5, 1.0, 2.0, -1.5]) * (1.0 + t) + 0.1 * xi

    F, Q = bd.ExternalWrench(fn, body=body).generalized_force(SYSTEM, KIN)
    F, Q, xi, qdot = (np.asarray(x) for x in (F, Q, KIN.xi, KIN.qdot))
    power = F @ xi + Q @ qdot
    w = np.asarray(jax.jit(fn)(KIN.t, KIN.g, KIN.q, KIN.xi, KIN.qdot))
    np.testing.assert_allclose(power, w @ np.asarray(_body_twist_fd(body)), rtol=1e-9)
    if body == 0:  # the base is the section frame: no shape force
        np.testing.assert_allclose(Q, 0.0, atol=1e-14)


def test_shape_potentials_springs_dampers_and_forces():
    K = jnp.array([[2.0, 0.3, 0.0], [0.3, 1.0, 0.1], [0.0, 0.1, 3.0]])
    rest = jnp.array([0.1, 0.0, -0.2])
    spring = bd.ShapeSpring(K, rest).generalized_force(SYSTEM, KIN)
    potential = bd.ShapePotential(lambda q: 0.5 * (q - rest) @ K @ (q - rest))
    np.testing.assert_allclose(potential.generalized_force(SYSTEM, KIN)[1], -K @ (KIN.q - rest))
    np.testing.assert_allclose(spring[1], -K @ (KIN.q - rest), rtol=1e-14)
    np.testing.assert_allclose(spring[0], 0.0)
    _, Q_damper = bd.ShapeDamper(jnp.array([1.0, 2.0, 3.0])).generalized_force(SYSTEM, KIN)
    np.testing.assert_allclose(Q_damper, -jnp.array([1.0, 2.0, 3.0]) * KIN.qdot)
    _, Q_force = bd.ShapeForce(lambda t, q, qdot: t * q + qdot).generalized_force(SYSTEM, KIN)
    np.testing.assert_allclose(Q_force, KIN.t * KIN.q + KIN.qdot)
    with pytest.raises(ValueError, match="stiffness"):
        bd.ShapeSpring(jnp.ones(2)).potential(SYSTEM, 0.0, KIN.g, KIN.q)


def test_gravity_does_the_work_of_its_potential():
    """Gravity's generalized force is minus the rate of change of m γ·c along the motion."""
    gravity = bd.Gravity(9.81, [0.3, -0.2, -1.0])
    (F, Q), programs = lowerings(gravity.generalized_force, SYSTEM, KIN)
    assert programs <= 1  # compiled, not run primitive by primitive

    def potential(t):
        g = KIN.g @ lie.se3_exp(t * KIN.xi)
        return gravity.potential(SYSTEM, 0.0, g, KIN.q + t * KIN.qdot)

    @jax.jit  # the references in one program, not one per primitive
    def references():
        rate = jax.jvp(potential, (0.0,), (1.0,))[1]
        # Independently, mγ·(world centre of mass) from the body poses.
        poses = KIN.g @ SYSTEM.body_poses(KIN.q)
        centres = poses[:, :3, 3] + jnp.einsum("nij,nj->ni", poses[:, :3, :3], SYSTEM.com)
        gamma = 9.81 * gravity.direction
        return rate, potential(0.0), -SYSTEM.mass @ (centres @ gamma)

    rate, at_zero, expected = references()
    np.testing.assert_allclose(F @ KIN.xi + Q @ KIN.qdot, -rate, rtol=1e-12)
    np.testing.assert_allclose(at_zero, expected, rtol=1e-12)


def _shipped(name, **kwargs):
    """A shipped model's system; its import warnings (unsupported elements) are not the point."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return (
            bd.load_system(bd.models / name)
            if not kwargs
            else bd.Multibody.from_mjcf(bd.models / name, **kwargs)
        )


GRAVITY_SYSTEMS = {
    **{
        name: lambda name=name: _shipped(name)
        for name in sorted(p.name for p in bd.models.iterdir())
    },
    "tree4.xml sectioned at body 2": lambda: _shipped("tree4.xml", section=2),
    "chain with rotor inertia": rotor_chain,
    "affine body": affine_body,
    "rigid body": asymmetric_body,
    "rigid body as a user's kinetic energy": rigid_generic,
}
# Uniform gravity, with masses and centres apart, and a central field near enough that its
# gradient's torque and shape forces are a sizeable part of the forces compared.
WRITTEN_OUT = {
    "gravity": bd.Gravity(9.81, [0.3, -0.2, -1.0]),
    "gravity, masses and centres apart": bd.Gravity(
        3.7, [-0.5, 0.8, 0.1], gravitational_mass=4.2, centre_offset=[0.02, -0.05, 0.1]
    ),
    "gravity gradient": bd.GravityGradient(5.0, [1.5, -2.0, 0.7]),
}
# The gravity gradient's second derivatives through the jet's forms take longest to compile:
# everyday on one system of each kind of jet (a tree's, a dense one, the affine body's, a
# rigid body's), on the rest in the slow part.
_GRADIENT_EVERYDAY = ("tree4.xml", "tree4.xml sectioned at body 2", "affine body", "rigid body")
EFFECT_CASES = (
    [pytest.param(name, "gravity", id=f"{name}-gravity") for name in GRAVITY_SYSTEMS]
    + [
        pytest.param(
            name,
            "gravity gradient",
            id=f"{name}-gravity gradient",
            marks=[] if name in _GRADIENT_EVERYDAY else [pytest.mark.slow],
        )
        for name in GRAVITY_SYSTEMS
    ]
    + [
        pytest.param(name, "gravity, masses and centres apart", id=f"{name}-apart")
        for name in ("tree4.xml", "affine body")
    ]
)


@eqx.filter_jit
def _forces_and_their_jacobians(force, gravity, system, kin):
    """`force(gravity, system, kin)` and its Jacobians in the pose (along eta) and the shape."""

    def of(eta, q):
        return force(gravity, system, kin._replace(g=kin.g @ lie.se3_exp(eta), q=q))

    eta = jnp.zeros(6, kin.q.dtype)
    return of(eta, kin.q), jax.jacfwd(of, argnums=(0, 1))(eta, kin.q)


@pytest.mark.parametrize(("name", "effect"), EFFECT_CASES)
def test_written_out_forces_are_the_potentials_gradient_with_their_derivatives(name, effect):
    """`Gravity`'s and `GravityGradient`'s forces, read off the metric's first rows and the
    jet's forms (Theorem 2.3), equal minus the potential's gradient by autodiff
    (`AbstractPotential.generalized_force`), and so do their derivatives in the pose and the
    shape, on every shipped model and every test system."""
    system, gravity = GRAVITY_SYSTEMS[name](), WRITTEN_OUT[effect]
    d = system.shape_dim
    rng = np.random.default_rng(d)
    kin = bd.Kinematics(
        jnp.asarray(0.3),
        lie.se3_exp(jnp.asarray(rng.normal(size=6))),
        jnp.asarray(0.5 * rng.uniform(-1.0, 1.0, d)),
        jnp.asarray(rng.normal(size=6)),
        jnp.asarray(rng.normal(size=d)),
    )
    written_out = _forces_and_their_jacobians(type(gravity).generalized_force, gravity, system, kin)
    by_autodiff = _forces_and_their_jacobians(
        bd.AbstractPotential.generalized_force, gravity, system, kin
    )
    # Each leaf to 1e-12 of its largest entry, or of the largest force where a leaf vanishes
    # identically (a wheel's spin moves no mass: its shape force is rounding either way).
    written_out, by_autodiff = jax.tree.map(np.asarray, (written_out, by_autodiff))
    forces = float(max(np.max(np.abs(f), initial=0.0) for f in by_autodiff[0]))
    for x, y in zip(jax.tree.leaves(written_out), jax.tree.leaves(by_autodiff), strict=True):
        scale = max(float(np.max(np.abs(y), initial=0.0)), forces)
        np.testing.assert_allclose(x, y, rtol=0.0, atol=1e-12 * scale)


def test_the_energy_adds_the_potentials_of_the_potential_effects_only():
    """`Trajectory.energy` is the kinetic energy plus the potential of each effect that is an
    `AbstractPotential`; dampers and forces have none (and no `potential` method)."""
    gravity, spring = bd.Gravity(), bd.ShapeSpring(2.0, 0.1)
    damper, force = bd.ShapeDamper(0.5), bd.ShapeForce(lambda t, q, qdot: q)
    assert isinstance(spring, bd.AbstractPotential) and isinstance(gravity, bd.AbstractEffect)
    assert not isinstance(damper, bd.AbstractPotential) and not hasattr(damper, "potential")
    scene = bd.Scene(SYSTEM, [gravity, damper, spring, force])
    n = 2
    ts = jnp.array([KIN.t, KIN.t + 1.0])
    qs = jnp.stack([KIN.q, 2 * KIN.q])
    gs, xis, qdots = (jnp.stack([x] * n) for x in (KIN.g, KIN.xi, KIN.qdot))
    traj = bd.Trajectory(ts, gs, qs, xis, qdots, xis, {}, None, scene)
    expected = [
        bd.kinetic_energy(SYSTEM, q, KIN.xi, KIN.qdot)
        + gravity.potential(SYSTEM, t, KIN.g, q)
        + spring.potential(SYSTEM, t, KIN.g, q)
        for t, q in zip(ts, qs, strict=True)
    ]
    np.testing.assert_allclose(traj.energy(), jnp.stack(expected), rtol=1e-13)
