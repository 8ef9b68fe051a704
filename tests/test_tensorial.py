"""Tensorial Lagrange equations (seed 000, §3–§4; issue 58): scalars, unit vectors and rotation
tensors as coordinates, the equations (44) by autodiff, the RKMK methods that keep them on
their manifolds, and chains of Lagrange gyroscopes.

The independent references: bundledyn's `RigidBody` through `simulate` (the bundle's
equations (2.6)–(2.7), not (44)); Euler's equations in the body frame; the seed's closed
forms (47), (54) and (60) and the identity (48); the heavy symmetric top's nutation period
by the elliptic integral; the two formulations of a chain against each other; central
finite differences.
"""

import functools
import re

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import bundledyn as bd
from bundledyn import lie

RTOL = ATOL = 1e-12
GRAVITY = 9.81
AXIS = jnp.array([0.0, 0.0, 1.0])
UP = jnp.array([0.0, 0.0, 1.0])
REFERENCE = jnp.array([0.9, 0.3, 0.2]) / jnp.linalg.norm(jnp.array([0.9, 0.3, 0.2]))


def _close(a, b, tol, what):
    error = float(np.max(np.abs(np.asarray(a) - np.asarray(b))))
    assert error <= tol, f"{what}: error {error:.3e} > {tol:.0e}"


def _empty(dtype=float):
    return jnp.zeros(0, dtype), jnp.zeros((0, 3), dtype), jnp.zeros((0, 3, 3), dtype)


def _rotations_only(Z, omega):
    scalars, vectors, _ = _empty()
    return (
        bd.TensorCoordinates(scalars, vectors, Z),
        bd.TensorVelocities(scalars, vectors, omega),
    )


@eqx.filter_jit
def _rollout(term, y0, ts):
    """The solution at `ts` by `TensorialRKMK87`, stepping onto each of `ts`."""
    return diffrax.diffeqsolve(
        term,
        bd.TensorialRKMK87(),
        ts[0],
        ts[-1],
        None,
        y0,
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=diffrax.PIDController(rtol=RTOL, atol=ATOL, step_ts=ts),
        max_steps=100_000,
    ).ys


def _orthogonality_error(Z):
    Z = np.asarray(Z)
    return np.max(np.abs(np.swapaxes(Z, -1, -2) @ Z - np.eye(3)))


# --- A free rigid body in (γ, c, Z) (seed 000, (46)–(47), (54)) -------------------------------

MASS = 2.0
INERTIA = jnp.array([[0.3, 0.01, 0.0], [0.01, 0.5, 0.02], [0.0, 0.02, 0.7]])
FALL = jnp.array([0.0, -3.0, -9.0])


@functools.cache
def _free_body():
    """T = ½m(γ̇² + γ²ċ²) + ½ω·J_cω (46), J_c = ZJZᵀ, ω = (ŻZᵀ)^∨; Π = -m f·γc."""

    def T(X, Xdot, t):
        gamma, gamma_rate = X.scalars[0], Xdot.scalars[0]
        c_rate = Xdot.unit_vectors[0]
        Z, Z_rate = X.rotations[0], Xdot.rotations[0]
        omega = lie.so3_vee(Z_rate @ Z.T)
        translation = gamma_rate**2 + gamma**2 * c_rate @ c_rate
        return 0.5 * MASS * translation + 0.5 * omega @ (Z @ INERTIA @ Z.T) @ omega

    return bd.TensorialSystem(T, Pi=lambda X, t: -MASS * FALL @ (X.scalars[0] * X.unit_vectors[0]))


def _free_body_state(centre, velocity, R, body_rates):
    gamma = jnp.linalg.norm(centre)
    c = centre / gamma
    gamma_rate = c @ velocity
    c_rate = (velocity - gamma_rate * c) / gamma
    X = bd.TensorCoordinates(gamma[None], c[None], R[None])
    V = bd.TensorVelocities(gamma_rate[None], jnp.cross(c, c_rate)[None], (R @ body_rates)[None])
    return X, V


def test_the_free_body_in_length_direction_and_rotation_moves_as_bundledyns_rigid_body():
    """Falling and tumbling for 1 s: the centre γc and the rotation Z equal those of
    `bd.RigidBody` through `simulate` to 1e-10, while |c| = 1 and ZᵀZ = 1 hold to rounding."""
    centre, velocity = jnp.array([1.0, 2.0, 3.0]), jnp.array([0.5, -1.0, 2.0])
    rotation, body_rates = jnp.array([0.2, 0.1, -0.3]), jnp.array([1.0, -2.0, 0.5])

    @jax.jit  # the two starts in one program, not one per primitive
    def starts(centre, velocity, rotation, body_rates):
        R0 = lie.so3_exp(rotation)
        pose = lie.se3_from_rotation_translation(R0, centre)
        twist = jnp.concatenate([body_rates, R0.T @ velocity])
        return _free_body_state(centre, velocity, R0, body_rates), (pose, twist)

    ts = jnp.linspace(0.0, 1.0, 5)
    y0, (pose, twist) = starts(centre, velocity, rotation, body_rates)
    X, _ = _rollout(bd.TensorialTerm(_free_body()), y0, ts)
    state = bd.State(pose, xi=twist)
    scene = bd.Scene(
        bd.RigidBody(MASS, jnp.zeros(3), INERTIA), (bd.Gravity(jnp.linalg.norm(FALL), FALL),)
    )
    traj = bd.simulate(scene, state, 1.0, rtol=1e-13, atol=1e-13, saveat=diffrax.SaveAt(ts=ts))
    X, g = jax.tree.map(np.asarray, X), np.asarray(traj.g)  # compared in numpy
    _close(X.scalars * X.unit_vectors[:, 0], g[:, :3, 3], 1e-10, "centre")
    _close(X.rotations[:, 0], g[:, :3, :3], 1e-10, "rotation")
    _close(np.linalg.norm(X.unit_vectors, axis=-1), 1.0, 1e-14, "|c|")
    _close(_orthogonality_error(X.rotations), 0.0, 1e-14, "ZᵀZ")


