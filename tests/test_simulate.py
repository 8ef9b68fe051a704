"""Simulation (issue: dynamics): closed forms, conservation laws, holonomy, gradients, errors."""

import re

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.integrate
import scipy.special
from systems import chain
from traced import lowerings, scan_lengths

import bundledyn as bd
from bundledyn import lie

INERTIA = np.array([1.0, 2.0, 3.0])


def euler_top(t, omega0):
    """Torque-free asymmetric top in closed form (Landau & Lifshitz §37), ω(0) = (a, 0, b).

    Body angular velocity by Jacobi elliptic functions; attitude by the Euler angles of the
    body axes relative to the (fixed) angular momentum, with φ by quadrature of φ̇.
    """
    I1, I2, I3 = INERTIA
    a, _, b = omega0
    E2 = I1 * a**2 + I3 * b**2  # 2E
    L2 = (I1 * a) ** 2 + (I3 * b) ** 2
    assert L2 > E2 * I2  # the branch of the formulas below
    L = np.sqrt(L2)
    rate = np.sqrt((I3 - I2) * (L2 - E2 * I1) / (I1 * I2 * I3))
    k2 = (I2 - I1) * (E2 * I3 - L2) / ((I3 - I2) * (L2 - E2 * I1))
    amp = np.array(
        [
            np.sqrt((E2 * I3 - L2) / (I1 * (I3 - I1))),
            np.sqrt((E2 * I3 - L2) / (I2 * (I3 - I2))),
            np.sqrt((L2 - E2 * I1) / (I3 * (I3 - I1))),
        ]
    )

    def omega(t):
        sn, cn, dn, _ = scipy.special.ellipj(rate * t, k2)
        return amp * np.array([cn, sn, dn])

    def angles(w):
        Lb = INERTIA * w  # body angular momentum = L (sinθ sinψ, sinθ cosψ, cosθ)
        return np.arccos(Lb[2] / L), np.arctan2(Lb[0], Lb[1])

    def phi_rate(t):
        w = omega(t)
        return L * (I1 * w[0] ** 2 + I2 * w[1] ** 2) / ((I1 * w[0]) ** 2 + (I2 * w[1]) ** 2)

    def euler_zxz(phi, theta, psi):
        return np.asarray(lie.rotation_z(phi) @ lie.rotation_x(theta) @ lie.rotation_z(psi))

    theta0, psi0 = angles(omega(0.0))
    phi, _ = scipy.integrate.quad(phi_rate, 0.0, t, epsabs=1e-13, epsrel=1e-13, limit=1000)
    theta, psi = angles(omega(t))
    # R(0) = 1 = R_align Rx(θ0) Rz(ψ0): the spatial frame whose z axis is the momentum.
    R_align = euler_zxz(0.0, theta0, psi0).T
    return omega(t), R_align @ euler_zxz(phi, theta, psi)


# The Dzhanibekov body: near the separatrix through the intermediate axis (elliptic modulus
# k² = 0.963) it flips over and over, the classic hard case for attitude integration.
OMEGA0 = np.array([0.85, 0.0, 0.5])
DZHANIBEKOV = bd.Scene(bd.RigidBody(1.0, np.zeros(3), np.diag(INERTIA)))
DZHANIBEKOV_STATE = bd.State(jnp.eye(4), xi=jnp.concatenate([OMEGA0, jnp.zeros(3)]))


def test_torque_free_body_matches_jacobi_elliptic_solution():
    """Dzhanibekov: ω and attitude at t = 20 to 1e-8 with rtol = 1e-10 (default solver)."""
    traj = bd.simulate(DZHANIBEKOV, DZHANIBEKOV_STATE, 20.0, rtol=1e-10, atol=1e-12)
    omega_exact, R_exact = euler_top(20.0, OMEGA0)
    np.testing.assert_allclose(traj.xi[-1, :3], omega_exact, atol=1e-8)
    np.testing.assert_allclose(traj.g[-1, :3, :3], R_exact, atol=1e-8)
    assert traj.orthogonality_error().max() < 1e-13


