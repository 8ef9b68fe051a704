"""The Levenberg–Marquardt solver behind `identify.fit`: its damped step, its chord steps
(the Jacobian reused with new residuals) and a caller's starting evaluation, checked against
dense singular value decompositions and against the solver without them."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from bundledyn._identify._levenberg_marquardt import (
    _factorization,
    _step,
    _with_residuals,
    levenberg_marquardt,
)


def _stacked(rows, seed):
    """A random stacked problem `(J, C, r, c, units)` whose column 5 no residual sees."""
    rng = np.random.default_rng(seed)
    n = 40
    J = rng.normal(size=(rows, n)) * np.logspace(-3, 3, n)
    J[:, 5] = 0.0
    C, r, c = rng.normal(size=(20, n)), rng.normal(size=rows), rng.normal(size=20)
    C[:, 5] = 0.0
    return J, C, r, c, rng.uniform(0.5, 2.0, n)


@pytest.mark.parametrize("rows", [300, 10], ids=["tall", "fewer residuals than variables"])
def test_the_damped_step_is_the_truncated_singular_value_one_of_the_stacked_jacobian(rows):
    """The step from the triangle of [A | b] equals the one written with the singular value
    decomposition of the whole stacked A = [J; C] diag(u) (its left vectors formed), at
    every damping, with an undetermined direction left where it is."""
    J, C, r, c, units = _stacked(rows, rows)
    A, b = np.concatenate([J, C]) * units, np.concatenate([r, c])
    W, singular, Vt = np.linalg.svd(A, full_matrices=False)
    factorization = _factorization(r, J, c, C, units)
    for damping in (1e-3, 1.0, 1e3):
        gain = np.where(singular * 10.0 > 1.0, singular / (singular**2 + damping), 0.0)
        y = -(Vt.T * gain) @ (W.T @ b)
        model = b + A @ y
        delta, predicted = _step(factorization, damping, units, 10.0)
        np.testing.assert_allclose(delta, units * y, rtol=0, atol=1e-12 * np.abs(y).max())
        np.testing.assert_allclose(predicted, 0.5 * (b @ b - model @ model), rtol=1e-12)
        assert abs(delta[5]) <= 1e-12 * np.abs(delta).max()  # stays put, to rounding


@pytest.mark.parametrize("rows", [300, 10], ids=["tall", "fewer residuals than variables"])
def test_a_chord_step_is_the_step_of_the_same_jacobian_factorized_with_the_new_residuals(rows):
    """`_with_residuals` (the old factorization, new residuals, no QR) gives the steps and
    predicted reductions of factorizing [A | b_new] anew, at every damping."""
    J, C, r, c, units = _stacked(rows, rows + 1)
    rng = np.random.default_rng(rows + 2)
    r_new, c_new = rng.normal(size=r.shape), rng.normal(size=c.shape)
    chord = _with_residuals(_factorization(r, J, c, C, units), r_new, J, c_new, C, units)
    anew = _factorization(r_new, J, c_new, C, units)
    np.testing.assert_allclose(chord.norm, anew.norm, rtol=1e-14)
    for damping in (1e-3, 1.0, 1e3):
        (d_chord, p_chord), (d_anew, p_anew) = (
            _step(f, damping, units, 10.0) for f in (chord, anew)
        )
        np.testing.assert_allclose(d_chord, d_anew, rtol=0, atol=1e-10 * np.abs(d_anew).max())
        np.testing.assert_allclose(p_chord, p_anew, rtol=1e-10)


# A damped oscillation's amplitude, decay, frequency and phase from noisy samples (the
# residuals do not vanish at the solution), with a heavily weighted constraint
# (amplitude × phase = 0.6) in the role of the shooting windows' continuity.
_TIMES = jnp.linspace(0.0, 6.0, 120)
_TRUTH = jnp.array([1.5, 0.3, 2.1, 0.4])


def _model(z):
    return z[0] * jnp.exp(-z[1] * _TIMES) * jnp.sin(z[2] * _TIMES + z[3])


_DATA = _model(_TRUTH) + 0.05 * jax.random.normal(jax.random.key(0), _TIMES.shape)


def _residuals(z):
    return (_model(z) - _DATA) / 0.05, 1e3 * jnp.atleast_1d(z[0] * z[3] - 0.6)


@jax.jit
def _evaluate(z):
    r, c = _residuals(z)
    J, C = jax.jacfwd(_residuals)(z)
    return r, J, c, C


_Z0 = jnp.array([1.0, 0.1, 1.9, 0.7])


@functools.cache
def _solution(reuse: int):
    return levenberg_marquardt(_evaluate, jax.jit(_residuals), _Z0, reuse=reuse, ftol=1e-12)


def test_chord_steps_reach_the_same_minimum_with_fewer_jacobians_and_return_the_last_one():
    """With chord steps the solver converges to the same least-squares point as without,
    evaluating fewer Jacobians, and the Jacobian it returns is the one at its solution."""
    plain, chord = _solution(0), _solution(3)
    assert plain.converged and chord.converged
    np.testing.assert_allclose(chord.z, plain.z, rtol=1e-7)
    assert chord.evaluations < plain.evaluations, (chord.evaluations, plain.evaluations)
    r, J, c, C = _evaluate(chord.z)
    for returned, fresh in zip(chord.evaluation(), (r, J, c, C), strict=True):
        np.testing.assert_array_equal(returned, fresh)
    # Not a stall of stale steps short of the minimum: the same merit to rounding.
    assert chord.costs[-1] <= plain.costs[-1] * (1 + 1e-12)


def test_a_given_starting_evaluation_replaces_the_first_and_is_not_counted():
    """`start=evaluate(z0)` gives the same iterates as evaluating at `z0`, one Jacobian
    fewer."""
    plain = _solution(0)
    started = levenberg_marquardt(
        _evaluate, jax.jit(_residuals), _Z0, ftol=1e-12, start=_evaluate(_Z0)
    )
    assert started.evaluations == plain.evaluations - 1
    np.testing.assert_array_equal(started.z, plain.z)
    assert started.costs == plain.costs
