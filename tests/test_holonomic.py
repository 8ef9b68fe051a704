"""Holonomic constraints f(q, t) = 0 beside kinematic ones (seed 001, §54; issue 57): carried
as Pfaffian rows, the configuration kept on them by coordinate partitioning, the residual
reported.

The independent references: a bead on a turning hoop against its equation of motion in the
hoop's angle, derived by hand; a knife edge on a heaving slope against the same system in
reduced coordinates (the constraint substituted into T and Π, no rows of it at all); the
Jacobi integral; central finite differences.
"""

import re

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import bundledyn as bd

RTOL = ATOL = 1e-12
GRAVITY = 9.81


def _close(a, b, tol, what):
    error = float(np.max(np.abs(np.asarray(a) - np.asarray(b))))
    assert error <= tol, f"{what}: error {error:.3e} > {tol:.0e}"


@eqx.filter_jit
def _rollout(term, y0, ts):
    return diffrax.diffeqsolve(
        term,
        diffrax.Tsit5(),
        ts[0],
        ts[-1],
        None,
        y0,
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=diffrax.PIDController(rtol=RTOL, atol=ATOL),
        max_steps=20_000,
    ).ys


# --- A bead on a hoop turning about the vertical ---------------------------------------------

HOOP_RADIUS = 0.5
HOOP_RATE = np.sqrt(2 * GRAVITY / HOOP_RADIUS)  # Ω² = 2g/R: the bead settles at 60°


class _Hoop(eqx.Module):
    """f(q, t) = (φ - Ωt, r² + z² - R²) for q = (r, φ, z), cylindrical coordinates of the bead."""

    radius: float
    rate: float

    def __call__(self, q, t):
        return jnp.stack([q[1] - self.rate * t, q[0] ** 2 + q[2] ** 2 - self.radius**2])


def _bead_on_a_hoop():
    """The bead of unit mass: T = ½(ṙ² + r²φ̇² + ż²), Π = g z; the hoop's rows solved for
    (φ̇, ż), the characteristic e = ṙ."""
    hoop = bd.HolonomicConstraints(_Hoop(HOOP_RADIUS, HOOP_RATE), dependent=(1, 2))
    return bd.NonholonomicSystem(
        T=lambda q, qdot, t: 0.5 * (qdot[0] ** 2 + (q[0] * qdot[1]) ** 2 + qdot[2] ** 2),
        constraints=bd.PfaffianConstraints(None, independent=(0,), holonomic=hoop),
        Pi=lambda q, t: GRAVITY * q[2],
    )


def _hoop_angle_field(t, y, args):
    """θ̈ = sin θ (Ω² cos θ - g/R), θ from the lowest point: Lagrange's equation of
    L = ½R²(θ̇² + Ω² sin²θ) + gR cos θ."""
    theta, rate = y
    return rate, jnp.sin(theta) * (HOOP_RATE**2 * jnp.cos(theta) - GRAVITY / HOOP_RADIUS)


def _bead_at(theta, t):
    return jnp.stack(
        [HOOP_RADIUS * jnp.sin(theta), HOOP_RATE * t, -HOOP_RADIUS * jnp.cos(theta)], axis=-1
    )


