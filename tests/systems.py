"""A registry of systems: every system kind runs the same test battery."""

import functools
import pathlib

import jax.numpy as jnp
import numpy as np
import pytest

import bundledyn as bd

MODELS = pathlib.Path(bd.__file__).parent / "models"


def box_body(mass, size, com=(0.0, 0.0, 0.0)):
    """A solid box of the given mass and edge lengths, centre of mass at `com`."""
    a, b, c = size
    inertia = mass / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    return bd.RigidBody(mass, com, inertia)


def asymmetric_body():
    return bd.RigidBody(
        2.0, [0.05, -0.02, 0.1], [[0.30, 0.01, -0.02], [0.01, 0.45, 0.03], [-0.02, 0.03, 0.6]]
    )


_JOINT_CYCLE = ("revolute", "universal", "spherical", "revolute", "prismatic")


def _joint(kind, i):
    anchor = (-0.25, 0.0, 0.0)
    if kind == "revolute":
        return bd.Revolute((0.0, np.cos(i), np.sin(i)), anchor)
    if kind == "universal":
        return bd.Universal((0.0, 0.0, 1.0), (0.0, 1.0, 0.0), anchor)
    if kind == "spherical":
        return bd.Spherical(anchor)
    return bd.Prismatic((1.0, 0.2, 0.0))


@functools.cache
def chain(n, kinds=_JOINT_CYCLE, armature=None):
    """A free-floating chain of `n` boxes, joints cycling through `kinds`, with the rotor
    inertia `armature` of its shape coordinates (a tuple; none by default)."""
    bodies = [
        box_body(1.0 + 0.3 * i, (0.5, 0.1 + 0.02 * i, 0.08), (0.02 * i, 0.01, 0.0))
        for i in range(n)
    ]
    placement = np.eye(4)
    placement[0, 3] = 0.5
    links = [
        bd.Link(bodies[i], _joint(kinds[(i - 1) % len(kinds)], i), i - 1, placement)
        for i in range(1, n)
    ]
    return bd.Multibody(bodies[0], links, armature=armature)


def chain3_state():
    """A generic moving state of `chain(3)`."""
    return bd.State(
        jnp.eye(4),
        jnp.array([0.2, -0.1, 0.3]),
        jnp.array([0.3, 0.2, -0.4, 0.1, 0.0, 0.2]),
        jnp.array([0.5, -0.4, 0.3]),
    )


@functools.cache
def tree4():
    """A branching tree: base with two children, one grandchild on the first child."""
    b = [box_body(1.0 + 0.5 * i, (0.4, 0.12, 0.1)) for i in range(4)]

    def at(x, y):
        T = np.eye(4)
        T[:3, 3] = (x, y, 0.0)
        return T

    links = [
        bd.Link(b[1], bd.Revolute((0, 0, 1), (-0.2, 0, 0)), 0, at(0.4, 0.1)),
        bd.Link(b[2], bd.Spherical((-0.2, 0, 0)), 0, at(-0.4, -0.1)),
        bd.Link(b[3], bd.Universal((0, 1, 0), (1, 0, 0), (-0.2, 0, 0)), 1, at(0.4, 0.0)),
    ]
    return bd.Multibody(b[0], links)


@functools.cache
def affine_body():
    return bd.AffineBody(3.0, 3.0 / 5.0 * np.diag([0.5**2, 0.3**2, 0.2**2]))


# What importing the shipped chain5.xml warns of: two joints whose home pose is bent.
CHAIN5_REFS = r"'shoulder' \(ref 0.4\), 'extend' \(ref 0.05\) have a non-zero reference"


@functools.cache
def mjcf_chain():
    with pytest.warns(UserWarning, match=CHAIN5_REFS):
        return bd.Multibody.from_mjcf(MODELS / "chain5.xml")


def rotor_chain():
    """`chain(5)` with rotor inertia (MuJoCo's armature) on its hinge and universal
    coordinates, none on the spherical joint's."""
    return chain(5, armature=(0.3, 0.2, 0.1, 0.0, 0.0, 0.0, 0.4))


def rigid_generic():
    """The asymmetric rigid body's kinetic energy given as a user function."""
    M = asymmetric_body().spatial_inertia()

    def T(q, qdot, xi):
        return 0.5 * xi @ M @ xi

    return bd.GenericSystem(T, 0)


