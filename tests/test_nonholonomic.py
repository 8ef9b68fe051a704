"""Nonholonomic systems (seed 001, §54–§60; issue 57): Maggi's and Appell's equations by
autodiff, the nonholonomic and holonomic terms, the diffrax term, the Chaplygin sleigh and
the rolling disc, each against an independent derivation.

The independent references: Appell's energy of accelerations of point masses placed in
space, ½ Σ m a·a with a by differentiating the positions twice (§60); the holonomic
system's Lagrange equations in reduced coordinates; the closed forms of the sleigh and the
disc derived by hand (their derivations are in the systems' docstrings); central finite
differences for gradients.
"""

import functools
import re
from collections.abc import Callable
from typing import NamedTuple

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import bundledyn as bd

N_STATES = 6
RTOL = ATOL = 1e-12


# --- Examples --------------------------------------------------------------------------------


def _sleigh():
    return bd.ChaplyginSleigh(mass=1.3, inertia=0.4, distance=0.35)


def _blade_row(a):
    """The sleigh's blade as a Pfaffian row (76): -sin θ ẋ + cos θ ẏ - a θ̇ = 0."""
    return lambda q, t: jnp.stack([jnp.stack([-jnp.sin(q[2]), jnp.cos(q[2]), -a + 0 * q[2]])])


def _sleigh_points(system, q):
    """The sleigh's mass as two points m/2 at C ± ρu, ρ² = I/m: the same mass, centre and
    moment of inertia as the body."""
    m, I = system.mass, system.inertia
    rho = jnp.sqrt(I / m)
    u = jnp.stack([jnp.cos(q[2]), jnp.sin(q[2])])
    return jnp.stack([m / 2, m / 2]), jnp.stack([q[:2] + rho * u, q[:2] - rho * u])


def _sleigh_samples(rng, n):
    # θ in (-1.2, 1.2) keeps the Pfaffian form's choice (ẋ, θ̇) away from cos θ = 0.
    q = np.column_stack([rng.normal(size=(n, 2)), rng.uniform(-1.2, 1.2, n)])
    return q, rng.normal(size=(n, 2)), rng.normal(size=(n, 2)), rng.uniform(0, 3, n)


def _sleigh_in_pfaffian_form():
    sleigh = _sleigh()
    return bd.NonholonomicSystem(
        T=sleigh.kinetic_energy,
        constraints=bd.PfaffianConstraints(_blade_row(sleigh.distance), independent=(0, 2)),
    ), sleigh


def _sleigh_on_a_slope():
    """The sleigh on a plane inclined along x: Π = m g sin β x."""
    sleigh = _sleigh()
    return bd.NonholonomicSystem(
        T=sleigh.kinetic_energy,
        constraints=sleigh.constraints,
        Pi=lambda q, t: sleigh.mass * 9.81 * np.sin(0.2) * q[0],
    ), sleigh


def _sleigh_on_a_belt():
    """The sleigh on a belt whose surface moves along x at u(y, t) = 0.4 cos 0.7t + 0.3y:
    the blade P = C - a u does not slide across the belt, (v_P - u(y_P, t) e_x)·n = 0, so
    q̇ = η e + η₀ with the sleigh's η and η₀ = (u(y_P, t), 0, 0): rheonomic constraints in
    parametric form, η₀ depending on q and t."""
    sleigh = _sleigh()

    def eta0(q, t):
        y_blade = q[1] - sleigh.distance * jnp.sin(q[2])
        return jnp.stack([0.4 * jnp.cos(0.7 * t) + 0.3 * y_blade, 0 * t, 0 * t])

    return bd.NonholonomicSystem(
        T=sleigh.kinetic_energy,
        constraints=bd.ParametricConstraints(
            eta=lambda q, t: sleigh.constraints.parametric_form(q, t)[0], eta0=eta0
        ),
    ), sleigh


def _disc():
    return bd.RollingDisc(mass=2.0, radius=0.5)  # a uniform disc


def _rotation_z(angle):
    c, s = jnp.cos(angle), jnp.sin(angle)
    return jnp.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rotation_y(angle):
    c, s = jnp.cos(angle), jnp.sin(angle)
    return jnp.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _disc_points(system, q):
    """A uniform disc as four points m/4 at distance R/√2 from the centre in its plane (body
    x–z, axle body y): axial moment mR²/2, diametral mR²/4, as the disc's."""
    m, R = system.mass, system.radius
    rho = R / jnp.sqrt(2.0)
    body = rho * jnp.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 0, 1.0], [0, 0, -1.0]])
    rotation = _rotation_z(q[2]) @ _rotation_y(q[3])
    centre = jnp.stack([q[0], q[1], R])
    return jnp.full(4, m / 4), centre[None, :] + body @ rotation.T