def test_default_solver_is_the_cheaper_and_more_accurate_at_default_tolerance():
    """Why `simulate` defaults to RKMK87: at its default rtol = atol = 1e-8 it beats RKMK54
    on the Dzhanibekov body over 20 s (closed form) both at t1 and at saved times between
    steps, where its dense output is only of fifth order, with fewer field evaluations.
    Measured: errors 8.9e-9 against 1.0e-7 at t1, at most 3.5e-8 against 8.0e-8 at the saved
    times, with 29 steps (406 evaluations) against 84 (588)."""
    ts = np.linspace(0.37, 20.0, 9)
    saveat = diffrax.SaveAt(ts=jnp.asarray(ts))
    exact = [euler_top(t, OMEGA0) for t in ts]
    errors, evaluations = {}, {}
    for solver in (None, bd.RKMK54()):
        traj = bd.simulate(DZHANIBEKOV, DZHANIBEKOV_STATE, 20.0, solver=solver, saveat=saveat)
        name = type(solver).__name__ if solver else "default"
        errors[name] = [
            max(np.abs(traj.xi[i, :3] - w).max(), np.abs(traj.g[i, :3, :3] - R).max())
            for i, (w, R) in enumerate(exact)
        ]
        stages = (solver or bd.RKMK87()).tableau.num_stages
        evaluations[name] = int(traj.stats["num_steps"]) * stages
    assert errors["default"][-1] < errors["RKMK54"][-1]
    assert max(errors["default"][:-1]) < max(errors["RKMK54"][:-1])
    assert evaluations["default"] < evaluations["RKMK54"]


def test_adaptive_solver_takes_fixed_steps_with_a_constant_controller():
    """`stepsize_controller=diffrax.ConstantStepSize()` with `dt0`: the default RKMK87 takes
    exactly (t1 - t0)/dt0 steps, and its error against the closed form falls at its order.
    Measured on the Dzhanibekov body over 20 s: 8.3e-10 with 40 steps, 3.3e-12 with 80, an
    order of 8.0."""
    constant = diffrax.ConstantStepSize()

    @jax.jit
    def run(dt):
        traj = bd.simulate(
            DZHANIBEKOV, DZHANIBEKOV_STATE, 20.0, dt0=dt, stepsize_controller=constant
        )
        return traj.xi[-1, :3], traj.g[-1, :3, :3], traj.stats["num_steps"]

    omega_exact, R_exact = euler_top(20.0, OMEGA0)
    errors = []
    for n in (40, 80):
        omega, R, steps = run(20.0 / n)
        assert int(steps) == n
        errors.append(max(np.abs(omega - omega_exact).max(), np.abs(R - R_exact).max()))
    assert 7.5 < np.log2(errors[0] / errors[1]) < 8.5


def test_a_given_adaptive_controller_starts_like_the_default():
    """A `stepsize_controller` equal to the default PI controller gives the default's
    solve step for step (the same starting step, from the controller's own tolerances);
    `ConstantStepSize` without `dt0` asks for it."""
    scene, state = DZHANIBEKOV, DZHANIBEKOV_STATE
    default = bd.simulate(scene, state, 5.0, rtol=1e-7, atol=1e-9)
    pi = diffrax.PIDController(rtol=1e-7, atol=1e-9, pcoeff=0.4, icoeff=0.3)
    given = bd.simulate(scene, state, 5.0, stepsize_controller=pi)
    assert int(given.stats["num_steps"]) == int(default.stats["num_steps"])
    np.testing.assert_array_equal(given.g, default.g)
    with pytest.raises(ValueError, match="ConstantStepSize takes fixed steps: pass `dt0`"):
        bd.simulate(scene, state, 5.0, stepsize_controller=diffrax.ConstantStepSize())


