"""Closed-form small inverses against LAPACK, with derivatives against finite differences."""

import jax
import jax.numpy as jnp
import numpy as np

from bundledyn._linalg import inverse_3x3, spd_inverse_6x6
from bundledyn._systems._rigid_body import spatial_inertia


def _random_spd(rng, n, condition):
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return (Q * np.geomspace(1.0, 1.0 / condition, n)) @ Q.T


def _spatial_inertias(rng):
    """Spatial inertias about points near and far from bodies, slender and flat ones included
    (the parallel-axis term then dominates the angular block), and composites of several."""
    out = []
    for _ in range(24):
        Q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
        principal = np.exp(rng.uniform(np.log(1e-6), 0.0, 3))
        com = rng.standard_normal(3) * 10.0 ** rng.uniform(-2, 1)
        mass = np.exp(rng.standard_normal())
        out.append(np.asarray(spatial_inertia(mass, com, (Q * principal) @ Q.T)))
    out += [sum(out[i : i + 4]) for i in range(0, 24, 4)]
    return out


def _check_inverse(M, inv, factor):
    """Forward error within `factor` κ ε of LAPACK's inverse (what `I_r⁻¹ @ v` inherits)."""
    bound = factor * np.linalg.cond(M) * np.finfo(float).eps * np.abs(np.linalg.inv(M)).max()
    assert np.abs(inv - np.linalg.inv(M)).max() < bound
    assert np.abs(inv - inv.T).max() < bound


def test_spatial_inertia_inverse_matches_lapack():
    """Locked inertias are spatial inertias: the 3×3 blocks are then as well conditioned as the
    body, and the closed form is as accurate as LAPACK's LU (condition numbers up to ~1e10)."""
    inverse = jax.jit(spd_inverse_6x6)
    for M in _spatial_inertias(np.random.default_rng(3)):
        _check_inverse(M, np.asarray(inverse(M)), factor=4.0)


def test_spd_inverse_of_a_generic_matrix():
    """Any SPD matrix with κ ≤ 1e3 to 10 κ ε. The Schur/adjugate form is not backward stable:
    for a matrix that mixes its conditioning across the blocks the error grows (measured
    ~80 κ ε at κ = 1e6), which locked inertias never do (see above)."""
    rng = np.random.default_rng(7)
    for condition in (1.0, 1e3):
        for _ in range(16):
            M = _random_spd(rng, 6, condition)
            _check_inverse(M, np.asarray(spd_inverse_6x6(M)), factor=10.0)


def test_inverse_3x3_matches_lapack():
    rng = np.random.default_rng(4)
    for _ in range(16):
        M = rng.standard_normal((3, 3))
        np.testing.assert_allclose(inverse_3x3(M), np.linalg.inv(M), rtol=1e-12, atol=1e-12)


def test_spd_inverse_derivatives_vs_finite_differences():
    """d(M⁻¹) = -M⁻¹ dM M⁻¹ (closed form), forward and reverse mode, and finite differences."""
    rng = np.random.default_rng(5)
    M, dM = _random_spd(rng, 6, 10.0), rng.standard_normal((6, 6))
    dM = dM + dM.T
    _, tangent = jax.jvp(spd_inverse_6x6, (jnp.asarray(M),), (jnp.asarray(dM),))
    inv = np.linalg.inv(M)
    np.testing.assert_allclose(tangent, -inv @ dM @ inv, rtol=1e-10, atol=1e-12)
    h = 1e-6
    fd = (spd_inverse_6x6(M + h * dM) - spd_inverse_6x6(M - h * dM)) / (2 * h)
    np.testing.assert_allclose(tangent, fd, rtol=1e-6, atol=1e-8)
    W = rng.standard_normal((6, 6))
    grad = jax.grad(lambda A: jnp.sum(W * spd_inverse_6x6(A)))(jnp.asarray(M))
    np.testing.assert_allclose(np.sum(grad * dM), np.sum(W * tangent), rtol=1e-12)


def test_spd_inverse_vmaps():
    rng = np.random.default_rng(6)
    Ms = np.stack([_random_spd(rng, 6, 100.0) for _ in range(8)])
    np.testing.assert_allclose(
        jax.vmap(spd_inverse_6x6)(Ms), np.linalg.inv(Ms), rtol=1e-11, atol=1e-12
    )