def _disc_samples(rng, n):
    return (
        rng.normal(size=(n, 4)),
        rng.normal(size=(n, 2)),
        rng.normal(size=(n, 2)),
        rng.uniform(0, 3, n),
    )


def _general_T(q, qdot, t):
    """A kinetic energy with everything (76)–(82) allow: q-dependent inertia, terms linear
    in q̇ and free of q̇, explicit time."""
    M = jnp.array(
        [
            [1.5 + 0.3 * jnp.sin(q[1]), 0.2 * jnp.cos(q[2]), 0.1],
            [0.2 * jnp.cos(q[2]), 2.0, 0.3 * jnp.sin(q[0])],
            [0.1, 0.3 * jnp.sin(q[0]), 1.2 + 0.2 * q[0] ** 2 / (1 + q[0] ** 2)],
        ]
    )
    w = 0.3 * jnp.stack([jnp.sin(t), q[0] * jnp.cos(t), q[1] * q[2]])
    return 0.5 * qdot @ M @ qdot + w @ qdot + 0.1 * q[1] ** 2 * jnp.cos(t)


def _rheonomic():
    """Nonholonomic, time-dependent constraints with b₀ ≠ 0, a potential and other forces."""
    return bd.NonholonomicSystem(
        T=_general_T,
        constraints=bd.PfaffianConstraints(
            lambda q, t: jnp.stack(
                [
                    jnp.stack(
                        [
                            0.4 * jnp.sin(q[2]) + 0.2 * jnp.sin(t),
                            -q[0] + 0.1 * t,
                            1.0 + 0.3 * jnp.cos(q[0]) ** 2,
                        ]
                    )
                ]
            ),
            independent=(0, 1),
            b0=lambda q, t: jnp.stack([0.5 * jnp.cos(t) * q[1]]),
        ),
        Pi=lambda q, t: 0.5 * (q[0] ** 2 + 2 * q[1] ** 2 + q[2] ** 2) * (1 + 0.2 * jnp.sin(t)),
        Q=lambda q, qdot, t: -0.1 * qdot + jnp.stack([0.05 * t, 0 * t, 0.02 * q[0]]),
    )


def _general_samples(rng, n):
    return (
        rng.normal(size=(n, 3)),
        rng.normal(size=(n, 2)),
        rng.normal(size=(n, 2)),
        rng.uniform(0, 3, n),
    )


GRAVITY = 9.81


def _sphere_radius(t):
    return 1.0 + 0.2 * jnp.sin(1.3 * t)


def _sphere():
    """A unit mass on a sphere of radius l(t) under gravity, the constraint |q|² = l(t)²
    given in Pfaffian form by its time derivative, q·q̇ - l l̇ = 0: integrable and
    rheonomic. The characteristics are (ẋ, ẏ); ż is solved for."""
    radius_rate = jax.grad(_sphere_radius)
    return bd.NonholonomicSystem(
        T=lambda q, qdot, t: 0.5 * qdot @ qdot,
        constraints=bd.PfaffianConstraints(
            lambda q, t: q[None, :],
            independent=(0, 1),
            b0=lambda q, t: -(_sphere_radius(t) * radius_rate(t))[None],
        ),
        Pi=lambda q, t: GRAVITY * q[2],
    )


def _point_itself(system, q):
    return jnp.ones(1), q[None, :]


def _sphere_samples(rng, n):
    # Off the sphere too (the constraint is integrable on every level set), away from z = 0.
    q = np.column_stack([rng.uniform(-0.5, 0.5, (n, 2)), rng.uniform(-1.5, -0.6, n)])
    return q, rng.normal(size=(n, 2)), rng.normal(size=(n, 2)), rng.uniform(0, 3, n)


class Example(NamedTuple):
    system: bd.AbstractNonholonomicSystem
    samples: Callable  # (rng, n) -> (q, e, edot, t)
    points: Callable | None  # (system whose mass it is, q) -> (masses, positions) or None
    mass_of: bd.AbstractNonholonomicSystem | None  # the system the points' masses come from
    scleronomic: bool
    integrable: bool
    steady: bool = False  # its characteristics are first integrals: ė = 0 on every state


