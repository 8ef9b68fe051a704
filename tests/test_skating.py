"""A rigid body on a skate's blade (`SkatingMode`, seed 001 (76), (77), (82) on SE(3)), and
every plane contact's accelerations: against the Chaplygin sleigh's closed form, conserved
energy, and the free body's equations with Lagrange multipliers for the contact rows."""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import bundledyn as bd

GRAVITY = 9.81


def _hat(w):
    return jnp.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


# --- the Chaplygin sleigh: an upright skate, in closed form -----------------------------

SLEIGH_MASS, SLEIGH_INERTIA, SPIN = 2.0, 0.3, 1.5
SLEIGH_SAVES = 13
SLEIGH_TS = jnp.linspace(0.0, 3.0, SLEIGH_SAVES)


def _sleigh_scene(distance):
    """A body skating upright, its blade `distance` behind the centre of mass at its height:
    the blade's sideways reaction acts in the horizontal plane of the centre of mass, so
    without gravity the body turns about the vertical only (a principal axis)."""
    inertia = jnp.diag(jnp.array([0.5, 0.4, SLEIGH_INERTIA]))
    body = bd.RigidBody(SLEIGH_MASS, jnp.zeros(3), inertia)
    blade = bd.PointContact(jnp.stack([-distance, 0.0, 0.0]))
    return bd.Scene(body, mode=bd.SkatingMode(blade, blade_axis=(0.0, 1.0, 0.0)))


def _sleigh_solve(distance):
    scene = _sleigh_scene(distance)
    state = scene.mode.state(jnp.eye(4), jnp.array([0.0, 0.0, SPIN]), jnp.zeros(1))
    return bd.simulate(
        scene, state, SLEIGH_TS[-1], rtol=1e-12, atol=1e-12, saveat=diffrax.SaveAt(ts=SLEIGH_TS)
    )


def _sleigh_closed_form(distance, t):
    """`ChaplyginSleigh`'s closed form from rest with turning rate `SPIN`: the blade's speed
    $v = V\\tanh kt$, the turning rate $\\omega_0\\,\\mathrm{sech}\\,kt$ and the heading."""
    J = SLEIGH_INERTIA + SLEIGH_MASS * distance**2
    V = SPIN * jnp.sqrt(J / SLEIGH_MASS)
    k = distance * SPIN * jnp.sqrt(SLEIGH_MASS / J)
    return V * jnp.tanh(k * t), SPIN / jnp.cosh(k * t), (SPIN / k) * jnp.arctan(jnp.sinh(k * t))


def test_an_upright_skate_is_the_chaplygin_sleigh():
    distance = 0.4
    traj = _sleigh_solve(distance)
    speed, turning, heading = _sleigh_closed_form(distance, traj.ts)
    # the blade at (-a, 0, 0) moves along the body's x axis: its speed is v_x
    np.testing.assert_allclose(traj.xi[:, 3], speed, rtol=0, atol=1e-9)
    np.testing.assert_allclose(traj.xi[:, 2], turning, rtol=0, atol=1e-9)
    np.testing.assert_allclose(
        jnp.arctan2(traj.g[:, 1, 0], traj.g[:, 0, 0]), heading, rtol=0, atol=1e-9
    )
    # it stays upright on the plane, and its blade never slides sideways
    np.testing.assert_allclose(traj.g[:, 2, 2], 1.0, rtol=0, atol=1e-12)
    assert float(jnp.max(jnp.abs(traj.constraint_residual()))) < 1e-14


def test_the_gradient_through_a_skating_solve_is_the_closed_forms():
    # d v(T) / d a through the solve (the sleigh's blade distance), against the closed
    # form's derivative
    distance = 0.4
    # Each compiled whole (one program, not a linearised and a transposed one and their ops).
    ours = jax.jit(jax.grad(lambda a: _sleigh_solve(a).xi[-1, 3]))(distance)
    expected = jax.jit(jax.grad(lambda a: _sleigh_closed_form(a, SLEIGH_TS[-1])[0]))(distance)
    np.testing.assert_allclose(ours, expected, rtol=1e-8)


# --- every plane contact against Lagrange multipliers -------------------------------------

BODY_INERTIA = jnp.array([[0.11, 0.01, -0.02], [0.01, 0.09, 0.015], [-0.02, 0.015, 0.07]])
BODY_CENTRE = jnp.array([0.01, -0.02, 0.03])
BLADE_AXIS = jnp.array([0.1, 1.0, 0.2]) / jnp.linalg.norm(jnp.array([0.1, 1.0, 0.2]))

