"""Wheels of a multibody tree rolling without slipping (`RollingWheelMode`, seed 001 (76),
(77), (82) on SE(3) × shape space), against independent derivations in generalized
coordinates: a unicycle (a rider hinged on a rolling disc's axle) in Euler angles, a
`NonholonomicSystem` with its kinetic energy written out and its contact rows by autodiff;
and the benchmark bicycle as a tree on two wheels against `WhippleBicycle`, whose
eigenvalues are the published benchmark's."""

import functools

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from euler_disc import (
    DISC_INERTIA,
    DISC_MASS,
    DISC_RADIUS,
    axis_rotation,
    centre_velocity,
    contact_velocity,
)

import bundledyn as bd

GRAVITY = 9.81

# The rider: a body hinged on the wheel's axle (the body y axis through the wheel's centre),
# its centre of mass below the axle and off the wheel's plane, its inertia not diagonal.
RIDER_MASS = 3.0
RIDER_COM = jnp.array([0.03, 0.05, -0.3])
RIDER_INERTIA = jnp.array([[0.09, 0.004, -0.006], [0.004, 0.08, 0.003], [-0.006, 0.003, 0.03]])


def _rider_orientation(q):
    """$R_r = R_z(\\varphi)R_x(\\theta)R_y(\\beta)$: the wheel's heading and tilt, then the rider's
    pitch about the axle."""
    return axis_rotation(2, q[2]) @ axis_rotation(0, q[3]) @ axis_rotation(1, q[5])


def _wheel_orientation(q):
    return axis_rotation(2, q[2]) @ axis_rotation(0, q[3]) @ axis_rotation(1, q[4])


def _angular_velocity(orientation, q, qdot):
    R, R_dot = jax.jvp(orientation, (q,), (qdot,))
    return bd.lie.so3_vee(R.T @ R_dot)


def _unicycle_in_euler_angles():
    """The unicycle in $q = (x, y, \\varphi, \\theta, \\psi, \\beta)$: the wheel's centre, heading,
    tilt and spin, and the rider's pitch about the axle; the wheel's horizontal contact rows
    (76) solved for $(\\dot x, \\dot y)$."""

    def kinetic_energy(q, qdot, t):
        v = centre_velocity(q, qdot)
        wheel = _angular_velocity(_wheel_orientation, q, qdot)
        rider = _angular_velocity(_rider_orientation, q, qdot)
        v_rider = v + _rider_orientation(q) @ jnp.cross(rider, RIDER_COM)
        return 0.5 * (
            DISC_MASS * v @ v
            + wheel @ DISC_INERTIA @ wheel
            + RIDER_MASS * v_rider @ v_rider
            + rider @ RIDER_INERTIA @ rider
        )

    def potential(q, t):
        height = DISC_RADIUS * jnp.cos(q[3])
        rider_height = height + (_rider_orientation(q) @ RIDER_COM)[2]
        return GRAVITY * (DISC_MASS * height + RIDER_MASS * rider_height)

    def rows(q, t):
        # the contact point depends on the wheel's heading and tilt only, as for the disc
        velocity = lambda qdot: contact_velocity(q[:5], qdot[:5])[:2]
        return jax.jacfwd(velocity)(jnp.zeros_like(q))

    return bd.NonholonomicSystem(
        T=kinetic_energy,
        constraints=bd.PfaffianConstraints(rows, independent=(2, 3, 4, 5)),
        Pi=potential,
    )


@functools.cache
def _unicycle():
    """The same unicycle as a tree: the rider is the floating base, its frame's origin on the
    axle at the wheel's centre, and the wheel a hinge about its y axis."""
    rider = bd.RigidBody(RIDER_MASS, RIDER_COM, RIDER_INERTIA)
    wheel = bd.RigidBody(DISC_MASS, jnp.zeros(3), DISC_INERTIA)
    hinge = bd.Link(wheel, bd.Revolute((0.0, 1.0, 0.0)), 0, np.eye(4))
    return bd.Multibody(rider, [hinge], names=("rider", "wheel"))


def _scene(wheel="wheel"):
    tree = _unicycle()
    mode = bd.RollingWheelMode([bd.Wheel(wheel, bd.DiscContact(DISC_RADIUS))])
    return bd.Scene(tree, [bd.Gravity(GRAVITY)], mode=mode)


