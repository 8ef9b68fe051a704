"""Rigid bodies rolling without slipping on a plane (`RollingMode`, seed 001 (77), (82) on SE(3)),
against closed forms, conserved quantities and an independent derivation: the tilting disc in
Euler angles, a `NonholonomicSystem` with its contact rows by autodiff."""

import functools

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from euler_disc import (
    AXIAL,
    DIAMETRAL,
    DISC_INERTIA,
    DISC_MASS,
    DISC_RADIUS,
    body_angular_velocity,
    centre_velocity,
    contact_velocity,
    orientation,
)
from systems import chain

import bundledyn as bd

GRAVITY = 9.81


def _rolling_scene(inertia, surface, *, mass=1.5, effects=None, **plane):
    body = bd.RigidBody(mass, jnp.zeros(3), inertia)
    effects = [bd.Gravity(GRAVITY)] if effects is None else effects
    return bd.Scene(body, effects, mode=bd.RollingMode(surface, **plane))


# One number of saved states per kind of body: scenes that differ only in numbers (their
# inertia, plane, horizon) then share one compiled solve.
BALL_SAVES, DISC_SAVES = 11, 21


def _simulate(scene, state, t1, ts=None, **options):
    saveat = diffrax.SaveAt(ts=ts) if ts is not None else None
    return bd.simulate(scene, state, t1, rtol=1e-12, atol=1e-12, saveat=saveat, **options)


# --- a ball: closed forms ---------------------------------------------------------------

BALL_MASS, BALL_RADIUS = 2.0, 0.1
BALL_INERTIA = 0.4 * BALL_MASS * BALL_RADIUS**2 * jnp.eye(3)


def test_a_homogeneous_ball_rolls_straight_with_constant_angular_velocity():
    # On a level plane a solid ball's angular velocity is constant and its centre moves as
    # omega x (r n): a straight line at constant speed.
    scene = _rolling_scene(BALL_INERTIA, bd.SphereContact(BALL_RADIUS), mass=BALL_MASS)
    g0 = bd.lie.se3_exp(jnp.array([0.4, -0.3, 1.1, 0.2, 0.5, 7.0]))  # the height is replaced
    omega = jnp.array([1.0, 2.0, 0.5])
    state = scene.mode.state(g0, omega)
    assert float(state.g[2, 3]) == pytest.approx(BALL_RADIUS, abs=1e-15)
    ts = jnp.linspace(0.0, 2.0, BALL_SAVES)
    traj = _simulate(scene, state, 2.0, ts)
    omega_world = jnp.einsum("tij,tj->ti", traj.g[:, :3, :3], traj.xi[:, :3])
    np.testing.assert_allclose(
        omega_world, jnp.broadcast_to(g0[:3, :3] @ omega, (BALL_SAVES, 3)), atol=1e-10
    )
    velocity = jnp.cross(g0[:3, :3] @ omega, jnp.array([0.0, 0.0, BALL_RADIUS]))
    expected = state.g[None, :3, 3] + ts[:, None] * velocity[None, :]
    np.testing.assert_allclose(traj.g[:, :3, 3], expected, atol=1e-10)


def test_a_ball_rolls_down_an_incline_at_five_sevenths_of_the_free_acceleration():
    # A solid ball from rest on a slope of angle alpha: s = (5/7) g sin(alpha) t^2 / 2.
    alpha = 0.3
    normal = jnp.array([jnp.sin(alpha), 0.0, jnp.cos(alpha)])
    scene = _rolling_scene(
        BALL_INERTIA, bd.SphereContact(BALL_RADIUS), mass=BALL_MASS, normal=normal, offset=0.2
    )
    state = scene.mode.state(jnp.eye(4), jnp.zeros(3))
    ts = jnp.linspace(0.0, 1.5, BALL_SAVES)
    traj = _simulate(scene, state, 1.5, ts)
    downhill = jnp.array([jnp.cos(alpha), 0.0, -jnp.sin(alpha)])
    travelled = (traj.g[:, :3, 3] - state.g[None, :3, 3]) @ downhill
    expected = 5.0 / 7.0 * GRAVITY * np.sin(alpha) * ts**2 / 2
    np.testing.assert_allclose(travelled, expected, rtol=0, atol=1e-10)
    # the centre stays at one radius from the plane
    heights = traj.g[:, :3, 3] @ normal - 0.2
    np.testing.assert_allclose(heights, BALL_RADIUS, rtol=0, atol=1e-13)


