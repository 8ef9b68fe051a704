"""The Whipple bicycle from its nonlinear model: four bodies, two rolling wheels, the pitch kept
by Newton's method. Checked against the linearized benchmark of Meijaard, Papadopoulos, Ruina &
Schwab (2007, Proc. R. Soc. A 463, Table 2), finite differences and its first integral."""

import functools

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import bundledyn as bd

BIKE = bd.WhippleBicycle.benchmark()

# Table 2 of the paper: the eigenvalues of the benchmark at three speeds, and the speeds
# where the weave and the capsize motions change stability.
TABLE_2 = {
    0.0: [-5.53094371765393, -3.13164324790656, 3.13164324790656, 5.53094371765393],
    5.0: [
        -14.07838969279822,
        -0.77534188219585 - 4.46486771378823j,
        -0.77534188219585 + 4.46486771378823j,
        -0.32286642900409,
    ],
    10.0: [
        -24.62459635017404,
        -3.72016840437287 - 10.90681139476287j,
        -3.72016840437287 + 10.90681139476287j,
        0.16105338653172,
    ],
}
WEAVE_SPEED, CAPSIZE_SPEED = 4.29238253634111, 6.02426201538837

_eigenvalues = jax.jit(lambda bike, speed: bike.eigenvalues(speed))
# The growth rate compiled once; `stability_boundary`, called outside `jax.jit`, compiles its
# bisection and its derivative's two slopes each once for it, and reuses them.
_abscissa = jax.jit(lambda speed, bike: bike.spectral_abscissa(speed))


def _boundary(bike, lower, upper):
    return bd.stability_boundary(_abscissa, (lower, upper), bike)


def test_a_boundarys_implicit_derivatives_are_the_closed_forms():
    # sigma(v; a, b) = a - b v^2 vanishes at v* = sqrt(a / b).
    def root(p):
        return bd.stability_boundary(lambda v, p: p[0] - p[1] * v**2, (0.1, 10.0), p)

    p = jnp.array([2.0, 0.5])
    np.testing.assert_allclose(root(p), 2.0, rtol=1e-15)
    expected = jnp.array([0.5 / jnp.sqrt(p[0] * p[1]), -0.5 * jnp.sqrt(p[0]) / p[1] ** 1.5])
    np.testing.assert_allclose(jax.grad(root)(p), expected, rtol=1e-12)
    np.testing.assert_allclose(jax.jacfwd(root)(p), expected, rtol=1e-12)
    with pytest.raises(Exception, match="same sign at both ends"):
        bd.stability_boundary(lambda v, p: p[0] - p[1] * v**2, (3.0, 10.0), p)


@pytest.mark.parametrize("speed", sorted(TABLE_2))
def test_eigenvalues_from_the_nonlinear_model_are_the_benchmarks(speed):
    ours = np.sort_complex(np.asarray(_eigenvalues(BIKE, speed)))
    np.testing.assert_allclose(ours, np.sort_complex(TABLE_2[speed]), rtol=0, atol=1e-8)


# The critical speeds are roots of the spectral abscissa, itself a derivative of Maggi's
# equations, and their derivatives third derivatives: the slowest programs of the suite to
# compile. One worker runs both (`.ci/run`'s `--dist loadgroup`), the root finder compiled once.
@pytest.mark.slow
@pytest.mark.xdist_group("bicycle")
def test_the_weave_and_capsize_speeds_are_the_benchmarks():
    weave, capsize = (float(_boundary(BIKE, *bracket)) for bracket in ((4.0, 5.0), (5.0, 7.0)))
    assert abs(weave - WEAVE_SPEED) < 1e-8
    assert abs(capsize - CAPSIZE_SPEED) < 1e-8
    # Between them, and only there, upright running is stable.
    for speed, stable in ((4.0, False), (5.0, True), (7.0, False)):
        assert (float(_abscissa(speed, BIKE)) < 0) == stable


@pytest.mark.slow
@pytest.mark.xdist_group("bicycle")
def test_the_weave_speeds_gradient_in_the_trail_equals_finite_differences():
    def weave(trail):
        return _boundary(eqx.tree_at(lambda b: b.trail, BIKE, trail), 4.0, 5.0)

    # Forward mode, one parameter; reverse mode is checked on a closed form above.
    gradient = jax.jvp(weave, (BIKE.trail,), (jnp.ones_like(BIKE.trail),))[1]
    h = 1e-5
    central = (weave(BIKE.trail + h) - weave(BIKE.trail - h)) / (2 * h)
    assert np.isfinite(gradient) and abs(gradient) > 1.0  # the trail matters
    np.testing.assert_allclose(gradient, central, rtol=1e-6)