def test_the_free_bodys_equations_are_the_seeds_47_and_54():
    """On random states and rates, (44) by autodiff equals the seed's (47):
    m(γ̈ - γċ²) - c·f and γc × [m(2γ̇ċ + γc̈) - f], and (54): d/dt(J_cω) with no moment,
    to 1e-12 (relative to the terms)."""
    system = _free_body()
    rng = np.random.default_rng(3)

    @jax.jit  # one program for the four draws, not one per primitive
    def both(centre, velocity, rotation, rates, A):
        X, V = _free_body_state(centre, velocity, lie.so3_exp(rotation), rates)
        A = bd.TensorVelocities(*A)
        ours = bd.tensorial_equations(system, X, V, A, 0.0)
        Xdot, Xddot = bd.rates_of(X, V), bd.accelerations_of(X, V, A)
        gamma, c = X.scalars[0], X.unit_vectors[0]
        gamma_rate, c_rate = Xdot.scalars[0], Xdot.unit_vectors[0]
        c_acceleration = Xddot.unit_vectors[0]
        force = MASS * FALL
        radial = MASS * (A.scalars[0] - gamma * c_rate @ c_rate) - c @ force
        transverse = gamma * jnp.cross(
            c, MASS * (2 * gamma_rate * c_rate + gamma * c_acceleration) - force
        )
        Z, omega, alpha = X.rotations[0], V.rotations[0], A.rotations[0]
        J = Z @ INERTIA @ Z.T
        momentum_rate = J @ alpha + jnp.cross(omega, J @ omega)  # d/dt(J ω), J̇ = ω̃J - Jω̃
        closing = (A.unit_vectors[0] @ c) * c  # the equation that fixes Ω̇·c
        return (
            (ours.scalars[0], radial),
            (ours.unit_vectors[0] - closing, transverse),
            (ours.rotations[0], momentum_rate),
        )

    for _ in range(4):
        centre, velocity, rotation, rates = (rng.normal(size=3) for _ in range(4))
        A = tuple(rng.normal(size=shape) for shape in ((1,), (1, 3), (1, 3)))
        (ours_radial, radial), transverse, rotational = both(centre, velocity, rotation, rates, A)
        _close(ours_radial, radial, 1e-12 * (1 + abs(float(radial))), "(47) radial")
        _close(*transverse, 1e-12 * 10, "(47) transverse")
        _close(*rotational, 1e-12 * 10, "(54)")


def test_identity_48_the_projection_of_the_angular_velocitys_derivative_is_the_unit_tensor():
    """(48): Z̃ ∧₂ [1]∂ω/∂Ż = E₂: for any v, the projection of ∂(v·ω)/∂Ż, ω = (ŻZᵀ)^∨, is v."""
    rng = np.random.default_rng(5)

    @jax.jit  # one program for the three draws, not one per primitive
    def projection(rotation, v, omega):
        Z = lie.so3_exp(rotation)
        along = lambda Zdot: v @ lie.so3_vee(Zdot @ Z.T)
        gradient = jax.grad(along)(lie.so3_hat(omega) @ Z)
        X, V = _rotations_only(Z[None], omega[None])
        bracket = bd.TensorCoordinates(X.scalars, X.unit_vectors, gradient[None])
        return bd.projected(X, bracket, V).rotations[0]

    for _ in range(3):
        rotation, v, omega = (rng.normal(size=3) for _ in range(3))
        _close(projection(rotation, v, omega), v, 1e-14, "(48)")


def _random_rotation_state(rng):
    Z = lie.so3_exp(jnp.asarray(rng.normal(size=3)))
    return Z, jnp.asarray(rng.normal(size=3)), jnp.asarray(rng.normal(size=3))


def test_identity_50_the_bracket_of_the_angular_velocity_projects_to_its_cross_product():
    """(50) with (48) and (56): for g = v·ω, ω = (ŻZᵀ)^∨, the projected bracket
    Z̃ ∧₂ [d/dt ∂g/∂Ż - ∂g/∂Z] is -ω̃v = v × ω (∂ĝ/∂ω = v is constant), to 1e-14; along
    Ż = ω̃Z and Z̈ = (α̃ + ω̃ω̃)Z for any α."""
    rng = np.random.default_rng(19)

    @jax.jit  # one program for the three draws, not one per primitive
    def projection(rotation, omega, v, alpha):
        Z = lie.so3_exp(rotation)
        X, V = _rotations_only(Z[None], omega[None])
        _, A = _rotations_only(Z[None], alpha)
        system = bd.TensorialSystem(
            lambda X, Xdot, t: v @ lie.so3_vee(Xdot.rotations[0] @ X.rotations[0].T)
        )
        bracket = bd.lagrange_bracket(
            system, X, bd.rates_of(X, V), bd.accelerations_of(X, V, A), 0.0
        )
        return bd.projected(X, bracket, A).rotations[0], jnp.cross(v, omega)

    for _ in range(3):
        rotation, omega, v, alpha = (rng.normal(size=shape) for shape in (3, 3, 3, (1, 3)))
        _close(*projection(rotation, omega, v, alpha), 1e-14, "(50)")