def _contact_momentum(mode, mass, inertia, g, xi):
    r"""The angular momentum about the contact point in space, $R(I\omega - m\,c\times(c\times
    \omega))$ for a body whose centre of mass is its frame's origin."""
    c, omega = mode.contact(g[:3, :3]), xi[:3]
    return g[:3, :3] @ (inertia @ omega - mass * jnp.cross(c, jnp.cross(c, omega)))


def test_the_chaplygin_sphere_keeps_its_four_invariants():
    # A ball with its centre of mass at its centre and three unequal moments: the energy and
    # the angular momentum about the contact point, a constant vector in space (the
    # reaction and gravity pass through the contact point's vertical).
    inertia = jnp.diag(jnp.array([0.010, 0.014, 0.020]))
    scene = _rolling_scene(inertia, bd.SphereContact(0.1), mass=1.0)
    g0 = bd.lie.se3_exp(jnp.array([0.3, -0.2, 0.5, 0.0, 0.0, 0.0]))
    state = scene.mode.state(g0, jnp.array([1.0, -2.0, 3.0]))
    traj = _simulate(scene, state, 3.0, jnp.linspace(0.0, 3.0, BALL_SAVES))
    momentum = jax.vmap(lambda g, xi: _contact_momentum(scene.mode, 1.0, inertia, g, xi))(
        traj.g, traj.xi
    )
    scale = float(jnp.linalg.norm(momentum[0]))
    np.testing.assert_allclose(
        momentum, jnp.broadcast_to(momentum[0], momentum.shape), atol=1e-10 * scale
    )
    energy = np.asarray(traj.energy())
    np.testing.assert_allclose(energy, energy[0], rtol=1e-11)
    # the motion is not trivial: the body axes of the spin wander
    assert float(jnp.max(jnp.abs(traj.xi[:, :3] - traj.xi[None, 0, :3]))) > 0.5


# --- the tilting disc: an independent derivation in Euler angles ---------------------------

CRITICAL_SPIN = np.sqrt(
    DISC_MASS * GRAVITY * DISC_RADIUS * DIAMETRAL / (AXIAL * (AXIAL + DISC_MASS * DISC_RADIUS**2))
)


def _disc_in_euler_angles():
    """The disc in $q = (x, y, \\varphi, \\theta, \\psi)$ (centre's position, heading, tilt,
    spin), its horizontal contact rows (76) the linear part of the contact point's
    velocity, solved for $(\\dot x, \\dot y)$."""

    def kinetic_energy(q, qdot, t):
        v, omega = centre_velocity(q, qdot), body_angular_velocity(q, qdot)
        return 0.5 * DISC_MASS * v @ v + 0.5 * omega @ DISC_INERTIA @ omega

    def rows(q, t):
        return jax.jacfwd(lambda qdot: contact_velocity(q, qdot)[:2])(jnp.zeros_like(q))

    return bd.NonholonomicSystem(
        T=kinetic_energy,
        constraints=bd.PfaffianConstraints(rows, independent=(2, 3, 4)),
        Pi=lambda q, t: DISC_MASS * GRAVITY * DISC_RADIUS * jnp.cos(q[3]),
    )


def _disc_scene(surface=None):
    return _rolling_scene(DISC_INERTIA, surface or bd.DiscContact(DISC_RADIUS), mass=DISC_MASS)


