"""Pseudo-inertias and their log-Cholesky coordinates: physical by construction, both ways.

Checked against an independent integral (a solid box's second moment), by round trips
(random, near-degenerate thin rods and flat plates), and through every system kind.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from systems import SYSTEMS, random_shapes

import bundledyn as bd
from bundledyn.identify import (
    inertial_from_pseudo_inertia,
    log_cholesky_from_pseudo_inertia,
    pseudo_inertia,
    pseudo_inertia_from_log_cholesky,
)

to_theta = jax.jit(log_cholesky_from_pseudo_inertia)
from_theta = jax.jit(pseudo_inertia_from_log_cholesky)


def _box_integral(mass, size, centre):
    """∫ [x; 1][x; 1]ᵀ dm of a solid box by Gauss–Legendre quadrature (exact for quadratics)."""
    nodes, weights = np.polynomial.legendre.leggauss(3)
    P = np.zeros((4, 4))
    for i, wi in zip(nodes, weights, strict=True):
        for j, wj in zip(nodes, weights, strict=True):
            for k, wk in zip(nodes, weights, strict=True):
                x = np.append(np.asarray(centre) + 0.5 * np.asarray(size) * (i, j, k), 1.0)
                P += mass * wi * wj * wk / 8.0 * np.outer(x, x)
    return P


def test_pseudo_inertia_of_a_box_is_its_second_moment():
    mass, size, centre = 2.5, (0.4, 0.1, 0.25), (0.3, -0.2, 0.05)
    inertia = bd.Box(size).rigid_body(mass).inertia
    np.testing.assert_allclose(
        pseudo_inertia(mass, centre, inertia), _box_integral(mass, size, centre), atol=1e-15
    )


def test_every_real_vector_is_a_physical_body_and_round_trips():
    theta = jax.random.normal(jax.random.key(0), (200, 10))
    P = from_theta(theta)
    np.testing.assert_allclose(to_theta(P), theta, rtol=1e-10, atol=1e-10)
    m, c, J = inertial_from_pseudo_inertia(P)
    moments = np.linalg.eigvalsh(J)
    assert np.all(m > 0) and np.all(moments[:, 0] > 0)
    assert np.all(moments[:, 0] + moments[:, 1] >= moments[:, 2] * (1 - 1e-12))
    np.testing.assert_allclose(pseudo_inertia(m, c, J), P, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(c, theta[:, 7:], rtol=1e-12, atol=1e-12)  # t is the centre
    np.testing.assert_allclose(m, np.exp(2 * theta[:, 0]), rtol=1e-12)


@pytest.mark.parametrize(
    "moments",
    [(1e-8, 1.0, 1.0), (1e-12, 1.0, 1.0), (1.0, 2.0, 3.0 - 1e-9), (0.5, 0.5, 1.0 - 1e-10)],
    ids=["rod", "thinner-rod", "plate", "square-plate"],
)
def test_near_degenerate_bodies_round_trip(moments):
    """Thin rods (one moment ~0) and flat plates (I₃ → I₁ + I₂): the inertia comes back to
    rounding relative to its largest moment, in a rotated frame with an offset centre."""
    R = np.asarray(bd.lie.so3_exp(jnp.array([0.3, -0.7, 1.1])))
    J = R @ np.diag(moments) @ R.T
    mass, com = 1.7, np.array([0.2, -0.4, 0.9])
    theta = to_theta(pseudo_inertia(mass, com, J))
    assert np.all(np.isfinite(theta))
    m, c, J_back = inertial_from_pseudo_inertia(from_theta(theta))
    np.testing.assert_allclose(m, mass, rtol=1e-14)
    np.testing.assert_allclose(c, com, rtol=0, atol=1e-14)
    np.testing.assert_allclose(J_back, J, rtol=0, atol=1e-12 * max(moments))


def test_a_non_physical_body_has_no_coordinates():
    J = np.diag([1.0, 1.0, 2.5])  # breaks the triangle inequality
    assert np.all(np.isnan(to_theta(pseudo_inertia(1.0, np.zeros(3), J))[1:7]))


def test_coordinates_are_smooth_and_their_derivatives_exact():
    theta = jnp.array([0.2, -0.3, 0.1, 0.4, 0.05, -0.2, 0.3, 0.1, 0.0, -0.2])
    jacobian = jax.jacfwd(pseudo_inertia_from_log_cholesky)(theta)
    h = 1e-6
    fd = jnp.stack(
        [(from_theta(theta + h * e) - from_theta(theta - h * e)) / (2 * h) for e in jnp.eye(10)],
        axis=-1,
    )
    np.testing.assert_allclose(jacobian, fd, rtol=1e-8, atol=1e-9)
    inverse = jax.jacfwd(log_cholesky_from_pseudo_inertia)(from_theta(theta))
    np.testing.assert_allclose(jnp.einsum("iab,abj->ij", inverse, jacobian), np.eye(10), atol=1e-12)


@pytest.mark.parametrize("name", sorted(SYSTEMS))
def test_systems_give_and_take_their_pseudo_inertias(name, key):
    """Every inertial system round-trips its pseudo-inertias, and scaling them all scales
    the bodies' part of its metric (the metric is linear in them and in the joints' rotor
    inertia, which stays)."""
    system = SYSTEMS[name]()
    if not isinstance(system, bd.AbstractInertialSystem):
        pytest.skip("a user's kinetic energy has no pseudo-inertias")
    q = random_shapes(system, key, 1)[0]
    P = system.pseudo_inertias()
    same, doubled = system.with_pseudo_inertias(P), system.with_pseudo_inertias(2.0 * P)
    # The three systems share one structure, so one compiled metric (not one per primitive).
    metric = eqx.filter_jit(lambda system, q: system.metric(q))
    original, same, doubled = (np.asarray(metric(s, q)) for s in (system, same, doubled))
    np.testing.assert_allclose(same, original, rtol=1e-13, atol=1e-15)
    rotors = np.diag(
        np.concatenate([np.zeros(6), np.asarray(getattr(system, "armature", np.zeros(q.size)))])
    )
    bodies = original - rotors
    np.testing.assert_allclose(doubled - rotors, 2.0 * bodies, rtol=1e-13, atol=1e-15)