@functools.cache
def example(name) -> Example:
    if name == "sleigh":
        sleigh = _sleigh()
        return Example(sleigh, _sleigh_samples, _sleigh_points, sleigh, True, False)
    if name == "sleigh_pfaffian":
        system, sleigh = _sleigh_in_pfaffian_form()
        return Example(system, _sleigh_samples, _sleigh_points, sleigh, True, False)
    if name == "sleigh_on_a_belt":
        system, sleigh = _sleigh_on_a_belt()
        return Example(system, _sleigh_samples, _sleigh_points, sleigh, False, False)
    if name == "rolling_disc":
        disc = _disc()
        return Example(disc, _disc_samples, _disc_points, disc, True, False, steady=True)
    if name == "rheonomic":
        return Example(_rheonomic(), _general_samples, None, None, False, False)
    if name == "sphere":
        return Example(_sphere(), _sphere_samples, _point_itself, None, False, True)
    raise KeyError(name)


EXAMPLES = (
    "sleigh",
    "sleigh_pfaffian",
    "sleigh_on_a_belt",
    "rolling_disc",
    "rheonomic",
    "sphere",
)
SCLERONOMIC = [n for n in EXAMPLES if example(n).scleronomic]


# --- The battery: every quantity on a batch of random states, one compilation per example --


def _point_kinematics(points, mass_of, system, q, e, edot, t):
    """Kinetic energy and energy of accelerations of the point masses, by differentiating their
    positions: v = dP/dt, a = d²P/dt² along q̇ = η e + η₀ (77), q̈ = its time derivative."""

    def velocities(q, e, t):
        eta, eta0 = system.constraints.parametric_form(q, t)
        return eta @ e + eta0

    qdot = velocities(q, e, t)
    _, qddot = jax.jvp(velocities, (q, e, t), (qdot, edot, jnp.ones_like(t)))

    def positions(q):
        return points(mass_of, q)[1]

    masses = points(mass_of, q)[0]
    v = jax.jvp(positions, (q,), (qdot,))[1]
    curvature = jax.jvp(lambda q: jax.jvp(positions, (q,), (qdot,))[1], (q,), (qdot,))[1]
    a = jax.jvp(positions, (q,), (qddot,))[1] + curvature
    return 0.5 * jnp.sum(masses * jnp.sum(v * v, -1)), 0.5 * jnp.sum(masses * jnp.sum(a * a, -1))


def _battery(system, points, mass_of, q, e, edot, t):
    c = system.constraints
    eta, eta0 = c.parametric_form(q, t)
    qdot = eta @ e + eta0
    qddot = bd.constrained_accelerations(c, q, e, edot, t)
    maggi = bd.maggi_accelerations(system, q, e, t)
    appell = bd.appell_accelerations(system, q, e, t)
    A = bd.nonholonomic_terms(system, q, e, t)
    covariants = bd.bilinear_covariants(c, q, t)
    phi = jnp.einsum("hba,b->ha", covariants, jnp.concatenate([jnp.ones(1), e]))[:, 1:]  # (87)
    momenta = jax.grad(system.kinetic_energy, argnums=1)(q, qdot, t)
    out = {
        "maggi": maggi,
        "appell": appell,
        "A": A,
        "A (93)": momenta @ phi,
        "A + Q (88)": A + bd.holonomic_terms(system, q, e, edot, t),
        "eta tau (88)": eta.T @ bd.lagrange_binomials(system, q, qdot, qddot, t),
        "Phi": bd.characteristic_forces(system, q, e, t),
        "Maggi residual at the motion": bd.maggi_equations(system, q, e, maggi, t),
        "covariants": covariants,
        "characteristics": bd.kinematic_characteristics(c, q, qdot, t),
        "S gradient": jax.grad(lambda d: bd.acceleration_energy(system, q, e, d, t))(edot),
        "T": system.kinetic_energy(q, qdot, t),
    }
    if isinstance(c, bd.PfaffianConstraints):
        out["Pfaffian residual"] = c.residual(q, qdot, t)
    if points is not None:
        mass_of = system if mass_of is None else mass_of
        out["points T"] = _point_kinematics(points, mass_of, system, q, e, edot, t)[0]
        out["points S gradient"] = jax.grad(
            lambda d: _point_kinematics(points, mass_of, system, q, e, d, t)[1]
        )(edot)
    return out


_battery_batch = eqx.filter_jit(eqx.filter_vmap(_battery, in_axes=(None, None, None, 0, 0, 0, 0)))


@functools.cache
def battery(name):
    ex = example(name)
    rng = np.random.default_rng(57)
    q, e, edot, t = (jnp.asarray(x) for x in ex.samples(rng, N_STATES))
    return (q, e, edot, t), _battery_batch(ex.system, ex.points, ex.mass_of, q, e, edot, t)