@eqx.filter_jit  # one program, shared by the tests that start from it
def _disc_state(scene, q, e):
    """The bundle's state of the Euler-angle state `(q, e)`."""
    qdot = bd.constrained_velocities(_disc_in_euler_angles().constraints, q, e, 0.0)
    g = jnp.eye(4).at[:3, :3].set(orientation(q))
    g = g.at[:3, 3].set(jnp.stack([q[0], q[1], DISC_RADIUS * jnp.cos(q[3])]))
    return scene.mode.state(g, body_angular_velocity(q, qdot))


def test_the_rolling_disc_on_se3_moves_as_its_euler_angle_equations_move_it():
    q0 = jnp.array([0.1, -0.2, 0.3, 0.25, 0.4])
    e0 = jnp.array([0.7, -0.3, 5.0])  # heading, tilt and spin rates
    scene = _disc_scene()
    ts = jnp.linspace(0.0, 2.0, DISC_SAVES)
    traj = _simulate(scene, _disc_state(scene, q0, e0), 2.0, ts)
    reference = diffrax.diffeqsolve(
        bd.NonholonomicTerm(_disc_in_euler_angles()), diffrax.Tsit5(), 0.0, 2.0, None, (q0, e0),
        saveat=diffrax.SaveAt(ts=ts), max_steps=100_000,
        stepsize_controller=diffrax.PIDController(rtol=1e-12, atol=1e-12),
    )  # fmt: skip
    q = reference.ys[0]
    orientations = jax.jit(jax.vmap(orientation))(q)
    g, q = np.asarray(traj.g), np.asarray(q)
    np.testing.assert_allclose(g[:, :3, :3], orientations, atol=1e-9)
    np.testing.assert_allclose(g[:, :2, 3], q[:, :2], atol=1e-9)
    assert float(np.max(np.abs(q[:, 3] - float(q0[3])))) > 0.1  # it tilts and wobbles
    energy = np.asarray(traj.energy())
    np.testing.assert_allclose(energy, energy[0], rtol=1e-10)


@jax.jit
def _maggi_and_appell(q, e):
    system = _disc_in_euler_angles()
    return bd.maggi_accelerations(system, q, e, 0.0), bd.appell_accelerations(system, q, e, 0.0)


def test_maggi_and_appell_agree_on_the_euler_angle_disc():
    kq, ke = jax.random.split(jax.random.PRNGKey(0))
    qs = jax.random.uniform(kq, (4, 5), minval=-1.0, maxval=1.0)
    es = 3.0 * jax.random.normal(ke, (4, 3))
    maggi, appell = jax.vmap(_maggi_and_appell)(qs, es)
    scale = 1.0 + float(jnp.max(jnp.abs(maggi)))
    np.testing.assert_allclose(maggi, appell, rtol=0, atol=1e-10 * scale)


def _steady_spin(tilt, heading_rate):
    r"""The spin rate $\dot\psi$ of a steady motion at tilt $\theta$ and heading rate
    $\Omega$: with $\omega_2 = \dot\psi + \Omega\sin\theta$ the angular velocity along the
    axle, the balance of angular momentum about the centre (its rate $\Omega e_z\times L$
    against the contact force's moment) gives
    $I_d\Omega^2\sin\theta\cos\theta - (I_a + ma^2)\Omega\omega_2\cos\theta - mga\sin\theta = 0$."""
    m, a = DISC_MASS, DISC_RADIUS
    s, c = np.sin(tilt), np.cos(tilt)
    axle_rate = (DIAMETRAL * heading_rate**2 * s * c - m * GRAVITY * a * s) / (
        (AXIAL + m * a**2) * heading_rate * c
    )
    return axle_rate - heading_rate * s