def test_a_bead_on_a_turning_hoop_follows_its_equation_in_the_hoops_angle():
    """Rheonomic holonomic constraints only: from θ = 45° at rest on the hoop, (r, φ, z)
    equal R sin θ, Ωt, -R cos θ with θ from the hand-derived equation, to 1e-9 over 3 s; the
    Jacobi integral h = T₂ - T₀ + Π is kept to 1e-9 while the energy changes; the integrated
    configuration stays on the hoop to 1e-9 and the one the field sees to 1e-12."""
    system = _bead_on_a_hoop()
    term = bd.NonholonomicTerm(system)
    ts = jnp.linspace(0.0, 3.0, 13)
    theta0 = jnp.pi / 4
    q, e = _rollout(term, (_bead_at(theta0, 0.0), jnp.zeros(1)), ts)
    theta, _ = _rollout(diffrax.ODETerm(_hoop_angle_field), (theta0, jnp.zeros(())), ts)

    @jax.jit  # the diagnostics in one program, not one per primitive
    def diagnostics(q, e, theta):
        qdot = jax.vmap(bd.constrained_velocities, in_axes=(None, 0, 0, 0))(
            system.constraints, q, e, ts
        )
        energy = jax.vmap(bd.mechanical_energy, in_axes=(None, 0, 0, 0))(system, q, qdot, ts)
        residual = jax.vmap(term.constraint_residual)(ts, (q, e))
        placed = jax.vmap(system.constraints.on_the_constraints)(q, ts)
        placed = jax.vmap(system.constraints.holonomic_residual)(placed, ts)
        return _bead_at(theta, ts), qdot, energy, residual, placed

    bead, qdot, energy, residual, placed = jax.tree.map(np.asarray, diagnostics(q, e, theta))
    q, theta = np.asarray(q), np.asarray(theta)
    _close(q, bead, 1e-9, "q")
    assert float(np.max(theta)) > np.pi / 3 + 0.2  # it swings past the 60° equilibrium

    kinetic = 0.5 * (qdot[:, 0] ** 2 + qdot[:, 2] ** 2)  # T₂: the velocity relative to the hoop
    transport = 0.5 * (q[:, 0] * HOOP_RATE) ** 2  # T₀
    jacobi = kinetic - transport + GRAVITY * q[:, 2]
    _close(jacobi - jacobi[0], 0.0, 1e-9, "Jacobi integral")
    assert float(np.max(energy) - np.min(energy)) > 0.1  # the hoop's drive does work

    _close(residual, 0.0, 1e-9, "integrated residual")
    _close(placed, 0.0, 1e-12, "placed")


def test_the_configuration_placed_on_the_constraints_has_the_implicit_functions_derivatives():
    """On the hoop z = -√(R² - r²), φ = Ωt whatever the dependent values started from: the
    Jacobian in (q, t) of `on_the_constraints` equals that closed form's to 1e-12."""
    constraints = _bead_on_a_hoop().constraints
    q, t = jnp.array([0.3, 0.2, -0.35]), jnp.array(0.4)

    def exact(q, t):
        return jnp.stack([q[0], HOOP_RATE * t, -jnp.sqrt(HOOP_RADIUS**2 - q[0] ** 2)])

    @jax.jit  # one program, not one per primitive
    def compared(q, t):
        placed = constraints.on_the_constraints
        return (
            (placed(q, t), exact(q, t)),
            *((jax.jacfwd(placed, n)(q, t), jax.jacfwd(exact, n)(q, t)) for n in (0, 1)),
            (jax.jacrev(placed)(q, t), jax.jacfwd(exact)(q, t)),
        )

    values, in_q, in_t, reverse = compared(q, t)
    _close(*values, 1e-14, "q")
    for argnums, (ours, expected) in enumerate((in_q, in_t)):
        _close(ours, expected, 1e-12, f"jacfwd in argument {argnums}")
    _close(*reverse, 1e-12, "jacrev")


# --- A knife edge on a heaving slope ---------------------------------------------------------

MASS, INERTIA = 1.3, 0.2


class _Slope(eqx.Module):
    """The plane z = x tan α + a sin ωt, heaving; its parameters are leaves to differentiate."""

    slope: jax.Array
    amplitude: jax.Array
    frequency: jax.Array

    def height(self, x, t):
        return x * jnp.tan(self.slope) + self.amplitude * jnp.sin(self.frequency * t)


def _slope(slope=0.3):
    return _Slope(jnp.asarray(slope), jnp.asarray(0.05), jnp.asarray(3.0))


def _blade(q, t):
    """The edge does not slide sideways: -sin θ ẋ + cos θ ẏ = 0, for θ = q[-1]."""
    theta = q[-1]
    zero = jnp.zeros_like(theta)
    row = [-jnp.sin(theta), jnp.cos(theta)] + [zero] * (q.shape[0] - 3) + [zero]
    return jnp.stack([jnp.stack(row)])