def _close(a, b, tol, what):
    a, b = np.asarray(a), np.asarray(b)
    scale = max(1.0, float(np.max(np.abs(b))))
    assert np.max(np.abs(a - b)) <= tol * scale, f"{what}: max difference {np.max(np.abs(a - b))}"


# --- (a) Maggi and Appell ---------------------------------------------------------------------


@pytest.mark.parametrize("name", EXAMPLES)
def test_maggi_and_appell_give_the_same_rates(name):
    """(82) and §60, assembled by different autodiff paths, solve to the same ė (1e-10), and
    the rates do solve (82). The rolling disc's rates are constant (its closed form)."""
    _, out = battery(name)
    _close(out["maggi"], out["appell"], 1e-10, "Maggi vs Appell")
    _close(out["Maggi residual at the motion"], 0.0, 1e-10, "residual of (82)")
    if example(name).steady:
        _close(out["maggi"], 0.0, 1e-13, "ė of a steady system")
    else:
        assert np.min(np.max(np.abs(out["maggi"]), axis=-1)) > 1e-3


@pytest.mark.parametrize("name", [n for n in EXAMPLES if example(n).points is not None])
def test_acceleration_energy_is_that_of_the_point_masses(name):
    """∂S/∂ė from T equals ∂/∂ė of ½ Σ m a·a for point masses with the same kinetic energy,
    their accelerations by differentiating their positions twice (§60, (95))."""
    _, out = battery(name)
    _close(out["points T"], out["T"], 1e-12, "the points' kinetic energy is the system's")
    _close(out["S gradient"], out["points S gradient"], 1e-10, "∂S/∂ė")


# --- The split (84)–(93) ----------------------------------------------------------------------


@pytest.mark.parametrize("name", EXAMPLES)
def test_nonholonomic_and_holonomic_terms_split_maggis_equations(name):
    """A_α (89) equals (93) with the bilinear covariants (84), (87); A_α + Q_α equals
    Σ η_hα τ_h for any ė (88), so with Maggi's residual at zero (tested above) it equals Φ_α
    on the motion (91); the covariants are skew (85)."""
    _, out = battery(name)
    _close(out["A"], out["A (93)"], 1e-12, "(89) vs (93)")
    _close(out["A + Q (88)"], out["eta tau (88)"], 1e-11, "(88)")
    covariants = np.asarray(out["covariants"])
    _close(covariants, -np.swapaxes(covariants, -1, -2), 0.0, "(85)")


@pytest.mark.parametrize("name", EXAMPLES)
def test_the_parametric_form_satisfies_the_constraints(name):
    """η e + η₀ satisfies the Pfaffian rows (76) for any e, and `kinematic_characteristics`
    inverts (77)."""
    (_, e, _, _), out = battery(name)
    _close(out["characteristics"], e, 1e-12, "e from q̇")
    if "Pfaffian residual" in out:
        _close(out["Pfaffian residual"], 0.0, 1e-13, "b q̇ + b₀")


def test_nonholonomic_terms_vanish_only_where_the_constraints_are_integrable():
    """Every A_α and every bilinear covariant vanishes for the integrable constraint (the
    sphere's, rheonomic, in Pfaffian form); the sleigh's do not (the test can fail)."""
    _, sphere = battery("sphere")
    assert example("sphere").integrable
    _close(sphere["A"], 0.0, 1e-13, "A for holonomic constraints")
    _close(sphere["covariants"], 0.0, 1e-13, "covariants for holonomic constraints")
    _, sleigh = battery("sleigh")
    assert np.min(np.max(np.abs(sleigh["A"]), axis=-1)) > 1e-2


@pytest.mark.parametrize("name", SCLERONOMIC)
def test_nonholonomic_terms_do_no_work_for_scleronomic_constraints(name):
    """Σ_α A_α e_α = 0 ((93)–(94), §59) for constraints that do not depend on time; only the
    last two indices α, β ≥ 1 of the covariants are nonzero."""
    (_, e, _, _), out = battery(name)
    power = np.sum(np.asarray(out["A"]) * np.asarray(e), axis=-1)
    _close(power, 0.0, 1e-13, "Σ A e")
    _close(np.asarray(out["covariants"])[:, :, 0, :], 0.0, 0.0, "time's covariants")


def test_nonholonomic_terms_work_for_rheonomic_constraints():
    """On the sheared, moving belt the constraints depend on time and Σ A_α e_α ≠ 0: the
    remark of §59 needs scleronomic constraints, and the test above could fail."""
    (_, e, _, _), out = battery("sleigh_on_a_belt")
    power = np.sum(np.asarray(out["A"]) * np.asarray(e), axis=-1)
    assert np.max(np.abs(power)) > 1e-2