@pytest.mark.parametrize("offset, steady", [(0.0, True), (1e-3, False)])
def test_the_disc_precesses_steadily_where_its_algebraic_condition_holds(offset, steady):
    # Rolling on a circle at a constant tilt: the tilt stays put to rounding at the spin the
    # condition gives, and wobbles visibly 1e-3 rad/s away from it.
    tilt, heading_rate = 0.3, 2.0
    scene = _disc_scene()
    spin = _steady_spin(tilt, heading_rate) + offset
    state = _disc_state(
        scene, jnp.array([0.0, 0.0, 0.0, tilt, 0.0]), jnp.array([heading_rate, 0.0, spin])
    )
    traj = _simulate(scene, state, 3.0, jnp.linspace(0.0, 3.0, DISC_SAVES))
    wobble = float(jnp.max(jnp.abs(jnp.arcsin(traj.g[:, 2, 1]) - tilt)))
    assert (wobble < 1e-10) if steady else (wobble > 1e-5)


@functools.cache
def _largest_growth_rates():
    """The largest real part of the linearization's eigenvalues about upright rolling, at
    spins `GROWTH_FACTORS` times the critical one (one compiled program)."""

    def largest(spin):
        term = bd.NonholonomicTerm(_disc_in_euler_angles())
        upright = (jnp.zeros(5), jnp.stack([0.0 * spin, 0.0 * spin, spin]))
        return bd.linearization(term, upright)

    jacobians = jax.jit(jax.vmap(largest))(CRITICAL_SPIN * jnp.array(GROWTH_FACTORS))
    # the reduced field's block: the tilt and the three rates (the position, heading and
    # spin angle are cyclic, and their block's zero eigenvalues are defective)
    kept = np.array([3, 5, 6, 7])
    reduced = np.asarray(jacobians)[:, kept][:, :, kept]
    rates = np.max(np.real(np.linalg.eigvals(reduced)), axis=-1)
    return dict(zip(GROWTH_FACTORS, rates, strict=True))


BELOW, ABOVE = (0.999, 0.99, 0.5), (1.001, 1.01, 2.0)
GROWTH_FACTORS = BELOW + ABOVE


@pytest.mark.parametrize("factor", BELOW)
def test_upright_rolling_is_unstable_below_the_critical_spin(factor):
    # Omega_c^2 = m g a I_d / (I_a (I_a + m a^2)): a growth rate appears below it ...
    assert _largest_growth_rates()[factor] > 0.1


@pytest.mark.parametrize("factor", ABOVE)
def test_upright_rolling_is_neutrally_stable_above_the_critical_spin(factor):
    # ... and above it every eigenvalue is on the imaginary axis (a conservative system)
    assert abs(_largest_growth_rates()[factor]) < 1e-10


@pytest.mark.parametrize("factor, stays_up", [(0.8, False), (1.25, True)])
def test_the_disc_on_se3_falls_below_the_critical_spin_and_rolls_on_above_it(factor, stays_up):
    tilt = 1e-3
    scene = _disc_scene()
    state = _disc_state(
        scene, jnp.array([0.0, 0.0, 0.0, tilt, 0.0]), jnp.array([0.0, 0.0, factor * CRITICAL_SPIN])
    )
    traj = _simulate(scene, state, 4.0, jnp.linspace(0.0, 4.0, DISC_SAVES))
    axle_up = jnp.abs(traj.g[:, 2, 1])  # sin of the tilt
    largest = float(jnp.max(axle_up))
    assert (largest < 10 * tilt) if stays_up else (largest > 0.3)


@pytest.mark.parametrize(
    "surface",
    [bd.EllipsoidContact(jnp.array([0.15, 0.2, 0.1])), bd.TorusContact(0.18, 0.03)],
    ids=["ellipsoid", "torus"],
)
def test_energy_is_conserved_on_every_surface(surface):
    # the rolling constraints are scleronomic and ideal: the reaction does no work
    scene = _disc_scene(surface)
    g0 = bd.lie.se3_exp(jnp.array([0.4, 0.3, -0.2, 0.0, 0.0, 0.0]))
    traj = _simulate(
        scene,
        scene.mode.state(g0, jnp.array([2.0, -4.0, 1.0])),
        2.0,
        jnp.linspace(0, 2, DISC_SAVES),
    )
    energy = np.asarray(traj.energy())
    np.testing.assert_allclose(energy, energy[0], rtol=1e-10)
    # the surface touches the plane at every saved state, to rounding
    placed = jax.jit(jax.vmap(scene.mode.placed))(traj.g)  # compiled, not op by op
    np.testing.assert_allclose(placed, traj.g, rtol=0, atol=1e-15)