def test_new_horizons_tolerances_and_first_steps_reuse_the_compiled_solve():
    """Times, tolerances and a first step given as Python numbers are data of the compiled
    solve, not keys of its cache (`equinox.filter_jit` holds Python numbers static: each new
    value compiled the solve again), and each call uses its own values."""
    from bundledyn._simulate import _traced

    scene, state = DZHANIBEKOV, DZHANIBEKOV_STATE
    bd.simulate(scene, state, 1.0)
    bd.simulate(scene, state, 1.0, dt0=0.1)
    cases = [(0.0, 2.0, 1e-6, 1e-9, None), (0.5, 3, 1e-9, 1e-7, None),
             (0.0, 1.5, 1e-8, 1e-8, 0.05), (1, 2.5, 1e-7, 1e-8, 0.2)]  # fmt: skip
    trajectories, programs = lowerings(
        lambda: [
            bd.simulate(scene, state, t1, t0=t0, rtol=rtol, atol=atol, dt0=dt0)
            for t0, t1, rtol, atol, dt0 in cases
        ]
    )
    assert programs == 0
    # A number first met inside a traced function is not kept as that trace's tracer.
    inside = jax.jit(lambda g: bd.simulate(scene, bd.State(g, xi=state.xi), 1.25).g[-1])
    np.testing.assert_array_equal(inside(state.g), bd.simulate(scene, state, 1.25).g[-1])
    assert not isinstance(_traced(1.25), jax.core.Tracer)
    for (t0, t1, rtol, atol, dt0), traj in zip(cases, trajectories, strict=True):
        np.testing.assert_array_equal(traj.ts, [t0, t1])
        f64 = lambda x: None if x is None else jnp.asarray(x, jnp.float64)  # noqa: E731
        given_as_arrays = bd.simulate(
            scene, state, f64(t1), t0=f64(t0), rtol=f64(rtol), atol=f64(atol), dt0=f64(dt0)
        )
        np.testing.assert_array_equal(traj.g, given_as_arrays.g)


FREE_CHAIN_STATE = bd.State(
    lie.se3_exp(jnp.array([0.1, -0.3, 0.2, 0.5, 0.0, -0.2])),
    0.3 * jnp.cos(jnp.arange(chain(5).shape_dim)),
    jnp.array([0.4, -0.3, 0.6, 0.2, -0.1, 0.3]),
    0.8 * jnp.sin(1.0 + jnp.arange(chain(5).shape_dim, dtype=float)),
)


def test_free_chain_conserves_energy_and_momentum():
    """Free 5-body chain, rtol 1e-10, 10 s: energy ≤ 1e-8 relative, momentum to 1e-10
    relative, at every step (measured 5e-12 and 3e-12; between steps the fifth-order dense
    output of the default RKMK87 adds its own error, 2e-10 and 6e-10 at `SaveAt(ts)`)."""
    traj = bd.simulate(
        bd.Scene(chain(5)),
        FREE_CHAIN_STATE,
        10.0,
        rtol=1e-10,
        atol=1e-12,
        saveat=diffrax.SaveAt(steps=True),
        max_steps=1024,
    )
    taken = np.isfinite(traj.ts)  # SaveAt(steps=True) pads up to max_steps
    assert taken.sum() > 100
    # The diagnostics are one compiled program each, not one per primitive (~400 each).
    (E, P), programs = lowerings(lambda: (traj.energy(), traj.spatial_momentum()))
    assert programs <= 2
    E, P = E[taken], P[taken]
    assert np.abs(E / E[0] - 1).max() <= 1e-8
    assert np.abs(P - P[:1]).max() <= 1e-10 * np.abs(P[0]).max()
    assert traj.orthogonality_error()[taken].max() <= 1e-13
    assert np.abs(traj.qdot[taken]).max() > 0.5  # the shape really moves


CAT = chain(3, ("revolute", "revolute"))


def _loop(q0, radius, period):
    def q_of_t(t):
        phase = 2 * jnp.pi * t / period
        return q0 + radius * jnp.array([jnp.cos(phase) - 1.0, jnp.sin(phase)])

    return q_of_t


@jax.jit
def _prescribed_loop(radius):
    q0 = jnp.array([0.4, -0.3])
    q_of_t = _loop(q0, radius, 1.0)
    scene = bd.Scene(CAT, shape=bd.Prescribed(q_of_t))
    q, qdot = scene.shape.at(0.0)
    xi0 = -bd.connection(CAT, q) @ qdot  # zero momentum: U = 0
    traj = bd.simulate(scene, bd.State(jnp.eye(4), q, xi0, qdot), 1.0, rtol=1e-11, atol=1e-13)
    direct = bd.horizontal_lift(CAT, q_of_t, steps=256)
    centre = q0 - jnp.array([radius, 0.0])
    return traj.g[-1], direct, bd.curvature(CAT, centre), traj.spatial_momentum()