@eqx.filter_jit  # one program, shared by the tests that start from it
def _state(scene, q, e):
    """The tree's state of the Euler-angle state `(q, e)`: the rider's pose, the hinge angle
    $\\psi - \\beta$, the rider's body angular velocity and the hinge's rate."""
    qdot = bd.constrained_velocities(_unicycle_in_euler_angles().constraints, q, e, 0.0)
    g = jnp.eye(4).at[:3, :3].set(_rider_orientation(q))
    g = g.at[:3, 3].set(jnp.stack([q[0], q[1], DISC_RADIUS * jnp.cos(q[3])]))
    omega = _angular_velocity(_rider_orientation, q, qdot)
    e = jnp.concatenate([omega, (e[2] - e[3])[None]])
    return scene.mode.state(scene.system, g, (q[4] - q[5])[None], e)


@eqx.filter_jit
def _metric(tree, q):
    """A tree's metric, compiled: the shipped scenes' trees and the ones built here share it."""
    return tree.metric(q)


@eqx.filter_jit
def _body_field(scene, y):
    """A rolling scene's body field at `y`, compiled: the shipped scene and the one built
    here (the same structure, other numbers) share one program."""
    return scene.mode.body_field(scene, 0.0, y)


@eqx.filter_jit  # one program, not one per primitive
def _residual_and_encoding(scene, python, state):
    """The residual of `scene`'s rolling constraints at `state`, and `state` encoded in the
    layout of `python` (the scene built here): a shipped scene's checks."""
    return scene.mode.constraint_residual(scene, state), python.mode.encode(python, 0.0, state)


Q0 = jnp.array([0.1, -0.2, 0.3, 0.25, 0.4, -0.2])
E0 = jnp.array([0.7, -0.3, 12.0, 0.5])  # heading, tilt, spin and pitch rates
T1, SAVES = 1.0, 11


def test_a_unicycle_on_the_bundle_moves_as_its_euler_angle_equations_move_it():
    scene = _scene()
    ts = jnp.linspace(0.0, T1, SAVES)
    traj = bd.simulate(
        scene, _state(scene, Q0, E0), T1, rtol=1e-12, atol=1e-12, saveat=diffrax.SaveAt(ts=ts)
    )
    reference = diffrax.diffeqsolve(
        bd.NonholonomicTerm(_unicycle_in_euler_angles()), diffrax.Tsit5(), 0.0, T1, None,
        (Q0, E0), saveat=diffrax.SaveAt(ts=ts), max_steps=100_000,
        stepsize_controller=diffrax.PIDController(rtol=1e-12, atol=1e-12),
    )  # fmt: skip
    q = reference.ys[0]
    rider = jax.jit(jax.vmap(_rider_orientation))(q)
    q = np.asarray(q)
    np.testing.assert_allclose(traj.g[:, :3, :3], rider, atol=1e-10)
    np.testing.assert_allclose(traj.g[:, :2, 3], q[:, :2], atol=1e-10)
    np.testing.assert_allclose(traj.q[:, 0], q[:, 4] - q[:, 5], atol=1e-10)
    # the motion is not trivial: the rider swings and the wheel tilts
    assert float(np.max(np.abs(q[:, 5] - float(Q0[5])))) > 0.1
    assert float(np.max(np.abs(q[:, 3] - float(Q0[3])))) > 0.05
    energy = np.asarray(traj.energy())
    np.testing.assert_allclose(energy, energy[0], rtol=1e-10)
    # the wheel's contact point is at rest and on the plane at every saved state
    residual = np.asarray(traj.diagnostics().constraint_residual)
    assert np.max(np.abs(residual)) < 1e-12


@pytest.mark.slow  # a rolling solve compiled forward and in reverse
def test_the_gradient_through_a_rolling_tree_equals_central_differences():
    scene = _scene()
    state = _state(scene, Q0, E0)

    @jax.jit
    def travel(rider_mass):
        heavier = eqx.tree_at(
            lambda s: s.system.mass, scene, scene.system.mass.at[0].set(rider_mass)
        )
        traj = bd.simulate(
            heavier, state, 0.3, rtol=1e-10, atol=1e-10, saveat=diffrax.SaveAt(t1=True)
        )
        return traj.g[-1, 0, 3]

    gradient = jax.grad(travel)(RIDER_MASS)
    h = 1e-5
    central = (travel(RIDER_MASS + h) - travel(RIDER_MASS - h)) / (2 * h)
    assert abs(float(gradient)) > 1e-4  # the rider's mass moves the wheel
    np.testing.assert_allclose(gradient, central, rtol=1e-6)