def test_identity_53_the_inertias_turn_projects_to_minus_omega_cross_the_momentum():
    """(49) and (53): the slope of T = ½ω·J_cω in Z through J_c = ZJZᵀ alone (ω held),
    projected, is 2J̃_c ∧₂ ∂T/∂J_c = -ω × J_cω, to 1e-13."""
    rng = np.random.default_rng(23)
    for _ in range(3):
        Z, omega, _ = _random_rotation_state(rng)
        X, V = _rotations_only(Z[None], omega[None])
        energy = lambda Z, omega=omega: 0.5 * omega @ (Z @ INERTIA @ Z.T) @ omega
        slope = bd.TensorCoordinates(X.scalars, X.unit_vectors, jax.grad(energy)(Z)[None])
        J = Z @ INERTIA @ Z.T
        _close(bd.projected(X, slope, V).rotations[0], -jnp.cross(omega, J @ omega), 1e-13, "(53)")


# --- The heavy top ----------------------------------------------------------------------------

TOP_MASS, TOP_ARM = 1.0, 0.3
TOP_INERTIA = jnp.diag(jnp.array([0.02, 0.02, 0.01]))  # about the fixed point


@functools.cache
def _heavy_top():
    def T(X, Xdot, t):
        Z, Z_rate = X.rotations[0], Xdot.rotations[0]
        omega = lie.so3_vee(Z_rate @ Z.T)
        return 0.5 * omega @ (Z @ TOP_INERTIA @ Z.T) @ omega

    return bd.TensorialSystem(
        T, Pi=lambda X, t: TOP_MASS * GRAVITY * TOP_ARM * (X.rotations[0] @ AXIS) @ UP
    )


def _euler_field(t, y, args):
    """Euler's equations in the body frame: Ż = ZΩ̃, JΩ̇ = JΩ × Ω + l e₃ × (-mg Zᵀe_z)."""
    Z, rates = y
    torque = TOP_ARM * jnp.cross(AXIS, -TOP_MASS * GRAVITY * Z.T @ UP)
    J = TOP_INERTIA
    return Z @ lie.so3_hat(rates), jnp.linalg.solve(J, jnp.cross(J @ rates, rates) + torque)


def test_the_heavy_top_in_its_rotation_tensor_follows_eulers_equations():
    """An asymmetric start of a fast top: Z from (44) in Z equals Euler's equations in the
    body frame (integrated in the embedding at 1e-13) to 1e-9 over 2 s; Z stays orthogonal
    to rounding and the energy is kept to 1e-10."""
    Z0, rates = lie.so3_exp(jnp.array([0.4, 0.1, 0.0])), jnp.array([0.3, -0.2, 40.0])
    ts = jnp.linspace(0.0, 2.0, 5)
    system = _heavy_top()
    X, V = _rollout(bd.TensorialTerm(system), _rotations_only(Z0[None], (Z0 @ rates)[None]), ts)
    reference = diffrax.diffeqsolve(
        diffrax.ODETerm(_euler_field),
        diffrax.Dopri8(),
        0.0,
        2.0,
        None,
        (Z0, rates),
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=diffrax.PIDController(rtol=1e-13, atol=1e-13),
        max_steps=100_000,
    ).ys[0]
    _close(X.rotations[:, 0], reference, 1e-9, "Z")
    _close(_orthogonality_error(X.rotations), 0.0, 1e-14, "ZᵀZ")
    energy = np.asarray(jax.jit(jax.vmap(system.energy))(X, V, ts))
    _close(energy - energy[0], 0.0, 1e-10, "energy")


@functools.cache
def _heavy_top_in_the_vector_parameter():
    """The same top in Gibbs's vector parameter c = tan(χ/2) n (three scalars): R(c) and
    ω(c, ċ) from `lie` (the seed's (30)-(35))."""

    def T(X, Xdot, t):
        R = lie.rotation_from_vector_parameter(X.scalars)
        omega = lie.angular_velocity_from_vector_parameter(X.scalars, Xdot.scalars)
        return 0.5 * omega @ (R @ TOP_INERTIA @ R.T) @ omega

    def Pi(X, t):
        R = lie.rotation_from_vector_parameter(X.scalars)
        return TOP_MASS * GRAVITY * TOP_ARM * (R @ AXIS) @ UP

    return bd.TensorialSystem(T, Pi=Pi)