def test_prescribed_loop_rotation_is_the_holonomy():
    """Zero momentum + closed shape loop: the net motion is the holonomy ∮ −A dq, and small loops
    rotate by −curvature × area."""
    g_sim, g_direct, _, momentum = _prescribed_loop(0.5)
    np.testing.assert_allclose(g_sim, g_direct, atol=1e-9)
    rotation = np.asarray(jax.jit(lie.so3_log)(g_sim[:3, :3]))
    assert np.abs(rotation).max() > 1e-2  # a real reorientation
    np.testing.assert_allclose(momentum, 0.0, atol=1e-12)
    se3_log = jax.jit(lie.se3_log)  # compiled once for both loops
    for radius in (1e-2, 5e-3):
        g, _, Omega, _ = _prescribed_loop(radius)
        expected = -np.pi * radius**2 * np.asarray(Omega)[:, 0, 1]
        np.testing.assert_allclose(se3_log(g), expected, atol=4 * radius * np.abs(expected).max())


def test_gravity_parabola_and_torque_free_rotation():
    """Under uniform gravity the centre of mass follows the parabola exactly and the rotation
    about it is the torque-free one."""
    body = bd.RigidBody(
        2.0, [0.1, -0.2, 0.3], [[0.3, 0.01, 0.0], [0.01, 0.5, 0.02], [0.0, 0.02, 0.7]]
    )
    state = bd.State(
        lie.se3_exp(jnp.array([0.2, 0.1, -0.3, 1.0, 2.0, 3.0])), xi=[1.0, -2.0, 0.5, 0.3, 0.2, 5.0]
    )
    ts = jnp.linspace(0.0, 3.0, 7)
    gamma = jnp.array([0.0, -3.0, -9.0])
    gravity = bd.Gravity(jnp.linalg.norm(gamma), gamma)

    kw = dict(rtol=1e-12, atol=1e-12, saveat=diffrax.SaveAt(ts=ts))
    fall = bd.simulate(bd.Scene(body, (gravity,)), state, 3.0, **kw)
    free = bd.simulate(bd.Scene(body), state, 3.0, **kw)
    # The closed form in numpy (not primitive by primitive).
    g0, xi0, com = (np.asarray(x) for x in (state.g, state.xi, body.com))
    ts, gamma = np.asarray(ts), np.asarray(gamma)
    c0 = g0[:3, 3] + g0[:3, :3] @ com
    v0 = g0[:3, :3] @ (xi0[3:] + np.cross(xi0[:3], com))
    parabola = c0[None, :] + ts[:, None] * v0[None, :] + 0.5 * ts[:, None] ** 2 * gamma[None, :]
    fall_g = np.asarray(fall.g)
    centres = fall_g[:, :3, 3] + np.einsum("...ij,j->...i", fall_g[:, :3, :3], com)
    np.testing.assert_allclose(centres, parabola, atol=1e-9)
    free_g, fall_xi, free_xi = (np.asarray(x) for x in (free.g, fall.xi, free.xi))
    np.testing.assert_allclose(fall_g[:, :3, :3], free_g[:, :3, :3], atol=1e-9)
    np.testing.assert_allclose(fall_xi[:, :3], free_xi[:, :3], atol=1e-9)


BAD_STATES = {
    "g shape": (lambda: bd.State(jnp.eye(3)), "shape"),
    "xi shape": (lambda: bd.State(jnp.eye(4), xi=jnp.zeros(5)), "xi"),
    "qdot length": (lambda: bd.State(jnp.eye(4), jnp.zeros(2), qdot=jnp.zeros(3)), "qdot"),
    "non-orthogonal": (lambda: bd.State(jnp.eye(4).at[0, 1].set(1e-6)), "orthogonal"),
    "NaN": (lambda: bd.State(jnp.eye(4), xi=jnp.array([jnp.nan, 0, 0, 0, 0, 0])), "NaN"),
}


@pytest.mark.parametrize("case", BAD_STATES)
def test_bad_states_raise_clear_errors(case):
    make, match = BAD_STATES[case]
    with pytest.raises(ValueError, match=match):
        make()