def _knife_edge(plane):
    """q = (x, y, z, θ): a point mass with a spin inertia, on the plane as a holonomic
    constraint z - h(x, t) = 0 solved for z, the blade row solved for ẏ; e = (ẋ, θ̇)."""
    on_the_plane = bd.HolonomicConstraints(
        lambda q, t: jnp.stack([q[2] - plane.height(q[0], t)]), dependent=(2,)
    )
    return bd.NonholonomicSystem(
        T=lambda q, qdot, t: 0.5 * MASS * (qdot[:3] @ qdot[:3]) + 0.5 * INERTIA * qdot[3] ** 2,
        constraints=bd.PfaffianConstraints(_blade, independent=(0, 3), holonomic=on_the_plane),
        Pi=lambda q, t: MASS * GRAVITY * q[2],
    )


def _knife_edge_reduced(plane):
    """The same system in p = (x, y, θ), z = h(x, t) substituted: ż = h_x ẋ + h_t."""

    def T(p, pdot, t):
        zdot = jax.jvp(plane.height, (p[0], t), (pdot[0], jnp.ones_like(t)))[1]
        return 0.5 * MASS * (pdot[0] ** 2 + pdot[1] ** 2 + zdot**2) + 0.5 * INERTIA * pdot[2] ** 2

    return bd.NonholonomicSystem(
        T=T,
        constraints=bd.PfaffianConstraints(_blade, independent=(0, 2)),
        Pi=lambda p, t: MASS * GRAVITY * plane.height(p[0], t),
    )


def _on_the_plane(plane, p, t):
    return jnp.stack([p[0], p[1], plane.height(p[0], t), p[2]])


def test_a_knife_edge_on_a_heaving_slope_moves_as_in_reduced_coordinates():
    """A nonholonomic row and a rheonomic holonomic constraint together: (x, y, z, θ) and
    e = (ẋ, θ̇) equal the reduced system's (x, y, h(x, t), θ) and (ẋ, θ̇) to 1e-9 over 3 s,
    while the edge turns and slides down the slope (θ within (0.3, 1.1), away from the
    blade row's singular cos θ = 0, where both forms lose their conditioning alike)."""
    plane = _slope()
    ts = jnp.linspace(0.0, 3.0, 7)
    p0, e0 = jnp.array([0.1, -0.2, 0.3]), jnp.array([0.4, 0.25])
    q, e = _rollout(
        bd.NonholonomicTerm(_knife_edge(plane)), (_on_the_plane(plane, p0, 0.0), e0), ts
    )
    p, e_reduced = _rollout(bd.NonholonomicTerm(_knife_edge_reduced(plane)), (p0, e0), ts)
    placed = jax.jit(jax.vmap(_on_the_plane, in_axes=(None, 0, 0)))(plane, p, ts)
    q = np.asarray(q)
    _close(q, placed, 1e-9, "q")
    _close(e, e_reduced, 1e-9, "e")
    assert float(np.min(q[:, 0] - q[0, 0])) < -0.3  # it does slide down
    assert float(np.abs(q[-1, 3] - q[0, 3])) > 0.7  # and turns


def test_maggi_and_appell_give_the_same_rates_with_holonomic_rows():
    """On 6 random states placed on the heaving slope, Maggi's (82) and Appell's (§60) ė
    agree to 1e-10, and equal the reduced system's to 1e-10."""
    plane = _slope()
    system, reduced = _knife_edge(plane), _knife_edge_reduced(plane)
    rng = np.random.default_rng(7)

    @jax.jit
    def rates(q, e, t):
        q = system.constraints.on_the_constraints(q, t)
        p = q[jnp.array([0, 1, 3])]
        return (
            bd.MaggiEquations().accelerations(system, q, e, t),
            bd.AppellEquations().accelerations(system, q, e, t),
            bd.MaggiEquations().accelerations(reduced, p, e, t),
        )

    for _ in range(6):
        q = jnp.asarray(np.concatenate([rng.normal(size=3), rng.uniform(-1.0, 1.0, 1)]))
        maggi, appell, in_reduced = rates(q, jnp.asarray(rng.normal(size=2)), rng.uniform(0, 2))
        _close(maggi, appell, 1e-10, "Maggi - Appell")
        _close(maggi, in_reduced, 1e-10, "Maggi - reduced")