def test_a_disc_lying_flat_has_a_finite_contact_point_and_derivative():
    surface = bd.DiscContact(DISC_RADIUS)
    for n in (jnp.array([0.0, 1.0, 0.0]), jnp.array([0.0, -1.0, 0.0])):
        point, tangent = jax.jvp(surface.contact_point, (n,), (jnp.array([0.3, 0.0, 0.1]),))
        np.testing.assert_array_equal(point, jnp.zeros(3))
        assert bool(jnp.all(jnp.isfinite(tangent)))
        assert bool(jnp.all(jnp.isfinite(jax.jacrev(surface.contact_point)(n))))
    # near flat, the contact point is on the rim
    n = jnp.array([1e-3, 1.0, 0.0]) / jnp.sqrt(1 + 1e-6)
    np.testing.assert_allclose(jnp.linalg.norm(surface.contact_point(n)), DISC_RADIUS, rtol=1e-14)


def test_the_gradient_through_a_rolling_solve_equals_central_differences():
    scene = _disc_scene()
    q0 = jnp.array([0.0, 0.0, 0.0, 0.2, 0.0])

    def final_x(spin):
        state = _disc_state(scene, q0, jnp.array([0.5, 0.0, spin]))
        return bd.simulate(scene, state, 0.5, rtol=1e-12, atol=1e-12).g[-1, 0, 3]

    # Compiled whole, once: the gradient's program gives both differences' values too (a
    # program of the value alone would compile the solve again).
    value_and_grad = jax.jit(jax.value_and_grad(final_x))
    grad = value_and_grad(6.0)[1]
    h = 1e-4
    differences = (float(value_and_grad(6.0 + h)[0]) - float(value_and_grad(6.0 - h)[0])) / (2 * h)
    np.testing.assert_allclose(grad, differences, rtol=1e-6)


def test_a_state_off_the_rolling_constraints_is_refused():
    scene = _disc_scene()
    state = scene.mode.state(jnp.eye(4), jnp.array([0.0, 3.0, 0.0]))
    slipping = bd.State(state.g, state.q, state.xi.at[3].add(0.1), state.qdot)
    with pytest.raises(Exception, match="does not keep the contact"):
        bd.simulate(scene, slipping, 0.1)


def test_rolling_scenes_refuse_what_they_cannot_integrate():
    with pytest.raises(ValueError, match="rigid body"):
        bd.Scene(chain(2), mode=bd.RollingMode(bd.SphereContact(0.1)))
    with pytest.raises(ValueError, match="no `frame`"):
        bd.Scene(
            bd.RigidBody(1.0, jnp.zeros(3), jnp.eye(3)),
            frame=bd.FreeFalling(9.81),
            mode=bd.RollingMode(bd.SphereContact(0.1)),
        )
    with pytest.raises(ValueError, match="AbstractContactSurface"):
        bd.RollingMode(0.1)
    with pytest.raises(ValueError, match="AppellEquations"):
        bd.RollingMode(bd.SphereContact(0.1), equations="appell")
    with pytest.raises(ValueError, match="positive"):
        bd.SphereContact(-0.1)


def test_the_layout_gives_back_the_state_it_encodes():
    scene = _disc_scene(bd.EllipsoidContact(jnp.array([0.15, 0.2, 0.1])))
    g0 = bd.lie.se3_exp(jnp.array([0.4, 0.3, -0.2, 1.0, -2.0, 0.0]))
    state = scene.mode.state(g0, jnp.array([2.0, -4.0, 1.0]))
    term = bd.SceneTerm(scene)
    y = term.encode(0.0, state)
    assert y[1].shape == (3,)  # the characteristics: the angular velocity alone
    for a, b in zip(jax.tree.leaves(term.decode(0.0, y)), jax.tree.leaves(state), strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-15)