def test_pfaffian_and_parametric_sleighs_move_alike():
    """The sleigh in Pfaffian form (characteristics (ẋ, θ̇)) and in parametric form ((v, ω))
    give the same accelerations q̈ at the same (q, q̇)."""
    (q, e, _, t), out = battery("sleigh")
    parametric, pfaffian = example("sleigh").system, example("sleigh_pfaffian").system

    @jax.jit
    @jax.vmap
    def accelerations(q, e, edot, t):
        qdot = bd.constrained_velocities(parametric.constraints, q, e, t)
        e_pfaffian = bd.kinematic_characteristics(pfaffian.constraints, q, qdot, t)
        edot_pfaffian = bd.maggi_accelerations(pfaffian, q, e_pfaffian, t)
        return (
            bd.constrained_accelerations(parametric.constraints, q, e, edot, t),
            bd.constrained_accelerations(pfaffian.constraints, q, e_pfaffian, edot_pfaffian, t),
            bd.constrained_velocities(pfaffian.constraints, q, e_pfaffian, t) - qdot,
        )

    qddot, qddot_pfaffian, velocity_error = accelerations(q, e, out["maggi"], t)
    _close(velocity_error, 0.0, 1e-13, "q̇")
    _close(qddot_pfaffian, qddot, 1e-11, "q̈")


# --- Rollouts ---------------------------------------------------------------------------------


@eqx.filter_jit
def _rollout(term, y0, ts):
    solution = diffrax.diffeqsolve(
        term,
        diffrax.Tsit5(),
        0.0,
        ts[-1],
        None,
        y0,
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=diffrax.PIDController(rtol=RTOL, atol=ATOL),
        max_steps=20_000,
    )
    return solution.ys


def _sleigh_closed_form(sleigh, theta0, omega0, t):
    """v = V tanh(kt), ω = ω₀ sech(kt), θ = θ₀ + (ω₀/k) arctan sinh(kt), V = |ω₀|√(J/m),
    k = a m V / J, J = I + m a², derived in the rest frame of the body (`ChaplyginSleigh`'s
    docstring: v̇ = a ω², J ω̇ = -m a v ω, energy conserved)."""
    m, I, a = float(sleigh.mass), float(sleigh.inertia), float(sleigh.distance)
    J = I + m * a**2
    V = abs(omega0) * np.sqrt(J / m)
    k = a * m * V / J
    return (
        V * np.tanh(k * t),
        omega0 / np.cosh(k * t),
        theta0 + omega0 / k * np.arctan(np.sinh(k * t)),
    )


def test_chaplygin_sleigh_follows_its_closed_form():
    """Started at v = 0, ω = ω₀ (vmapped over three starts in one jitted rollout), the
    sleigh's (v, ω, θ) equal the closed form to 1e-9 up to t = 4."""
    sleigh = example("sleigh").system
    ts = jnp.linspace(0.0, 4.0, 9)
    theta0 = jnp.array([0.0, 0.7, -2.0])
    omega0 = jnp.array([1.5, -2.0, 0.8])
    q0 = jnp.stack([jnp.zeros(3), jnp.ones(3), theta0], axis=1)
    e0 = jnp.stack([jnp.zeros(3), omega0], axis=1)
    term = bd.NonholonomicTerm(sleigh)
    q, e = eqx.filter_vmap(_rollout, in_axes=(None, 0, None))(term, (q0, e0), ts)
    for i in range(3):
        v, omega, theta = _sleigh_closed_form(sleigh, float(theta0[i]), float(omega0[i]), ts)
        _close(e[i, :, 0], v, 1e-9, "v")
        _close(e[i, :, 1], omega, 1e-9, "ω")
        _close(q[i, :, 2], theta, 1e-9, "θ")
    assert abs(float(e[0, -1, 0])) > 0.9 * abs(float(_sleigh_closed_form(sleigh, 0, 1.5, 4.0)[0]))