def test_the_state_keeps_the_wheel_rolling_and_the_layout_gives_it_back():
    scene = _scene()
    state = _state(scene, Q0, E0)

    @eqx.filter_jit  # one program, not one per primitive
    def round_trip(scene, state):
        y = scene.mode.encode(scene, 0.0, state)
        return scene.mode.constraint_residual(scene, state), scene.mode.decode(scene, 0.0, y)[0]

    residual, back = round_trip(scene, state)
    np.testing.assert_allclose(residual, 0.0, atol=1e-14)
    for name in ("g", "q", "xi", "qdot"):
        np.testing.assert_allclose(getattr(back, name), getattr(state, name), atol=1e-14)
    sliding = bd.State(state.g, state.q, state.xi.at[3].add(0.1), state.qdot)
    with pytest.raises(Exception, match="does not keep the wheels rolling"):
        jax.block_until_ready(round_trip(scene, sliding))  # the same compiled `encode`


def test_independent_velocities_the_rolling_cannot_solve_around_are_located_and_raise():
    # The section's linear velocity and the hinge's rate as characteristics: the contact's
    # rows then have to give the angular velocity, but they see it only through p x omega,
    # of rank two.
    wheel = bd.Wheel("wheel", bd.DiscContact(DISC_RADIUS))
    mode = bd.RollingWheelMode([wheel], independent=(3, 4, 5, 6))
    scene = bd.Scene(_unicycle(), [], mode=mode)
    with pytest.raises(Exception, match="choose other independent velocities"):
        # compiled, as `_state` above (eagerly its hundreds of primitives compile one by one)
        state = eqx.filter_jit(lambda mode, system, *x: mode.state(system, *x))
        jax.block_until_ready(state(mode, scene.system, jnp.eye(4), jnp.zeros(1), jnp.zeros(4)))


@pytest.mark.parametrize(
    "build, message",
    [
        (lambda: _scene(wheel="tyre"), "not one of the tree's bodies"),
        (lambda: _scene(wheel=2), "the tree has 2 bodies"),
        (
            lambda: bd.RollingWheelMode(
                [bd.Wheel("wheel", bd.DiscContact(0.2)), bd.Wheel("rider", bd.SphereContact(0.1))]
            ),
            "needs `independent`",
        ),
        (
            lambda: bd.Scene(
                _unicycle(),
                [],
                mode=bd.RollingWheelMode(
                    [bd.Wheel("wheel", bd.DiscContact(0.2))], independent=(0, 1, 6)
                ),
            ),
            "must name 4 different velocities",
        ),
        (
            lambda: bd.Scene(
                bd.RigidBody(1.0, jnp.zeros(3), jnp.eye(3)),
                [],
                mode=bd.RollingWheelMode([bd.Wheel(0, bd.DiscContact(0.2))]),
            ),
            "A single rolling body is `bd.RollingMode`",
        ),
        (lambda: bd.Wheel("wheel", 0.2), "AbstractContactSurface"),
    ],
)
def test_what_it_cannot_roll_is_refused_with_the_fix(build, message):
    with pytest.raises(ValueError, match=message):
        build()


def test_the_shipped_unicycle_scene_is_the_tree_built_in_python():
    sf = bd.SceneFile.load(bd.scenes / "unicycle.toml")
    mode, tree = sf.scene.mode, sf.scene.system
    assert isinstance(mode, bd.RollingWheelMode) and mode.wheels[0].body == "wheel"
    assert tree.names == ("rider", "wheel")
    for q in (0.0, 0.6, -2.0):
        np.testing.assert_allclose(
            _metric(tree, jnp.array([q])), _metric(_unicycle(), jnp.array([q])), atol=1e-15
        )
    # placed on the plane, rolling, with the file's shape and angular velocity
    python = _scene()
    residual, y = _residual_and_encoding(sf.scene, python, sf.state)
    np.testing.assert_allclose(residual, 0.0, atol=1e-15)
    np.testing.assert_allclose(np.asarray(sf.state.xi)[:3], [0.0, 0.5, 0.7])
    np.testing.assert_allclose(sf.state.qdot, [12.0])
    # and moves as the Python scene does from there
    for a, b in zip(_body_field(python, y), _body_field(sf.scene, y), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-13)