def test_gravity_as_a_force_at_the_centre_is_the_potentials_force():
    """Q = [1]∂r/∂Z · f for the weight f = -mg e_z at the centre r = l Ze₃
    (`generalized_forces_at_points`) gives the top the same equations (44) as its potential
    Π = mgl (Ze₃)·e_z, on random states, to 1e-13."""

    def weight(X, Xdot, t):
        centre = lambda X: TOP_ARM * (X.rotations @ AXIS)
        force = -TOP_MASS * GRAVITY * UP[None]
        return bd.generalized_forces_at_points(centre, X, force)

    by_force = bd.TensorialSystem(_heavy_top().T, Q=weight)
    by_potential = _heavy_top()
    rng = np.random.default_rng(17)

    @jax.jit  # one program for the three draws, not one per primitive
    def both(rotation, omega):
        X, V = _rotations_only(lie.so3_exp(rotation), omega)
        return (
            bd.tensorial_accelerations(by_force, X, V, 0.0).rotations,
            bd.tensorial_accelerations(by_potential, X, V, 0.0).rotations,
        )

    for _ in range(3):
        _close(*both(rng.normal(size=(1, 3)), rng.normal(size=(1, 3))), 1e-13 * 100, "ω̇")


def test_the_top_in_the_vector_parameter_agrees_until_its_singularity_and_then_says_so():
    """The fast top written in Gibbs's vector parameter equals it in its rotation tensor to
    1e-9 while the rotation angle stays below π (0.04 s); continued, the rotation passes
    through a turn by π, where c is infinite: the integration raises, naming the
    parametrization, where the rotation tensor's runs on (its |ZᵀZ - 1| still rounding)."""
    Z0, rates = lie.so3_exp(jnp.array([0.4, 0.1, 0.0])), jnp.array([0.3, -0.2, 40.0])
    omega0 = Z0 @ rates

    @jax.jit  # one program, not one per primitive
    def gibbs_start(Z0, omega0):
        c0 = lie.vector_parameter_from_rotation(Z0)
        along = jax.jacfwd(lie.angular_velocity_from_vector_parameter, argnums=1)
        _, vectors, rotations = _empty()
        return (
            bd.TensorCoordinates(c0, vectors, rotations),
            bd.TensorVelocities(
                jnp.linalg.solve(along(c0, jnp.zeros(3)), omega0), vectors, jnp.zeros((0, 3))
            ),
        )

    @jax.jit
    def angles_and_rotations(Z, c):
        angles = jnp.linalg.norm(jax.vmap(lie.so3_log)(Z), axis=-1)
        return angles, jax.vmap(lie.rotation_from_vector_parameter)(c)

    gibbs = gibbs_start(Z0, omega0)
    # Five saves in each run, as in the test above: the top's runs share one compiled
    # rollout, the vector parameter's theirs.
    short = jnp.linspace(0.0, 0.04, 5)
    X, _ = _rollout(bd.TensorialTerm(_heavy_top_in_the_vector_parameter()), gibbs, short)
    Z, _ = _rollout(bd.TensorialTerm(_heavy_top()), _rotations_only(Z0[None], omega0[None]), short)
    angles, by_vector_parameter = angles_and_rotations(Z.rotations[:, 0], X.scalars)
    assert float(np.max(angles)) < np.pi - 0.5
    _close(by_vector_parameter, Z.rotations[:, 0], 1e-9, "R")

    long = jnp.linspace(0.0, 0.3, 5)
    Z, _ = _rollout(bd.TensorialTerm(_heavy_top()), _rotations_only(Z0[None], omega0[None]), long)
    _close(_orthogonality_error(Z.rotations), 0.0, 1e-14, "ZᵀZ")
    with pytest.raises(Exception, match=re.escape("a vector parameter near a rotation by pi")):
        jax.block_until_ready(
            _rollout(bd.TensorialTerm(_heavy_top_in_the_vector_parameter()), gibbs, long)
        )


# --- Chains of Lagrange gyroscopes ----------------------------------------------------------


def _chain(n):
    return bd.LagrangeGyroscopeChain(
        masses=[1.0, 0.8, 0.6][:n],
        lengths=[0.4, 0.35, 0.3][:n],
        centres=[0.2, 0.18, 0.15][:n],
        transverse_inertias=[0.01, 0.008, 0.006][:n],
        axial_inertias=[0.006, 0.005, 0.004][:n],
    )


def _spinning_start(n):
    """Tilted bodies spinning fast about their axes, in the rotation tensors."""
    tilts = jnp.array([[0.3, 0.2, 0.0], [0.5, -0.1, 0.2], [0.2, 0.4, 0.1]])[:n]
    body_rates = jnp.array([[0.5, 0.2, 30.0], [0.1, -0.3, 25.0], [0.0, 0.2, -20.0]])[:n]
    Z = lie.so3_exp(tilts)
    return _rotations_only(Z, jnp.einsum("kij,kj->ki", Z, body_rates))


def test_the_chains_equations_by_autodiff_are_the_seeds_closed_form_60():
    """On random states and rates of three gyroscopes, (44) from T and Π by autodiff equals
    (60), assembled from the augmented bodies' inertias and the seed's b_k, g_kj, to 1e-12."""
    chain = _chain(3)
    system = chain.in_rotations()
    rng = np.random.default_rng(11)

    @jax.jit  # one program for the four draws, not one per primitive
    def both(rotations, omega, alpha):
        X, V = _rotations_only(lie.so3_exp(rotations), omega)
        _, A = _rotations_only(X.rotations, alpha)
        closed = chain.closed_form_equations(X, V, A)
        return bd.tensorial_equations(system, X, V, A, 0.0).rotations, closed

    for _ in range(4):
        ours, closed = both(*(rng.normal(size=(3, 3)) for _ in range(3)))
        _close(ours, closed, 1e-12 * float(np.max(np.abs(closed))), "(60)")