MODES = {
    "rolling sphere": bd.RollingMode(bd.SphereContact(0.2, (0.0, 0.02, 0.05))),
    "rolling disc": bd.RollingMode(bd.DiscContact(0.25, axis=BLADE_AXIS)),
    "rolling ellipsoid": bd.RollingMode(bd.EllipsoidContact(jnp.array([0.2, 0.15, 0.1]))),
    "rolling torus": bd.RollingMode(bd.TorusContact(0.18, 0.03, axis=BLADE_AXIS)),
    "skating point": bd.SkatingMode(bd.PointContact((-0.2, 0.0, -0.3)), blade_axis=BLADE_AXIS),
    "skating rockered blade": bd.SkatingMode(
        bd.DiscContact(1.2, axis=BLADE_AXIS, centre=(0.0, 0.0, 0.9)), blade_axis=BLADE_AXIS
    ),
}


# Maggi's equations with the body twist as quasi-velocities, and Appell's from the energy of
# the material points' accelerations: two assemblies of the same rates.
EQUATIONS = {"maggi": bd.MaggiEquations(), "appell": bd.AppellEquations()}


def _tilted_plane(mode, equations):
    """`mode` on a tilted plane, with `equations`: gravity then drives motion along it."""
    normal = jnp.array([0.3, -0.2, 1.0])
    return type(mode)(
        mode.surface,
        normal=normal,
        offset=0.1,
        equations=equations,
        **({"blade_axis": mode.blade_axis} if isinstance(mode, bd.SkatingMode) else {}),
    )


def _contact_scene(name, equations="maggi"):
    body = bd.RigidBody(1.7, BODY_CENTRE, BODY_INERTIA)
    mode = _tilted_plane(MODES[name], EQUATIONS[equations])
    return bd.Scene(body, [bd.Gravity(GRAVITY)], mode=mode)


def _rows(mode, g):
    """The contact's velocity rows, from the physical description alone: the contact point
    $u = v + \\omega\\times c$ has no velocity along the plane's normal and, on a blade,
    none across the blade (along the blade plane's normal projected onto the plane)."""
    n = g[:3, :3].T @ mode.normal
    c = mode.surface.contact_point(n)
    point_velocity = jnp.concatenate([-_hat(c), jnp.eye(3)], axis=1)  # u = [-c^, I] xi
    if isinstance(mode, bd.SkatingMode):
        k = mode.blade_axis
        directions = jnp.stack([n, k - jnp.dot(k, n) * n])
        return directions @ point_velocity
    return point_velocity


def _characteristics(mode, g, xi):
    """$e = (\\omega, \\sigma)$: on a blade, $\\sigma$ the contact point's speed along the
    blade's line on the plane, $k\\times n/|k\\times n|$."""
    if not isinstance(mode, bd.SkatingMode):
        return xi[:3]
    n = g[:3, :3].T @ mode.normal
    c = mode.surface.contact_point(n)
    along = jnp.cross(mode.blade_axis, n)
    sigma = jnp.dot(along / jnp.linalg.norm(along), xi[3:] + jnp.cross(xi[:3], c))
    return jnp.concatenate([xi[:3], sigma[None]])


def _multiplier_rates(scene, g, xi):
    """$\\dot e$ from the free body's Euler–Poincaré equations $M\\dot\\xi =
    \\operatorname{ad}_\\xi^T M\\xi + F + A^T\\lambda$ with the rows $A\\xi = 0$ differentiated,
    $A\\dot\\xi + \\dot A\\xi = 0$: a derivation that never forms the parametric form."""
    mode = scene.mode
    M = scene.system.metric(jnp.zeros(0))
    omega, v = xi[:3], xi[3:]
    ad = jnp.block([[_hat(omega), jnp.zeros((3, 3))], [_hat(v), _hat(omega)]])
    q = jnp.zeros(0)
    F, _ = scene.forces(bd.Kinematics(0.0, g, q, xi, q))
    g_dot = g @ bd.lie.hat(xi)
    A, A_dot_xi = jax.jvp(lambda g: _rows(mode, g) @ xi, (g,), (g_dot,))
    A = _rows(mode, g)
    r = A.shape[0]
    saddle = jnp.block([[M, -A.T], [A, jnp.zeros((r, r))]])
    xi_dot = jnp.linalg.solve(saddle, jnp.concatenate([ad.T @ M @ xi + F, -A_dot_xi]))[:6]
    return jax.jvp(lambda g, xi: _characteristics(mode, g, xi), (g, xi), (g_dot, xi_dot))[1]


@eqx.filter_jit
def _both_rates(scene, state):
    term = bd.SceneTerm(scene)
    _, ours = term.body_vf(0.0, term.encode(0.0, state), None)
    return ours, _multiplier_rates(scene, state.g, state.xi)