SYSTEMS = {
    "rigid_body": asymmetric_body,
    "chain2": lambda: chain(2),
    "chain5": lambda: chain(5),
    "tree4": tree4,
    "affine_body": affine_body,
    "mjcf_chain5": mjcf_chain,
    "rotor_chain5": rotor_chain,
}


def random_shapes(system, key, n, scale=0.8):
    """`n` random shapes in a box of half-width `scale` (well inside every chart)."""
    import jax

    return scale * jax.random.uniform(key, (n, system.shape_dim), minval=-1.0, maxval=1.0)


def body_inertia_data(system, q):
    """Independent mass, centre of mass and inertia about it, summed body by body.

    Uses only the bodies' poses and their own inertias (no metric): for `Multibody`,
    the bodies; for `AffineBody`, the deformed second moment.
    """
    if isinstance(system, bd.RigidBody):
        return system.mass, system.com, system.inertia
    if isinstance(system, bd.AffineBody):
        from bundledyn._systems._affine_body import stretch

        U = stretch(q)
        S = U @ system.second_moment @ U.T
        return system.mass, jnp.zeros(3), jnp.trace(S) * jnp.eye(3) - S
    r = system.body_poses(q)
    R, p = r[:, :3, :3], r[:, :3, 3]
    c_a = p + jnp.einsum("nij,nj->ni", R, system.com)
    m = jnp.sum(system.mass)
    c = jnp.einsum("n,ni->i", system.mass, c_a) / m
    d = c_a - c[None]
    parallel = system.mass[:, None, None] * (
        jnp.einsum("ni,ni->n", d, d)[:, None, None] * jnp.eye(3)[None]
        - jnp.einsum("ni,nj->nij", d, d)
    )
    inertia = jnp.sum(jnp.einsum("nij,njk,nlk->nil", R, system.inertia, R) + parallel, axis=0)
    return m, c, inertia


def picture_size(path):
    """`(width, height, frames)` of an image file, after checking it is not blank."""
    import numpy as np
    from PIL import Image

    with Image.open(path) as image:
        frames = getattr(image, "n_frames", 1)
        pixels = np.asarray(image.convert("RGB"), dtype=float)
    assert pixels.std() > 10.0 and len(np.unique(pixels.reshape(-1, 3), axis=0)) > 20
    return pixels.shape[1], pixels.shape[0], frames


# Gymnasium-style passive joints: damping, springs about springref (one with a reference
# position), rotor inertia, gravity, a ball joint, a fixed tendon that only couples joint
# ranges (as in gymnasium's humanoid) and one with a spring and a damper of its own.
PASSIVE = """<mujoco><compiler angle="radian"/>
<option gravity="0 -2 -9.81" integrator="RK4" timestep="1e-4"/>
<default><joint armature="0.2" damping="0.3"/></default><worldbody><body name="torso">
<freejoint/><inertial pos="0.01 0 0" mass="2" diaginertia="0.1 0.2 0.3"/>
<body name="a" pos="0.3 0 0"><joint name="j1" type="hinge" axis="0 0 1" stiffness="4"
 springref="0.3"/><inertial pos="0.1 0 0" mass="0.5" diaginertia="0.01 0.02 0.02"/>
<body name="b" pos="0.3 0 0"><joint name="j2" type="hinge" axis="0 1 0" ref="0.2"
 stiffness="2" springref="-0.1"/><joint name="j3" type="slide" axis="1 0 0" stiffness="20"/>
<inertial pos="0.1 0 0.02" mass="0.4" diaginertia="0.01 0.02 0.03"/></body></body>
<body name="c" pos="-0.3 0 0"><joint name="j4" type="hinge" axis="1 0 0" damping="0"/>
<inertial pos="-0.1 0 0" mass="0.5" diaginertia="0.01 0.02 0.02"/>
<body name="d" pos="-0.2 0 0.1"><joint name="shoulder" type="ball" armature="0" damping="0"/>
<inertial pos="-0.1 0 0" mass="0.3" diaginertia="0.01 0.015 0.02"/></body></body>
</body></worldbody><tendon><fixed name="couple" limited="true" range="-1 1">
<joint joint="j1" coef="1"/><joint joint="j4" coef="1"/></fixed>
<fixed name="sinew" stiffness="3" damping="0.4" springlength="0.1">
<joint joint="j2" coef="0.5"/><joint joint="j3" coef="-1"/><joint joint="j4" coef="0.7"/>
</fixed></tendon></mujoco>"""