def test_three_gyroscopes_in_rotations_and_in_axes_move_alike():
    """The seed's first and second formulations of a chain of three gyroscopes, integrated
    separately for 1 s: the axes agree to 1e-8, each formulation keeps its energy to 1e-9,
    the vertical angular momentum about the pivot is kept to 1e-9 (the horizontal changes),
    and the axes stay unit and the rotations orthogonal to rounding."""
    chain = _chain(3)
    ts = jnp.linspace(0.0, 1.0, 5)
    X0, V0 = _spinning_start(3)
    in_rotations = _rollout(bd.TensorialTerm(chain.in_rotations()), (X0, V0), ts)
    in_axes = _rollout(
        bd.TensorialTerm(chain.in_axes(REFERENCE)), chain.axes_state(X0, V0, REFERENCE), ts
    )

    @jax.jit  # the diagnostics in one program, not one per primitive
    def diagnostics(in_rotations, in_axes):
        axes = in_rotations[0].rotations @ AXIS
        energies = [
            jax.vmap(system.energy)(X, V, ts)
            for system, (X, V) in (
                (chain.in_rotations(), in_rotations),
                (chain.in_axes(REFERENCE), in_axes),
            )
        ]
        omega = in_rotations[1].rotations
        momentum = jax.vmap(chain.angular_momentum)(axes, jnp.cross(omega, axes), omega)
        return axes, energies, momentum, jnp.linalg.norm(in_axes[0].unit_vectors, axis=-1)

    axes, energies, momentum, norms = diagnostics(in_rotations, in_axes)
    axes, momentum = np.asarray(axes), np.asarray(momentum)
    _close(axes, in_axes[0].unit_vectors, 1e-8, "axes")
    assert float(np.max(np.abs(axes[-1] - axes[0]))) > 0.5  # the chain does move
    for energy in energies:
        energy = np.asarray(energy)
        _close(energy - energy[0], 0.0, 1e-9, "energy")
    _close(momentum[:, 2] - momentum[0, 2], 0.0, 1e-9, "vertical angular momentum")
    assert float(np.max(np.abs(momentum[:, :2] - momentum[:1, :2]))) > 1e-2  # gravity's moment
    _close(norms, 1.0, 1e-14, "|e|")
    _close(_orthogonality_error(in_rotations[0].rotations), 0.0, 1e-14, "ZᵀZ")


def _mujoco_start(model, joints):
    """A spinning, tilted start of the chain's MJCF: ball joints turned and spun about the
    bodies' axes, universal joints bent and turning."""
    qpos, qvel = np.zeros(model.nq), np.zeros(model.nv)
    tilts = [[0.3, 0.2, 0.0], [0.5, -0.1, 0.2], [0.2, 0.4, 0.1]]
    if joints == "ball":
        for k, tilt in enumerate(tilts):
            qpos[4 * k : 4 * k + 4] = lie.quaternion_from_rotation(lie.so3_exp(jnp.array(tilt)))
        qvel[:] = [0.5, 0.2, 30.0, 0.1, -0.3, -5.0, 0.0, 0.2, -45.0]
    else:
        qpos[:4] = lie.quaternion_from_rotation(lie.so3_exp(jnp.array(tilts[0])))
        qpos[4:] = [0.4, -0.3, 0.2, 0.5]
        qvel[:] = [0.5, 0.2, 30.0, 1.0, -2.0, 0.5, 1.5]
    return qpos, qvel


def _tensor_state_of(data, joints):
    """(X, V) read off MuJoCo's body frames and world angular velocities (`cvel`)."""
    Z = jnp.asarray(data.xmat[2:].reshape(-1, 3, 3))
    omega = jnp.asarray(data.cvel[2:, :3])
    if joints == "ball":
        return _rotations_only(Z, omega)
    return _chain(3).universal_joint_state(Z, omega)