def test_simulate_rejects_wrong_shape_and_reports_max_steps():
    scene, state = DZHANIBEKOV, DZHANIBEKOV_STATE  # a rigid body compiles fast
    with pytest.raises(ValueError, match="shape"):
        bd.simulate(scene, bd.State(jnp.eye(4), jnp.zeros(2)), 1.0)
    with pytest.raises(ValueError, match="dt0"):
        bd.simulate(scene, state, 1.0, solver=bd.RKMK4())
    short = dict(rtol=1e-12, atol=1e-12, max_steps=4)
    with pytest.raises(Exception, match="max_steps|maximum number of"):
        bd.simulate(scene, state, 1.0, **short)
    traj = bd.simulate(scene, state, 1.0, throw=False, **short)
    assert traj.result == diffrax.RESULTS.max_steps_reached


TWO = chain(2, ("revolute",))
TWO_STATE = bd.State(
    jnp.eye(4), jnp.array([0.3]), jnp.array([0.3, -0.2, 0.5, 0.1, 0.0, 0.2]), jnp.array([0.5])
)


@jax.jit
def _variational_run(h):
    """10⁴ steps of the free 2-body chain with the variational integrator."""
    steps = 10_000
    traj = bd.simulate(
        bd.Scene(TWO),
        TWO_STATE,
        steps * h,
        solver=bd.VariationalMidpoint(),
        dt0=h,
        saveat=diffrax.SaveAt(ts=jnp.linspace(0.0, steps * h, 401)),
        max_steps=steps + 1,
    )
    return traj.energy(), traj.spatial_momentum(), traj.g[-1]


def test_variational_integrator_has_bounded_energy_and_exact_momentum():
    """No energy drift over 10⁴ steps (the error's envelope does not grow), spatial momentum
    conserved to rounding, second-order energy error."""
    E, P, _ = _variational_run(0.01)
    dE = np.abs(E / E[0] - 1)
    assert dE[-100:].max() < 1.5 * dE[:100].max()  # last quarter vs first quarter
    np.testing.assert_allclose(P, jnp.broadcast_to(P[0], P.shape), atol=1e-11 * np.abs(P[0]).max())
    E_half, _, _ = _variational_run(0.005)
    ratio = dE.max() / np.abs(E_half / E_half[0] - 1).max()
    assert 3.5 < ratio < 4.5  # energy error ∝ h²


def test_gravity_gradient_torque_is_maccullagh():
    """The torque of GravityGradient about the centre of mass is 3μ/ρ³ ρ̂ × (l ρ̂) (MacCullagh),
    and the per-body sum equals the system expansion for a single body."""
    body = bd.RigidBody(
        3.0, [0.1, 0.2, -0.1], [[0.4, 0.05, 0.0], [0.05, 0.6, 0.02], [0.0, 0.02, 0.9]]
    )
    one = bd.Multibody(body, [])
    g = lie.se3_exp(jnp.array([0.3, -0.5, 0.2, 7.0, -3.0, 2.0]))
    kin = bd.Kinematics(0.0, g, jnp.zeros(0), jnp.zeros(6), jnp.zeros(0))
    mu = 4.0e3
    F, _ = bd.GravityGradient(mu).generalized_force(body, kin)
    F_per_body, _ = bd.BodywiseGravityGradient(mu).generalized_force(one, kin)
    np.testing.assert_allclose(F_per_body, F, rtol=1e-12)
    R, c = g[:3, :3], body.com
    rho = g[:3, 3] + R @ c
    l_world = R @ body.inertia @ R.T
    torque_world = (
        3
        * mu
        / (rho @ rho) ** 1.5
        * jnp.cross(rho / jnp.linalg.norm(rho), l_world @ rho / jnp.linalg.norm(rho))
    )
    torque_com = F[:3] - jnp.cross(c, F[3:])  # move the moment from the body origin to the centre
    np.testing.assert_allclose(torque_com, R.T @ torque_world, rtol=1e-10)
    point_mass = -mu * body.mass * rho / (rho @ rho) ** 1.5
    np.testing.assert_allclose(
        R @ F[3:], point_mass, rtol=1e-2
    )  # the quadrupole is a small correction