@eqx.filter_jit
def _final_x(slope):
    """x at t = 1 after 40 fixed Heun steps, forward-mode differentiable (fixed steps, so that
    central differences see the same discrete map as the derivative)."""
    plane = _slope(slope)
    y0 = (_on_the_plane(plane, jnp.array([0.1, -0.2, 0.3]), 0.0), jnp.array([0.4, 0.25]))
    solution = diffrax.diffeqsolve(
        bd.NonholonomicTerm(_knife_edge(plane)),
        diffrax.Heun(),
        0.0,
        1.0,
        0.025,
        y0,
        adjoint=diffrax.ForwardMode(),
    )
    return solution.ys[0][-1, 0]


def test_the_derivative_through_the_constraints_equals_central_differences():
    """d x(1)/d α, through Newton's solve for z at every stage and the rows' ∂f/∂t, equals
    central differences to 1e-7 relative."""
    slope = jnp.array(0.3)
    # One program: the derivative's gives the differences' values too (a program of the
    # value alone would compile the solve again).
    value_and_derivative = jax.jit(lambda s: jax.jvp(_final_x, (s,), (jnp.ones_like(s),)))
    derivative = value_and_derivative(slope)[1]
    h = 1e-5
    differences = (value_and_derivative(slope + h)[0] - value_and_derivative(slope - h)[0]) / (
        2 * h
    )
    assert abs(float(derivative)) > 0.1
    _close(derivative / differences, 1.0, 1e-7, "derivative / differences")


# --- Refusals ----------------------------------------------------------------------------------


def _unit_circle(q, t):
    return jnp.stack([q[0] ** 2 + q[1] ** 2 - 1.0])


@pytest.mark.parametrize(
    "build, message",
    [
        (lambda: bd.HolonomicConstraints(1.0, dependent=(0,)), "must be a function f(q, t)"),
        (lambda: bd.HolonomicConstraints(_unit_circle, dependent=()), "at least one"),
        (lambda: bd.HolonomicConstraints(_unit_circle, dependent=(1, 1)), "each coordinate once"),
        (lambda: bd.PfaffianConstraints(None, independent=(0,)), "needs rows"),
        (
            lambda: bd.PfaffianConstraints(None, independent=(0,), b0=lambda q, t: q),
            "needs rows",
        ),
        (
            lambda: bd.PfaffianConstraints(
                None, independent=(1,), holonomic=bd.HolonomicConstraints(_unit_circle, (1,))
            ),
            "take them out of `independent`",
        ),
        (
            lambda: bd.PfaffianConstraints(None, independent=(0,), holonomic=_unit_circle),
            "must be a `HolonomicConstraints`",
        ),
    ],
    ids=[
        "function-not-callable",
        "no-dependent",
        "repeated-dependent",
        "no-rows",
        "b0-without-rows",
        "dependent-listed-independent",
        "holonomic-not-constraints",
    ],
)
def test_bad_construction_is_refused(build, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        build()


def test_rows_that_do_not_add_up_are_refused():
    """One holonomic row for three coordinates with one independent velocity leaves a row
    missing: refused, naming the count."""
    constraints = bd.PfaffianConstraints(
        None, independent=(2,), holonomic=bd.HolonomicConstraints(_unit_circle, (1,))
    )
    with pytest.raises(ValueError, match=re.escape("need s = 2 rows")):
        constraints.parametric_form(jnp.array([0.6, 0.8, 0.0]), 0.0)


def test_a_configuration_newton_cannot_bring_to_the_constraints_raises():
    """From y = 0 the circle's ∂f/∂y vanishes: Newton's method cannot start, and placing the
    configuration raises inside `jit` instead of returning a point off the circle."""
    constraints = bd.HolonomicConstraints(_unit_circle, dependent=(1,))
    place = jax.jit(constraints.on_the_constraints)
    _close(place(jnp.array([0.6, 0.5]), 0.0), jnp.array([0.6, 0.8]), 1e-14, "placed")
    with pytest.raises(Exception, match=re.escape("too far from the constraints")):
        jax.block_until_ready(place(jnp.array([0.6, 0.0]), 0.0))