@pytest.mark.parametrize("joints", ["ball", "universal"])
def test_the_chain_moves_as_its_multibody_and_as_mujoco(joints):
    """One model, three derivations: the chain's MJCF (`to_mjcf`) run by MuJoCo (RK4, dt
    1e-4) and imported as a `Multibody` on a fixed base run by `simulate`, against (44) in
    the rotation tensors (ball joints, the seed's (59)–(60)) or in Z₁ and the axes
    (universal joints, (61)–(62)). At the start the energies equal MuJoCo's to 1e-12 (and
    the universal joints' bases its body frames to 1e-15); after 0.5 s, while the bodies
    turn by more than 1 rad, the Multibody's rotations equal (44)'s to 1e-10 and MuJoCo's
    to 1e-7 (its fixed-step RK4: measured 4.9e-9 and 2.0e-9)."""
    mujoco = pytest.importorskip("mujoco")
    chain, duration = _chain(3), 0.5
    xml = chain.to_mjcf(joints)
    model = mujoco.MjModel.from_xml_string(xml)
    model.opt.integrator, model.opt.timestep = mujoco.mjtIntegrator.mjINT_RK4, 1e-4
    model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    data = mujoco.MjData(model)
    qpos, qvel = _mujoco_start(model, joints)
    data.qpos[:], data.qvel[:] = qpos, qvel
    mujoco.mj_forward(model, data)
    system = chain.in_rotations() if joints == "ball" else chain.in_universal_joints()
    rotations = (lambda X: X.rotations) if joints == "ball" else chain.universal_joint_rotations
    # The start and its bases eagerly, as the check to 1e-15 was measured (compiled, XLA's
    # fusion moves them by an ulp or two); the energy compiled.
    X0, V0 = _tensor_state_of(data, joints)
    bases = rotations(X0)
    energy = jax.jit(lambda X, V: system.energy(X, V, 0.0))(X0, V0)
    _close(bases, data.xmat[2:].reshape(3, 3, 3), 1e-15, "bases")
    _close(energy, np.sum(data.energy), 1e-12, "energy")
    for _ in range(round(duration / model.opt.timestep)):
        mujoco.mj_step(model, data)
    by_mujoco = data.xmat[2:].reshape(3, 3, 3)

    X, _ = _rollout(bd.TensorialTerm(system), (X0, V0), jnp.array([0.0, duration]))
    tree = bd.Multibody.from_mjcf(xml)
    start = bd.state_from_mujoco(tree, qpos, qvel, free_root=False)
    scene = bd.Scene(tree, (bd.Gravity(float(chain.gravity)),), base=bd.PrescribedBase.fixed())
    traj = bd.simulate(scene, start, duration, rtol=RTOL, atol=ATOL)

    @jax.jit  # one program, not one per primitive
    def final_rotations(X, q):
        return rotations(jax.tree.map(lambda x: x[-1], X)), tree.body_poses(q)[1:, :3, :3]

    by_tensors, by_tree = (np.asarray(R) for R in final_rotations(X, traj.q[-1]))
    assert float(np.max(np.abs(by_tensors - np.asarray(bases)))) > 1.0
    _close(by_tree, by_tensors, 1e-10, "Multibody - (44)")
    _close(by_mujoco, by_tensors, 1e-7, "MuJoCo - (44)")


def test_the_universal_joint_chains_equations_are_the_seeds_61_and_62():
    """On random states and rates of three bodies on universal joints (axes kept off their
    joints' first axes), (44) by autodiff equals (62) term by term, to 1e-12: the equation of
    Z₁ as it stands, those of the relative axes as (62)'s in the parent's basis (the seed's
    relative vectors). And the bodies' angular velocities from the differentiated bases are
    (61)'s sum ω₁ + Σ A_j ė_j (ė_j relative), to 1e-14."""
    chain = _chain(3)
    system = chain.in_universal_joints()
    rng = np.random.default_rng(13)

    @jax.jit  # one program for the four draws, not one per primitive
    def compared(axes, rotation, V, A):
        axes = axes / jnp.linalg.norm(axes, axis=-1, keepdims=True)
        X = bd.TensorCoordinates(jnp.zeros(0), axes, lie.so3_exp(rotation))
        V = bd.TensorVelocities(jnp.zeros(0), *V)
        A = bd.TensorVelocities(jnp.zeros(0), *A)
        ours = bd.tensorial_equations(system, X, V, A, 0.0)
        first, rest = chain.closed_form_universal_equations(X, V, A)
        Z = chain.universal_joint_rotations(X)
        in_parents = jnp.einsum("kji,kj->ki", Z[:-1], rest)
        closing = jnp.sum(A.unit_vectors * axes, axis=-1, keepdims=True) * axes
        equations = ((ours.rotations[0], first), (ours.unit_vectors - closing, in_parents))

        rates = bd.rates_of(X, V)
        _, Zdot = jax.jvp(chain.universal_joint_rotations, (X,), (rates,))
        spin = Zdot @ jnp.swapaxes(Z, -1, -2)
        omega = lie.so3_vee(0.5 * (spin - jnp.swapaxes(spin, -1, -2)))
        absolute_axes, joint_axes, first_axes = Z[1:, :, 2], Z[:-1, :, 1], Z[1:, :, 0]
        relative_rates = jnp.einsum("kij,kj->ki", Z[:-1], rates.unit_vectors)
        factor = jnp.sum(joint_axes * absolute_axes, -1) / jnp.linalg.norm(
            jnp.cross(joint_axes, absolute_axes), axis=-1
        )
        turns = (
            factor[:, None]
            * jnp.sum(first_axes * relative_rates, -1, keepdims=True)
            * absolute_axes
        )
        turns = turns + jnp.cross(absolute_axes, relative_rates)  # A_j ė_j
        sums = V.rotations[:1] + jnp.cumsum(turns, axis=0)
        return equations, (omega[1:], sums)

    for _ in range(4):
        axes = rng.normal(size=(2, 3)) * [1.0, 0.3, 1.0] + [0.0, 0.0, 1.5]
        rotation = rng.normal(size=(1, 3))
        V, A = (tuple(rng.normal(size=shape) for shape in ((2, 3), (1, 3))) for _ in range(2))
        ((ours_first, first), axes_equations), (omega, sums) = compared(axes, rotation, V, A)
        scale = float(np.max(np.abs(first)))
        _close(ours_first, first, 1e-12 * scale, "(62), Z₁")
        _close(*axes_equations, 1e-12 * scale, "(62), axes")
        _close(omega, sums, 1e-14 * float(np.max(np.abs(sums))), "(61)")