def test_stock_diffrax_solver_on_the_embedding():
    """A stock diffrax solver integrates the pose in its 4×4 embedding: accurate, but its
    rotation drifts off SO(3) by its local error (projected back on output, drift reported),
    which the Lie-group solvers avoid."""
    scene, state = DZHANIBEKOV, DZHANIBEKOV_STATE
    stock = bd.simulate(scene, state, 20.0, solver=diffrax.Tsit5(), rtol=1e-8, atol=1e-8)
    lie_group = bd.simulate(scene, state, 20.0, rtol=1e-8, atol=1e-8)
    omega_exact, R_exact = euler_top(20.0, OMEGA0)
    for traj in (stock, lie_group):
        np.testing.assert_allclose(traj.xi[-1, :3], omega_exact, atol=1e-5)
        np.testing.assert_allclose(traj.g[-1, :3, :3], R_exact, atol=1e-5)
    assert lie_group.orthogonality_error().max() < 1e-13 < stock.stats["embedding_drift"]
    assert stock.orthogonality_error().max() < 1e-13  # the saved poses are projected


@pytest.mark.parametrize("kind", ["identity", "rotation", "near_rotation", "general"])
def test_project_to_se3_derivatives_at_rotations(key, kind):
    """The polar factor's derivative is finite and right at every rotation, where all three
    singular values coincide (autodiff of the SVD divides by their differences: NaN):
    forward mode against central differences, reverse mode its transpose, and at a rotation
    $P$ the closed form $P\\,\\mathrm{skew}(P^T dA) = (dA - P\\,dA^T P)/2$; second
    derivatives (the gradient's JVP) against central differences of the gradient."""
    R = lie.se3_exp(jnp.array([0.4, -1.1, 0.7, 0.0, 0.0, 0.0]))[:3, :3]
    noise, dA, W = jax.random.normal(key, (3, 3, 3))
    A = {
        "identity": jnp.eye(3),
        "rotation": R,
        "near_rotation": R + 1e-8 * noise,
        "general": R + 0.3 * noise,  # distinct singular values
    }[kind]
    g = jnp.eye(4).at[:3, 3].set(jnp.array([1.0, 2.0, 3.0]))
    polar = jax.jit(lambda A: bd.project_to_se3(g.at[:3, :3].set(A))[:3, :3])
    P, tangent = jax.jvp(polar, (A,), (dA,))
    h = 1e-6
    np.testing.assert_allclose(
        tangent, (polar(A + h * dA) - polar(A - h * dA)) / (2 * h), atol=1e-8
    )
    grad = jax.jit(jax.grad(lambda A: jnp.sum(W * polar(A))))
    np.testing.assert_allclose(jnp.sum(grad(A) * dA), jnp.sum(W * tangent), rtol=1e-12)
    _, second = jax.jvp(grad, (A,), (dA,))  # the JVP rule is differentiated in turn
    np.testing.assert_allclose(second, (grad(A + h * dA) - grad(A - h * dA)) / (2 * h), atol=1e-7)
    if kind != "general":
        np.testing.assert_allclose(tangent, (dA - P @ dA.T @ P) / 2, atol=1e-7)
    translation = jax.jacrev(lambda t: bd.project_to_se3(g.at[:3, 3].set(t))[:3, 3])(g[:3, 3])
    np.testing.assert_array_equal(translation, np.eye(3))


def test_gradient_through_a_stock_solver_at_a_rotation_free_motion():
    """A body that translates without turning keeps its rotation block exactly at 1 in the
    embedding; the gradient through the projected output is still finite and exact:
    $p(1) = v$, so $\\nabla_\\xi |p(1)|^2 = (0, 2v)$ (the angular rate leaves $p$ unchanged to
    first order: the world velocity $Rv_b$ is conserved)."""
    scene = bd.Scene(bd.RigidBody(2.0, np.zeros(3), np.diag(INERTIA)))
    xi = jnp.array([0.0, 0.0, 0.0, 1.0, 0.5, -0.25])

    def loss(xi, solver):
        traj = bd.simulate(scene, bd.State(jnp.eye(4), xi=xi), 1.0, solver=solver)
        return jnp.sum(traj.g[-1, :3, 3] ** 2)

    gradient = eqx.filter_jit(jax.grad(loss))  # one program each, not a jvp's and a transpose's
    for solver in (diffrax.Tsit5(), bd.RKMK87()):
        np.testing.assert_allclose(
            gradient(xi, solver), jnp.concatenate([jnp.zeros(3), 2 * xi[3:]]), atol=1e-12
        )