def test_rolling_disc_with_appells_equations_follows_its_closed_form():
    """Appell's equations in the term: the rates stay constant and the contact point runs on
    the circle of radius Rψ̇/φ̇, to 1e-9."""
    disc = example("rolling_disc").system
    ts = jnp.linspace(0.0, 3.0, 7)
    q0 = jnp.array([0.3, -0.2, 0.4, 0.0])
    heading_rate, spin_rate = 1.1, 2.5
    q, e = _rollout(
        bd.NonholonomicTerm(disc, bd.AppellEquations()),
        (q0, jnp.array([heading_rate, spin_rate])),
        ts,
    )
    t = np.asarray(ts)
    phi = 0.4 + heading_rate * t
    radius = float(disc.radius) * spin_rate / heading_rate
    _close(e, np.broadcast_to([heading_rate, spin_rate], e.shape), 1e-9, "rates")
    _close(q[:, 2], phi, 1e-9, "φ")
    _close(q[:, 3], spin_rate * t, 1e-9, "ψ")
    _close(q[:, 0], 0.3 + radius * (np.sin(phi) - np.sin(0.4)), 1e-9, "x")
    _close(q[:, 1], -0.2 - radius * (np.cos(phi) - np.cos(0.4)), 1e-9, "y")


def test_energy_is_conserved_on_a_slope():
    """Scleronomic constraints, a potential and no other forces: T + Π is conserved to the
    solver's tolerance while the sleigh turns, slides down and speeds up."""
    system, _ = _sleigh_on_a_slope()
    ts = jnp.linspace(0.0, 3.0, 7)
    q, e = _rollout(bd.NonholonomicTerm(system), (jnp.zeros(3), jnp.array([0.5, 2.0])), ts)
    qdot = jax.vmap(functools.partial(bd.constrained_velocities, system.constraints))(q, e, ts)
    energy = jax.vmap(functools.partial(bd.mechanical_energy, system))(q, qdot, ts)
    kinetic = jax.vmap(system.kinetic_energy)(q, qdot, ts)
    assert float(kinetic[-1] - kinetic[0]) > 1.0  # it does exchange energy
    _close(energy - energy[0], 0.0, 1e-9, "T + Π")


def _sphere_point(r, t):
    """The point of the sphere of radius l(t) below the equator with (x, y) = r."""
    return jnp.concatenate([r, -jnp.sqrt(_sphere_radius(t) ** 2 - r @ r)[None]])


def _reduced_lagrangian(r, rdot, t):
    qdot = jax.jvp(_sphere_point, (r, t), (rdot, jnp.ones_like(t)))[1]
    return 0.5 * qdot @ qdot - GRAVITY * _sphere_point(r, t)[2]


def _reduced_field(t, y, args):
    """Lagrange's equations in the reduced coordinates r = (x, y) of the holonomic system,
    M r̈ = ∂L/∂r - ∂²L/∂ṙ∂r ṙ - ∂²L/∂ṙ∂t (no constraints, no characteristics)."""
    r, rdot = y
    L = _reduced_lagrangian
    M = jax.hessian(L, argnums=1)(r, rdot, t)
    mixed_r, mixed_t = jax.jacfwd(jax.grad(L, argnums=1), argnums=(0, 2))(r, rdot, t)
    rhs = jax.grad(L, argnums=0)(r, rdot, t) - mixed_r @ rdot - mixed_t
    return rdot, jnp.linalg.solve(M, rhs)


def test_integrable_constraints_move_as_the_reduced_system():
    """The sphere of varying radius, its constraint in differentiated (Pfaffian) form, moves
    as the same system in reduced coordinates does under Lagrange's equations, to 1e-9."""
    system = example("sphere").system
    ts = jnp.linspace(0.0, 2.0, 5)
    r0, rdot0 = jnp.array([0.3, -0.2]), jnp.array([0.4, 0.9])
    q0 = _sphere_point(r0, jnp.zeros(()))
    q, e = _rollout(bd.NonholonomicTerm(system), (q0, rdot0), ts)
    r, rdot = _rollout(diffrax.ODETerm(_reduced_field), (r0, rdot0), ts)
    _close(q, jax.vmap(_sphere_point)(r, ts), 1e-9, "q")
    _close(e, rdot, 1e-9, "e = ṙ")
    assert float(jnp.max(jnp.abs(q[-1] - q0))) > 0.1


# --- Differentiation --------------------------------------------------------------------------


@eqx.filter_jit
def _final_state(sleigh, omega0):
    """The sleigh's state at t = 1 after 50 fixed Heun steps (fixed, so that central
    differences see the same discrete map as the gradient; a two-stage method, to keep the
    reverse pass's compilation short)."""
    solution = diffrax.diffeqsolve(
        bd.NonholonomicTerm(sleigh),
        diffrax.Heun(),
        0.0,
        1.0,
        0.02,
        (jnp.array([0.0, 0.0, 0.3]), jnp.stack([0.2 * omega0, omega0])),
        stepsize_controller=diffrax.ConstantStepSize(),
    )
    q, e = solution.ys
    return q[-1], e[-1]