def _agm_quarter_period(m):
    """K(m), the complete elliptic integral of the first kind, by the arithmetic-geometric mean."""
    a, b = 1.0, np.sqrt(1.0 - m)
    for _ in range(40):
        a, b = 0.5 * (a + b), np.sqrt(a * b)
    return np.pi / (2.0 * a)


def _nutation(chain, energy, spin, vertical_momentum):
    """The heavy symmetric top's nutation: u = cos θ obeys u̇² = f(u) = (1 - u²)(α - βu) - (b - au)²
    with α = 2E'/I₁, β = 2mgc/I₁, a = L₃/I₁, b = L_z/I₁, E' = E - ½C ω₃²; between the roots
    u₁ < u₂ < u₃ of f its period is 4K(k)/√(β(u₃ - u₁)), k² = (u₂ - u₁)/(u₃ - u₁).
    Returns the period and f's coefficients (lowest first)."""
    transverse, axial = (float(x[0]) for x in chain.pivot_inertias())
    weight = float(chain.masses[0] * chain.gravity * chain.centres[0])
    alpha = 2 * (energy - 0.5 * axial * spin**2) / transverse
    beta = 2 * weight / transverse
    a, b = axial * spin / transverse, vertical_momentum / transverse
    P = np.polynomial.polynomial
    f = P.polysub(P.polymul([1.0, 0.0, -1.0], [alpha, -beta]), P.polymul([b, -a], [b, -a]))
    u1, u2, u3 = np.sort(np.real(P.polyroots(f)))
    k2 = (u2 - u1) / (u3 - u1)
    return 4.0 * _agm_quarter_period(k2) / np.sqrt(beta * (u3 - u1)), f


def _top_at_a_turning_point():
    """The axis tilted by 0.5 rad, spinning at 40 rad/s, precessing at 2 rad/s: θ̇ = 0."""
    tilt = 0.5
    axis = jnp.array([np.sin(tilt), 0.0, np.cos(tilt)])
    omega = 40.0 * axis + 2.0 * UP
    Z = lie.rotation_from_unit_vector_and_angle(axis, 0.3, REFERENCE)
    return _rotations_only(Z[None], omega[None])


@pytest.mark.parametrize("formulation", ["rotations", "axes"])
def test_the_heavy_symmetric_top_nutates_with_the_elliptic_integrals_period(formulation):
    """A chain of one gyroscope, in either formulation, started where θ̇ = 0: after half the
    closed-form period and after one and two, θ̇ = 0 again to 1e-9 s of the period
    (u̇/ü there), u alternates between the cubic's roots, and the spin ω·e₃ and the vertical
    angular momentum are kept to 1e-9."""
    chain = _chain(1)
    X0, V0 = _top_at_a_turning_point()
    system = chain.in_rotations() if formulation == "rotations" else chain.in_axes(REFERENCE)
    y0 = (X0, V0) if formulation == "rotations" else chain.axes_state(X0, V0, REFERENCE)
    e3, up = np.asarray(AXIS), np.asarray(UP)
    # The diagnostics in numpy and in compiled programs, not primitive by primitive.
    transverse, axial = (np.asarray(x) for x in chain.pivot_inertias())
    axis, omega = np.asarray(X0.rotations[0]) @ e3, np.asarray(V0.rotations[0])
    spin = float(omega @ axis)
    pivot_inertia = transverse[0] * np.eye(3) + (axial[0] - transverse[0]) * np.outer(axis, axis)
    vertical = float((pivot_inertia @ omega) @ up)
    energy = float(jax.jit(lambda X, V: system.energy(X, V, 0.0))(*y0))
    period, f = _nutation(chain, energy, spin, vertical)
    ts = jnp.array([0.0, 0.5, 1.0, 2.0]) * period
    X, V = jax.tree.map(np.asarray, _rollout(bd.TensorialTerm(system), y0, ts))
    if formulation == "rotations":
        axes, axis_omega, omegas = X.rotations[:, 0] @ e3, V.rotations[:, 0], V.rotations[:, 0]
    else:
        axes, axis_omega = X.unit_vectors[:, 0], V.unit_vectors[:, 0]
        omegas = jax.jit(
            jax.vmap(lie.angular_velocity_from_unit_vector_and_angle, (0, 0, 0, 0, None))
        )(axes, X.scalars[:, 0], np.cross(axis_omega, axes), V.scalars[:, 0], REFERENCE)
        omegas = np.asarray(omegas)
    u = axes @ up
    u_rate = np.cross(axis_omega, axes) @ up
    u_acceleration = 0.5 * np.polynomial.polynomial.polyval(u, np.polynomial.polynomial.polyder(f))
    _close(u_rate / u_acceleration, 0.0, 1e-9 * period, "the period's error, s")
    assert u[1] < u[0] - 0.3  # it did nutate, to the other root, and back
    _close(u[[2, 3]], u[0], 1e-9, "u after whole periods")
    spins = np.sum(omegas * axes, axis=-1)
    _close(spins, spin, 1e-9, "spin")
    moments = transverse[0] * omegas + (axial[0] - transverse[0]) * spins[:, None] * axes
    _close(moments @ up, vertical, 1e-9, "vertical angular momentum")