@pytest.mark.parametrize("equations", EQUATIONS)
@pytest.mark.parametrize("name", MODES)
def test_the_contact_accelerations_equal_those_of_lagrange_multipliers(name, equations):
    scene = _contact_scene(name, equations)
    keys = jax.random.split(jax.random.PRNGKey(7), 3)
    for key in keys:
        k = jax.random.split(key, 3)
        g = bd.lie.se3_exp(jnp.concatenate([0.8 * jax.random.normal(k[0], (3,)), jnp.zeros(3)]))
        s = 1 if isinstance(scene.mode, bd.SkatingMode) else 0
        state = scene.mode.state(
            g, 3.0 * jax.random.normal(k[1], (3,)), jax.random.normal(k[2], (s,))
        )
        ours, reference = _both_rates(scene, state)
        scale = float(jnp.max(jnp.abs(reference)))
        np.testing.assert_allclose(ours, reference, rtol=0, atol=1e-11 * scale)


# --- a skate falling over: energy and the blade -------------------------------------------


def test_a_skate_tipping_under_gravity_keeps_its_energy_and_its_blade():
    scene = _contact_scene("skating rockered blade")
    g0 = bd.lie.se3_exp(jnp.array([0.25, -0.1, 0.3, 0.0, 0.0, 0.0]))
    state = scene.mode.state(g0, jnp.array([0.5, -1.0, 2.0]), jnp.array([1.5]))
    ts = jnp.linspace(0.0, 1.0, SLEIGH_SAVES)
    traj = bd.simulate(scene, state, 1.0, rtol=1e-12, atol=1e-12, saveat=diffrax.SaveAt(ts=ts))
    energy = np.asarray(traj.energy())
    np.testing.assert_allclose(energy, energy[0], rtol=1e-10)
    assert np.ptp(np.asarray(traj.g[:, 2, 3])) > 1e-2  # it moves: gravity does work
    residual = traj.diagnostics().constraint_residual
    assert residual.shape == (SLEIGH_SAVES, 4)  # the contact velocity off the blade, the height
    assert float(jnp.max(jnp.abs(residual))) < 1e-13


# --- the layout, singular points and refusals -----------------------------------------------


def test_the_layout_gives_back_the_state_it_encodes():
    scene = _contact_scene("skating point")
    g0 = bd.lie.se3_exp(jnp.array([0.4, 0.3, -0.2, 1.0, -2.0, 0.0]))
    state = scene.mode.state(g0, jnp.array([2.0, -4.0, 1.0]), jnp.array([0.7]))
    term = bd.SceneTerm(scene)
    y = term.encode(0.0, state)
    assert y[1].shape == (4,)  # the angular velocity and the speed along the blade
    for a, b in zip(jax.tree.leaves(term.decode(0.0, y)), jax.tree.leaves(state), strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-15)


def test_a_blade_lying_flat_has_a_finite_direction_and_derivative():
    mode = MODES["skating point"]
    for n in (BLADE_AXIS, -BLADE_AXIS):
        direction, tangent = jax.jvp(mode.sliding_directions, (n,), (jnp.array([0.3, 0.0, 0.1]),))
        np.testing.assert_array_equal(direction, jnp.zeros((3, 1)))
        assert bool(jnp.all(jnp.isfinite(tangent)))
        assert bool(jnp.all(jnp.isfinite(jax.jacrev(mode.sliding_directions)(n))))
    # upright, the blade runs along the body's x axis
    upright = bd.SkatingMode(bd.PointContact((0.0, 0.0, 0.0)))
    np.testing.assert_allclose(
        upright.sliding_directions(jnp.array([0.0, 0.0, 1.0]))[:, 0], [1.0, 0.0, 0.0]
    )


def test_a_state_sliding_across_the_blade_is_refused():
    scene = _sleigh_scene(0.4)
    state = scene.mode.state(jnp.eye(4), jnp.array([0.0, 0.0, 1.0]), jnp.array([0.5]))
    sideways = bd.State(state.g, state.q, state.xi.at[4].add(0.1), state.qdot)
    np.testing.assert_allclose(scene.mode.constraint_residual(scene, sideways)[1], 0.1)
    with pytest.raises(Exception, match="does not keep the contact"):
        bd.simulate(scene, sideways, 0.1)


def test_skating_refuses_what_it_cannot_integrate():
    with pytest.raises(ValueError, match="blade_axis"):
        bd.SkatingMode(bd.PointContact((0.0, 0.0, 0.0)), blade_axis=(0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="AbstractContactSurface"):
        bd.SkatingMode((0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="PointContact.point"):
        bd.PointContact((0.0, 0.0))
    with pytest.raises(ValueError, match="sliding"):
        _sleigh_scene(0.4).mode.state(jnp.eye(4), jnp.zeros(3), jnp.zeros(2))