# --- the benchmark bicycle as a tree on two rolling wheels -----------------------------------

BIKE = bd.WhippleBicycle.benchmark()
# The tree's bodies in order (the base first); `WhippleBicycle.placement` lists the rear
# wheel first, then the rear frame.
REAR_FRAME, REAR_WHEEL, FRONT_FRAME, FRONT_WHEEL = range(4)
PLACED_REAR_WHEEL, PLACED_REAR_FRAME = 0, 1


def _bicycle_tree(bike):
    """The bicycle of Meijaard et al. (2007) as a tree, from the paper's parameters: the rear
    frame is the floating base, its frame's origin at the rear wheel's centre and its axes the
    paper's ($z$ down) at the upright reference; the rear wheel hinges on it, the front frame
    turns about the steer axis, the front wheel hinges on the front frame."""
    r_R, r_F, w, c, tilt = (
        float(x)
        for x in (
            bike.rear_wheel_radius,
            bike.front_wheel_radius,
            bike.wheelbase,
            bike.trail,
            bike.steer_axis_tilt,
        )
    )

    def point(x, z):  # a point given from the rear contact, from the rear wheel's centre
        return np.array([x, 0.0, z + r_R])

    def wheel(mass, inertia, centre):
        diagonal = jnp.diag(jnp.array([inertia[0], inertia[1], inertia[0]]))
        return bd.RigidBody(mass, centre, diagonal)

    front_centre = point(w, -r_F)
    steer_axis = (np.sin(tilt), 0.0, np.cos(tilt))
    links = [
        bd.Link(
            wheel(bike.rear_wheel_mass, bike.rear_wheel_inertia, np.zeros(3)),
            bd.Revolute((0.0, 1.0, 0.0)),
            REAR_FRAME,
            np.eye(4),
        ),
        bd.Link(
            bd.RigidBody(
                bike.front_frame_mass, point(*bike.front_frame_centre), bike.front_frame_inertia
            ),
            bd.Revolute(steer_axis, point(w + c, 0.0)),
            REAR_FRAME,
            np.eye(4),
        ),
        bd.Link(
            wheel(bike.front_wheel_mass, bike.front_wheel_inertia, front_centre),
            bd.Revolute((0.0, 1.0, 0.0), front_centre),
            FRONT_FRAME,
            np.eye(4),
        ),
    ]
    base = bd.RigidBody(
        bike.rear_frame_mass, point(*bike.rear_frame_centre), bike.rear_frame_inertia
    )
    tree = bd.Multibody(
        base, links, names=("rear frame", "rear wheel", "front frame", "front wheel")
    )
    wheels = [
        bd.Wheel("rear wheel", bd.DiscContact(r_R, axis=(0.0, 1.0, 0.0))),
        bd.Wheel("front wheel", bd.DiscContact(r_F, axis=(0.0, 1.0, 0.0), centre=front_centre)),
    ]
    # The characteristics: the rear frame's body angular velocity about its forward axis
    # (the roll rate at the upright reference), the rear wheel's rate and the steer rate.
    mode = bd.RollingWheelMode(wheels, independent=(0, 6, 7), normal=(0.0, 0.0, -1.0))
    return bd.Scene(tree, [bd.Gravity(float(bike.gravity), (0.0, 0.0, 1.0))], mode=mode)