# --- Integrators: order, gradients, batches ----------------------------------------------------


@eqx.filter_jit
def _fixed_steps(system, y0, steps):
    return diffrax.diffeqsolve(
        bd.TensorialTerm(system),
        bd.TensorialRKMK4(),
        0.0,
        0.2,
        0.2 / steps,
        y0,
        max_steps=256,
    ).ys


def test_tensorial_rkmk4_converges_with_order_four():
    """The top's rotation after 0.2 s with 16, 32 and 64 steps of `TensorialRKMK4`, against
    `TensorialRKMK87` at 1e-12: the error falls by 2^p with p > 3.8 per halving."""
    chain = _chain(1)
    y0 = _top_at_a_turning_point()
    exact = _rollout(bd.TensorialTerm(chain.in_rotations()), y0, jnp.array([0.0, 0.2]))[0]
    # The step counts as data: one compiled solve for the three, and the gradient's below.
    errors = [
        float(
            np.max(
                np.abs(
                    np.asarray(_fixed_steps(chain.in_rotations(), y0, jnp.asarray(s))[0].rotations)[
                        -1
                    ]
                    - np.asarray(exact.rotations)[-1]
                )
            )
        )
        for s in (16.0, 32.0, 64.0)
    ]
    orders = np.log2(np.asarray(errors[:-1]) / np.asarray(errors[1:]))
    assert np.all(orders > 3.8), f"errors {errors}, orders {orders}"


def _final_axis_height(mass):
    chain = eqx.tree_at(lambda c: c.masses, _chain(1), jnp.reshape(mass, (1,)))
    X, _ = _fixed_steps(chain.in_rotations(), _top_at_a_turning_point(), jnp.asarray(40.0))
    return (X.rotations[-1, 0] @ AXIS) @ UP


def test_the_gradient_through_a_rollout_equals_central_differences():
    """d u(0.2 s)/d m through 40 steps of `TensorialRKMK4` (the autodiff of (44) and of the
    exponentials) equals central differences to 1e-7 relative."""
    mass = jnp.array(1.0)
    # Compiled whole, once: one program, not a linearised and a transposed one and their
    # ops, and it gives the differences' values too.
    value_and_grad = jax.jit(jax.value_and_grad(_final_axis_height))
    gradient = value_and_grad(mass)[1]
    h = 1e-5
    differences = (value_and_grad(mass + h)[0] - value_and_grad(mass - h)[0]) / (2 * h)
    assert abs(float(gradient)) > 1e-3
    _close(gradient / differences, 1.0, 1e-7, "gradient / differences")


def test_a_vmapped_batch_equals_the_single_rollouts():
    """Three tops of different masses, vmapped through one compiled rollout, equal the
    rollouts one at a time to rounding."""
    masses = jnp.array([0.8, 1.0, 1.3])
    batch = jax.vmap(_final_axis_height)(masses)
    single = jnp.stack([_final_axis_height(m) for m in masses])
    _close(batch, single, 1e-14, "batch")


# --- Refusals ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "build, message",
    [
        (lambda: bd.TensorialSystem(T=1.0), "T` must be a callable"),
        (lambda: bd.TensorialSystem(T=lambda X, Xd, t: 0.0, Pi=2.0), "Pi` must be a callable"),
        (lambda: bd.TensorialTerm(_chain(1)), "must be an AbstractTensorialSystem"),
        (lambda: bd.LagrangeGyroscopeChain([1.0], [0.4, 0.3], [0.2], [0.01], [0.01]), "one shape"),
        (lambda: bd.LagrangeGyroscopeChain([-1.0], [0.4], [0.2], [0.01], [0.01]), "positive"),
    ],
    ids=["T-not-callable", "Pi-not-callable", "term-of-a-chain", "shapes", "negative-mass"],
)
def test_bad_construction_is_refused(build, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        build()


def test_a_state_of_the_wrong_layout_is_refused_by_the_solver():
    with pytest.raises(ValueError, match=re.escape("step states `(X, V)`")):
        diffrax.diffeqsolve(
            bd.TensorialTerm(_heavy_top()),
            bd.TensorialRKMK54(),
            0.0,
            0.1,
            0.01,
            (jnp.eye(3), jnp.zeros(3)),
        )


def test_a_kinetic_energy_blind_to_a_coordinate_raises():
    """T that does not depend on a scalar coordinate's rate leaves (44) singular: the rates
    raise instead of coming out as NaN or noise."""
    system = bd.TensorialSystem(lambda X, Xdot, t: 0.5 * jnp.sum(Xdot.scalars[:1] ** 2))
    scalars = jnp.zeros(2)
    _, vectors, rotations = _empty()
    X = bd.TensorCoordinates(scalars, vectors, rotations)
    V = bd.TensorVelocities(scalars, vectors, jnp.zeros((0, 3)))
    with pytest.raises(Exception, match=re.escape("do not determine the accelerations to half")):
        jax.block_until_ready(eqx.filter_jit(bd.tensorial_accelerations)(system, X, V, 0.0))