def test_the_trajectory_reports_the_rolling_constraints_residuals():
    scene = _disc_scene(bd.TorusContact(0.18, 0.03))
    g0 = bd.lie.se3_exp(jnp.array([0.3, 0.0, 0.0, 0.0, 0.0, 0.0]))
    traj = _simulate(
        scene, scene.mode.state(g0, jnp.array([0.0, 6.0, 0.5])), 1.0, jnp.linspace(0, 1, DISC_SAVES)
    )
    residual = traj.diagnostics().constraint_residual
    assert residual.shape == (DISC_SAVES, 4)  # the contact velocity (3) and height (1)
    assert float(jnp.max(jnp.abs(residual))) < 1e-14
    # a slipping state has a residual of its slip
    slipping = bd.State(traj.g[0], traj.q[0], traj.xi[0].at[3].add(0.1), traj.qdot[0])
    np.testing.assert_allclose(scene.mode.constraint_residual(scene, slipping)[0], 0.1, rtol=1e-12)


EGG_MJCF = """
<mujoco>
  <worldbody>
    <body name="egg">
      <freejoint/>
      <geom name="shell" type="ellipsoid" size="0.15 0.2 0.1" pos="0.01 -0.02 0.03" density="800"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_a_rolling_contact_on_an_imported_mjcf_body_equals_the_body_built_in_python():
    pytest.importorskip("mujoco")
    radii, centre = jnp.array([0.15, 0.2, 0.1]), jnp.array([0.01, -0.02, 0.03])
    surface = bd.contact_surface_from_mjcf(EGG_MJCF, "shell")
    assert isinstance(surface, bd.EllipsoidContact)
    with pytest.warns(UserWarning, match="contacts of 1 collision geom"):
        imported = bd.Scene.from_mjcf(EGG_MJCF, gravity=True)  # MuJoCo's contacts are not kept
    imported = bd.Scene(imported.system, imported.effects, mode=bd.RollingMode(surface))
    # the same egg from its solid: mass = density * 4/3 pi abc, the solid's moments
    mass = 800.0 * 4.0 / 3.0 * np.pi * float(jnp.prod(radii))
    inertia = jnp.diag(bd.Ellipsoid(radii).principal_moments(mass))
    python = bd.Scene(
        bd.RigidBody(mass, centre, inertia),
        [bd.Gravity(9.81)],
        mode=bd.RollingMode(bd.EllipsoidContact(radii, centre)),
    )
    g0 = bd.lie.se3_exp(jnp.array([0.3, -0.5, 0.2, 0.0, 0.0, 0.0]))
    ts = jnp.linspace(0.0, 1.5, DISC_SAVES)
    ours = _simulate(imported, imported.mode.state(g0, jnp.array([1.0, 3.0, -2.0])), 1.5, ts)
    theirs = _simulate(python, python.mode.state(g0, jnp.array([1.0, 3.0, -2.0])), 1.5, ts)
    np.testing.assert_allclose(ours.g, theirs.g, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ours.xi, theirs.xi, rtol=0, atol=1e-11)


@pytest.mark.parametrize(
    "geom, message",
    [
        ('type="cylinder" size="0.2 0.02"', "along a line"),
        ('type="box" size="0.1 0.1 0.1"', "not a sphere"),
    ],
    ids=["cylinder", "box"],
)
def test_a_geom_that_does_not_roll_at_a_point_is_refused(geom, message):
    pytest.importorskip("mujoco")
    xml = (
        f'<mujoco><worldbody><body><freejoint/><geom name="g" {geom}/></body></worldbody></mujoco>'
    )
    with pytest.raises(ValueError, match=message):
        bd.contact_surface_from_mjcf(xml, "g")