def test_simulate_skips_the_dense_only_stage_when_nothing_interpolates():
    """Saving at t0, t1 or the steps, the default RKMK87 steps evaluate 13 stages; saving
    between steps, densely, or stopping at an event, 14 (the dense output needs the 14th)."""
    scene = bd.Scene(bd.RigidBody(1.0, [0.0, 0.0, 0.0], np.diag(INERTIA)))
    never = diffrax.Event(lambda t, y, args, **kwargs: t > 10.0)

    def lengths(**kwargs):
        def run(xi):
            return bd.simulate(scene, bd.State(jnp.eye(4), xi=xi), 1.0, **kwargs).g

        return scan_lengths(run, jnp.ones(6))

    for kwargs in [{}, dict(saveat=diffrax.SaveAt(steps=True))]:
        assert 13 in lengths(**kwargs) and 14 not in lengths(**kwargs)
    for kwargs in [
        dict(saveat=diffrax.SaveAt(ts=jnp.linspace(0.0, 1.0, 3))),
        dict(saveat=diffrax.SaveAt(t1=True, dense=True)),
        dict(event=never),
    ]:
        assert 14 in lengths(**kwargs) and 13 not in lengths(**kwargs)


def test_a_horizon_or_tolerances_no_solve_can_meet_are_refused_inside_jit_too():
    """Outside `jax.jit` a time that is not finite raises `ValueError`; inside, where the
    numbers are traced, the same refusals and the tolerances' stop the compiled solve."""
    scene = bd.Scene(chain(2))
    d = scene.system.shape_dim
    xi = jnp.array([0.0, 1.0, 0.0, 0.0, 0.0, 0.0])
    state = bd.State(jnp.eye(4), jnp.zeros(d), xi, jnp.full(d, 0.3))
    with pytest.raises(ValueError, match="`t1` must be finite"):
        bd.simulate(scene, state, float("nan"))

    @eqx.filter_jit  # (under `jax.jit` the same errors arrive wrapped in XLA's ValueError)
    def final_pose(t1, rtol, atol):
        return bd.simulate(scene, state, t1, rtol=rtol, atol=atol, solver=bd.RKMK54()).g[-1]

    assert np.all(np.isfinite(final_pose(*jnp.array([1.0, 1e-8, 1e-8]))))
    for t1, rtol, atol, message in [
        (jnp.nan, 1e-8, 1e-8, "`t0` and `t1` must be finite"),
        (jnp.inf, 1e-8, 1e-8, "`t0` and `t1` must be finite"),
        (1.0, -1e-8, 1e-8, "non-negative"),
        (1.0, 1e-30, 1e-30, "below float64's rounding error"),
    ]:
        with pytest.raises(eqx.EquinoxRuntimeError, match=message):
            jax.block_until_ready(final_pose(*jnp.array([t1, rtol, atol])))


def test_running_out_of_steps_names_the_stiffest_mode_and_what_to_do():
    """A floating chain on stiff joint springs: the message gives the fastest mode's rate,
    which is the small oscillations' $\\omega$ at zero momentum, $\\omega^2$ the largest
    eigenvalue of $J^{-1}K$ with $J$ the reduced shape metric."""
    system = chain(3)
    d, k = system.shape_dim, 1e6
    scene = bd.Scene(system, (bd.ShapeSpring(k),))
    state = bd.State(jnp.eye(4), jnp.full(d, 1e-6), jnp.zeros(6), jnp.zeros(d))
    metric = bd.shape_metric(system, jnp.zeros(d))
    omega = float(jnp.sqrt(jnp.max(jnp.linalg.eigvalsh(k * jnp.linalg.inv(metric)))))
    with pytest.raises(eqx.EquinoxRuntimeError, match="maximum number of solver steps") as info:
        bd.simulate(scene, state, 1.0, max_steps=50)
    message = str(info.value)
    reported = float(re.search(r"\|λ\| = ([0-9.e+]+)/s", message).group(1))
    assert abs(reported - omega) <= 1e-3 * omega, (reported, omega)
    assert f"period {2 * np.pi / omega:.3g} s" in message
    assert "VariationalMidpoint" in message and "max_steps = 50" in message