def _loss(parameters):
    mass, distance, omega0 = parameters
    sleigh = bd.ChaplyginSleigh(mass=mass, inertia=0.4, distance=distance)
    q, e = _final_state(sleigh, omega0)
    return q[0] + 0.5 * q[1] - 0.3 * q[2] + e[0] * e[1]


def test_gradient_through_a_rollout_equals_central_differences():
    """jax.grad of a rollout with respect to the sleigh's mass, blade distance and initial
    turning rate equals central differences (step 1e-5) to 1e-7."""
    parameters = jnp.array([1.3, 0.35, 1.5])
    # One program: the gradient's gives the differences' values too (a program of the
    # value alone would compile the rollout again).
    value_and_grad = jax.jit(jax.value_and_grad(_loss))
    gradient = value_and_grad(parameters)[1]
    h = 1e-5
    for i in range(3):
        step = jnp.zeros(3).at[i].set(h)
        fd = (value_and_grad(parameters + step)[0] - value_and_grad(parameters - step)[0]) / (2 * h)
        assert abs(float(gradient[i] - fd)) <= 1e-7 * max(1.0, abs(float(fd))), (i, gradient, fd)
    assert np.all(np.abs(np.asarray(gradient)) > 1e-3)


# --- Singular points and construction ---------------------------------------------------------


def test_a_bad_choice_of_independent_velocities_is_located_and_raises():
    """The sleigh's blade solved for ẏ (independent (ẋ, θ̇)) breaks down at cos θ = 0 while
    the constraint itself keeps its rank: `smallest_singular_value` is 0 there, the rates
    raise inside jit and grad, and a state near it does not."""
    system = example("sleigh_pfaffian").system
    c = system.constraints
    singular = jnp.array([0.0, 0.0, np.pi / 2])
    assert float(c.smallest_singular_value(singular, 0.0)) < 1e-15
    assert float(c.constraint_singular_value(singular, 0.0)) > 1.0
    e = jnp.array([0.3, 0.5])
    rates = eqx.filter_jit(bd.maggi_accelerations)
    message = re.escape("The dependent velocities cannot be solved for here")
    with pytest.raises(Exception, match=message):
        jax.block_until_ready(rates(system, singular, e, 0.0))
    with pytest.raises(Exception, match=message):
        jax.block_until_ready(
            jax.grad(lambda q: jnp.sum(bd.maggi_accelerations(system, q, e, 0.0)))(singular)
        )
    near = singular.at[2].add(-1e-3)
    assert np.all(np.isfinite(np.asarray(rates(system, near, e, 0.0))))
    assert float(c.smallest_singular_value(near, 0.0)) == pytest.approx(1e-3, rel=1e-3)


def test_constraints_that_lose_rank_are_located_and_raise():
    """Two Pfaffian rows that become dependent at q₂ = 0: the constraints' singular value is
    0 there and the equations raise, naming rank loss."""
    constraints = bd.PfaffianConstraints(
        lambda q, t: jnp.stack([jnp.array([1.0, 0.0, 0.0]), jnp.stack([1.0, 0.0 * q[2], q[2]])]),
        independent=(1,),
    )
    system = bd.NonholonomicSystem(T=lambda q, qdot, t: 0.5 * qdot @ qdot, constraints=constraints)
    singular = jnp.array([0.2, 0.1, 0.0])
    assert float(constraints.constraint_singular_value(singular, 0.0)) < 1e-15
    assert float(constraints.constraint_singular_value(singular.at[2].set(0.5), 0.0)) > 0.1
    with pytest.raises(Exception, match=re.escape("lose rank here")):
        jax.block_until_ready(
            eqx.filter_jit(bd.maggi_accelerations)(system, singular, jnp.array([1.0]), 0.0)
        )


def test_parametric_constraints_with_dependent_columns_raise():
    """η(q) whose columns become parallel at q₀ = 0 is located and refused at run time."""
    constraints = bd.ParametricConstraints(
        lambda q, t: jnp.stack(
            [jnp.stack([1.0 + 0 * q[0], 1.0 + 0 * q[0]]), jnp.stack([0 * q[0], q[0]])]
        )
    )
    system = bd.NonholonomicSystem(T=lambda q, qdot, t: 0.5 * qdot @ qdot, constraints=constraints)
    singular = jnp.array([0.0, 0.3])
    assert float(constraints.smallest_singular_value(singular, 0.0)) < 1e-15
    with pytest.raises(Exception, match=re.escape("linearly dependent")):
        jax.block_until_ready(
            eqx.filter_jit(bd.appell_accelerations)(system, singular, jnp.array([1.0, 0.5]), 0.0)
        )