@functools.partial(jax.jit, static_argnums=0)  # one program, not one per primitive
def _random_states(n, key):
    """`n` states `(q, e)` with both wheels on the ground: random position, yaw and wheel
    angles, roll and steer within 0.3 rad, rates of a bicycle ridden at a few m/s."""
    k = jax.random.split(key, 4)
    q = jax.random.normal(k[0], (n, 8))
    angles = 0.3 * jax.random.uniform(k[1], (n, 2), minval=-1.0, maxval=1.0)
    q = jax.vmap(BIKE.on_the_ground)(q.at[:, 3].set(angles[:, 0]).at[:, 5].set(angles[:, 1]))
    e = jax.random.normal(k[2], (n, 3)) * jnp.array([[0.5, 0.5, 15.0]])
    return q, e


def test_the_pitch_keeps_the_front_wheel_on_the_ground_and_has_the_implicit_derivative():
    roll, steer = jnp.array(0.2), jnp.array(-0.35)
    # Each function compiled once (its Newton solve included), not run primitive by primitive.
    pitch_of = jax.jit(lambda roll, steer: BIKE.pitch(roll, steer))
    height = jax.jit(lambda pitch, roll, steer: BIKE.front_contact_height(pitch, roll, steer))
    pitch = pitch_of(roll, steer)
    assert abs(float(height(pitch, roll, steer))) < 1e-15
    assert float(pitch_of(jnp.array(0.0), jnp.array(0.0))) == 0.0  # upright: level
    gradient = jax.jit(jax.grad(pitch_of, argnums=(0, 1)))(roll, steer)
    h = 1e-6
    central = [
        (float(pitch_of(roll + h, steer)) - float(pitch_of(roll - h, steer))) / (2 * h),
        (float(pitch_of(roll, steer + h)) - float(pitch_of(roll, steer - h))) / (2 * h),
    ]
    np.testing.assert_allclose(gradient, central, rtol=1e-7, atol=1e-10)
    # The second derivative too (Maggi's equations differentiate the placement twice).
    second = jax.jit(jax.grad(jax.grad(pitch_of)))(roll, steer)
    first = jax.jit(jax.grad(pitch_of))
    np.testing.assert_allclose(
        second, (float(first(roll + h, steer)) - float(first(roll - h, steer))) / (2 * h), rtol=1e-6
    )


def test_maggi_and_appell_give_the_same_accelerations():
    maggi = bd.NonholonomicTerm(BIKE)
    appell = bd.NonholonomicTerm(BIKE, bd.AppellEquations())
    q, e = _random_states(4, jax.random.PRNGKey(0))

    @jax.jit  # one program, not one per primitive
    def both(q, e):
        return (
            jax.vmap(lambda q, e: maggi.vf(0.0, (q, e), None)[1])(q, e),
            jax.vmap(lambda q, e: appell.vf(0.0, (q, e), None)[1])(q, e),
        )

    for a, b in zip(*both(q, e), strict=True):
        a, b = np.asarray(a), np.asarray(b)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-10 * max(1.0, float(np.max(np.abs(b)))))


@pytest.mark.slow  # a 4 s nonlinear solve of Maggi's equations, compiled with their second derivatives
def test_a_leaning_bicycle_keeps_its_energy_and_its_wheels_roll():
    # Inside the self-stable band, a lean of 0.1 rad and a steer rate die out; the motion is
    # nonlinear and conservative.
    q0, e0 = BIKE.steady_motion(4.6)
    q0 = q0.at[3].set(0.1)
    e0 = e0.at[1].set(0.5)
    term = bd.NonholonomicTerm(BIKE)
    sol = diffrax.diffeqsolve(
        term,
        diffrax.Tsit5(),
        0.0,
        4.0,
        None,
        (q0, e0),
        saveat=diffrax.SaveAt(ts=jnp.linspace(0.0, 4.0, 9)),
        stepsize_controller=diffrax.PIDController(rtol=1e-10, atol=1e-10),
        max_steps=4096,
    )
    q, e = sol.ys
    qdot = jax.vmap(lambda q, e: bd.constrained_velocities(BIKE.constraints, q, e, 0.0))(q, e)
    energy = jax.vmap(lambda q, qdot: bd.mechanical_energy(BIKE, q, qdot, 0.0))(q, qdot)
    assert float(jnp.max(jnp.abs(energy - energy[0]))) < 1e-8 * float(jnp.abs(energy[0]))
    contacts = jax.vmap(BIKE.contact_velocities)(q, qdot)
    assert float(jnp.max(jnp.abs(contacts))) < 1e-12  # the front one's vertical one too
    # The front wheel stays on the ground (the constraint is integrated in its
    # differentiated form, so to the solver's tolerance); the rear one by construction.
    placed = jax.vmap(BIKE.placement)(q)
    assert float(jnp.max(jnp.abs(placed.contacts[:, 0, 2]))) < 1e-15
    assert float(jnp.max(jnp.abs(placed.contacts[:, 1, 2]))) < 1e-9
    assert float(jnp.abs(q[-1, 3])) < 0.25 * float(jnp.abs(q[0, 3]))  # the lean dies out