def _bicycle_state(scene, q, e):
    """The tree's state of the bicycle's state `(q, e)`: the rear frame's pose and the
    velocities the bicycle's constraints give, in the tree's variables."""
    qdot = bd.constrained_velocities(BIKE.constraints, q, e, 0.0)
    placed, moving = jax.jvp(BIKE.placement, (q,), (qdot,))
    R, R_dot = placed.rotations[PLACED_REAR_FRAME], moving.rotations[PLACED_REAR_FRAME]
    g = jnp.eye(4).at[:3, :3].set(R).at[:3, 3].set(placed.centres[PLACED_REAR_WHEEL])
    shape = jnp.stack([q[6] - q[4], q[5], q[7]])
    shape_rate = jnp.stack([qdot[6] - qdot[4], qdot[5], qdot[7]])
    omega, v = bd.lie.so3_vee(R.T @ R_dot), R.T @ moving.centres[PLACED_REAR_WHEEL]
    return scene.mode.state(scene.system, g, shape, jnp.concatenate([omega[:1], shape_rate[:2]])), (
        omega,
        v,
    )


@pytest.mark.slow
def test_the_benchmark_bicycle_as_a_tree_on_two_wheels_moves_as_its_nonlinear_model():
    scene = _bicycle_tree(BIKE)
    q0, e0 = BIKE.steady_motion(4.6)
    q0, e0 = BIKE.on_the_ground(q0.at[3].set(0.1).at[5].set(-0.05)), e0.at[1].set(0.5)
    state, (omega, v) = _bicycle_state(scene, q0, e0)
    # the tree's rolling rows give the bicycle's dependent velocities
    np.testing.assert_allclose(state.xi, jnp.concatenate([omega, v]), rtol=0, atol=1e-12)
    ts = jnp.linspace(0.0, 1.0, 5)
    traj = bd.simulate(scene, state, 1.0, rtol=1e-11, atol=1e-11, saveat=diffrax.SaveAt(ts=ts))
    reference = diffrax.diffeqsolve(
        bd.NonholonomicTerm(BIKE), diffrax.Tsit5(), 0.0, 1.0, None, (q0, e0),
        saveat=diffrax.SaveAt(ts=ts), max_steps=100_000,
        stepsize_controller=diffrax.PIDController(rtol=1e-11, atol=1e-11),
    )  # fmt: skip
    placed = jax.vmap(BIKE.placement)(reference.ys[0])
    np.testing.assert_allclose(traj.g[:, :3, :3], placed.rotations[:, PLACED_REAR_FRAME], atol=1e-9)
    np.testing.assert_allclose(traj.g[:, :3, 3], placed.centres[:, PLACED_REAR_WHEEL], atol=1e-9)
    np.testing.assert_allclose(traj.q[:, 1], reference.ys[0][:, 5], atol=1e-9)  # the steer
    assert float(jnp.max(jnp.abs(reference.ys[0][:, 5] - q0[5]))) > 0.05  # it steers
    energy = np.asarray(traj.energy())
    np.testing.assert_allclose(energy, energy[0], rtol=1e-10)
    residual = np.asarray(traj.diagnostics().constraint_residual)
    assert np.max(np.abs(residual[:, :6])) < 1e-12  # both contacts at rest
    assert np.max(np.abs(residual[:, 6])) < 1e-15  # the rear one on the ground, by the pose
    assert np.max(np.abs(residual[:, 7])) < 1e-10  # the front one, to the solver's tolerance


def test_the_shipped_bicycle_scene_is_the_tree_built_from_the_papers_parameters():
    sf = bd.SceneFile.load(bd.scenes / "bicycle.toml")
    python = _bicycle_tree(BIKE)
    mode, tree = sf.scene.mode, sf.scene.system
    assert isinstance(mode, bd.RollingWheelMode) and mode.independent == (0, 6, 7)
    assert [w.body for w in mode.wheels] == ["rear wheel", "front wheel"]
    assert tree.names == python.system.names
    for q in ([0.0, 0.0, 0.0], [0.4, -0.3, 1.2]):
        q = jnp.array(q)
        np.testing.assert_allclose(_metric(tree, q), _metric(python.system, q), atol=1e-12)
    # upright, both wheels on the ground and rolling, forward at 4.6 m/s, rolled at 0.5 rad/s
    # about the rear contact, so the rear wheel's centre, 0.3 above it, moves sideways
    residual, y = _residual_and_encoding(sf.scene, python, sf.state)
    np.testing.assert_allclose(residual, 0.0, atol=1e-14)
    np.testing.assert_allclose(sf.state.xi, [0.5, 0.0, 0.0, 4.6, 0.5 * 0.3, 0.0], atol=1e-14)
    for a, b in zip(_body_field(python, y), _body_field(sf.scene, y), strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)