def _oblique_columns(q, t):
    """η = [diag(1, ε) R(θ)ᵀ; 0] with q = (ε, θ, ·): singular values 1 and ε, columns
    orthogonal at θ = 0 and far from it at θ = π/6 (ηᵀη = R diag(1, ε²) Rᵀ)."""
    c, s, zero = jnp.cos(q[1]), jnp.sin(q[1]), 0 * q[0]
    return jnp.stack([jnp.stack([c, s]), jnp.stack([-q[0] * s, q[0] * c]), jnp.stack([zero, zero])])


def _partition_of_size(q, t):
    """b = [ε I | I] with independent = (2, 3): σ_min(b_D) = ε, σ_max(b) = √(1 + ε²), and
    ‖b‖_F = √2 σ_max(b), so a Frobenius bound of the scale would refuse ε = 1.1e-3 too."""
    zero, one = 0 * q[0], 1 + 0 * q[0]
    return jnp.stack([jnp.stack([q[0], zero, one, zero]), jnp.stack([zero, q[0], zero, one])])


@pytest.mark.parametrize(
    "constraints, q, message",
    [
        (
            bd.ParametricConstraints(_oblique_columns, rank_tolerance=1e-3),
            lambda eps: jnp.array([eps, 0.0, 0.0]),
            "linearly dependent",
        ),
        (
            bd.ParametricConstraints(_oblique_columns, rank_tolerance=1e-3),
            lambda eps: jnp.array([eps, np.pi / 6, 0.0]),
            "linearly dependent",
        ),
        (
            bd.PfaffianConstraints(_partition_of_size, independent=(2, 3), rank_tolerance=1e-3),
            lambda eps: jnp.array([eps, 0.0, 0.0, 0.0]),
            "The dependent velocities cannot be solved for here",
        ),
    ],
    ids=["parametric-orthogonal", "parametric-oblique", "pfaffian-partition"],
)
def test_the_rank_tolerance_is_the_singular_value_ratio(constraints, q, message):
    """The checks refuse exactly where σ_min ≤ rank_tolerance σ_max, as documented: a ratio
    10% below the tolerance raises, 10% above does not, whether the cheap bound that spares
    the singular value decompositions settles the case (orthogonal columns) or leaves it to
    them (oblique columns, a block small against the whole)."""
    parametric_form = eqx.filter_jit(constraints.parametric_form)
    with pytest.raises(Exception, match=re.escape(message)):
        jax.block_until_ready(parametric_form(q(0.9e-3), 0.0))
    eta, _ = parametric_form(q(1.1e-3), 0.0)
    assert np.all(np.isfinite(np.asarray(eta)))


@pytest.mark.parametrize(
    "build, message",
    [
        (lambda: bd.PfaffianConstraints(lambda q, t: q, independent=(0, 0)), "none twice"),
        (lambda: bd.PfaffianConstraints(lambda q, t: q, independent=(-1,)), "non-negative"),
        (lambda: bd.PfaffianConstraints(np.eye(2), independent=(0,)), "must be a callable"),
        (lambda: bd.ParametricConstraints(lambda q, t: q, eta0=1.0), "eta0` must be a callable"),
        (lambda: bd.NonholonomicSystem(T=1.0, constraints=_sleigh().constraints), "T` must be"),
        (lambda: bd.NonholonomicSystem(T=_general_T, constraints=None), "constraints` must be"),
        (lambda: bd.ChaplyginSleigh(mass=-1.0, inertia=0.4, distance=0.3), "positive"),
        (lambda: bd.RollingDisc(mass=1.0, radius=0.0), "positive"),
        (lambda: bd.NonholonomicTerm(_sleigh(), equations="maggi"), "equations` must be"),
    ],
    ids=[
        "repeated-index",
        "negative-index",
        "b-not-callable",
        "eta0-not-callable",
        "T-not-callable",
        "no-constraints",
        "negative-mass",
        "zero-radius",
        "equations-as-a-string",
    ],
)
def test_bad_construction_is_refused(build, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        build()


def test_rows_of_the_wrong_shape_are_refused():
    """s rows must equal n - ν: one row for three coordinates with one independent is refused."""
    constraints = bd.PfaffianConstraints(lambda q, t: q[None, :], independent=(0,))
    with pytest.raises(ValueError, match=re.escape("must have shape (2, 3)")):
        constraints.parametric_form(jnp.ones(3), 0.0)
