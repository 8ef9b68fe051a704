"""Static invariance checks (seed 004, Theorems 2.2 and 2.3) on every system and counter-example."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from systems import SYSTEMS, body_inertia_data

import bundledyn as bd

TOLERANCE = 1e-10

# Each counter-example with the conditions of Theorem 2.2 it breaks on generic shapes.
COUNTEREXAMPLES = {
    "anisotropic_mass": (bd.checks.anisotropic_mass, ("(a)",)),
    "shape_dependent_mass": (bd.checks.shape_dependent_mass, ("(b)",)),
    "drifting_centre": (bd.checks.drifting_centre, ("(b)",)),
    "translational_curvature": (bd.checks.translational_curvature, ("(b)", "(c)")),
}


@pytest.mark.parametrize("name", SYSTEMS)
def test_static_checks_pass_on_256_states(name, key):
    report = bd.checks.galilean_invariance(SYSTEMS[name](), key, 256, tolerance=TOLERANCE)
    assert report.shapes.shape[0] == 256
    assert report.passed, str(report)
    assert report.conditions.max() <= TOLERANCE and report.properties.max() <= TOLERANCE
    assert "PASSED" in str(report)


@pytest.mark.parametrize("name", COUNTEREXAMPLES)
def test_counterexample_fails_exactly_its_condition(name, key):
    make, broken = COUNTEREXAMPLES[name]
    report = bd.checks.galilean_invariance(make(), key, 256, tolerance=TOLERANCE)
    assert report.failed == broken, str(report)
    # Broken by far more than rounding, and Theorem 2.3's equivalent properties agree.
    flagged = report.worst > TOLERANCE
    assert np.all(report.worst[flagged] > 1e-2)
    assert np.array_equal(report.properties.max(axis=0) > TOLERANCE, flagged)
    text = str(report)
    assert "FAILED: " + ", ".join(broken) in text and text.count("✗") == 2 * len(broken)


def test_translational_curvature_breaks_c_alone_at_its_symmetric_shape():
    """At q = 0 the connection vanishes, so (b) holds there while (c) does not; the residual is
    the closed form J(e_x, Ω(e_1, e_2)) = m k in the metric's units, i.e. k·L with m = 1."""
    k = 0.7
    system = bd.checks.translational_curvature(k)
    residuals = jax.jit(lambda q: bd.checks.galilean_conditions(system, q).residuals)(jnp.zeros(2))
    metric = np.asarray(jax.jit(lambda q: system.metric(q))(jnp.zeros(2)))  # compiled
    length = np.sqrt(np.trace(metric[:3, :3]) / 3.0)
    np.testing.assert_allclose(residuals, [0.0, 0.0, k * length], rtol=1e-12, atol=1e-15)


class _RigidByConstruction(eqx.Module):
    """Kinetic energy of a frozen-rigid system whose centre of mass stays put along horizontal
    curves: (a) and (b) hold by construction, the rotational connection is arbitrary."""

    centre: jax.Array  # c(q) = centre @ sin(q)
    angular: jax.Array  # A_ω(q) = angular[0] + angular[1] * cos(q)
    inertia: jax.Array

    def __call__(self, q, qdot, xi):
        def c_of(q_):
            return self.centre @ jnp.sin(q_)

        c, dc = c_of(q), jax.jacfwd(c_of)(q)
        A_w = self.angular[0] + self.angular[1] * jnp.cos(q)[None]
        A_v = dc + bd.lie.hat(c) @ A_w  # the connection's velocity at c equals dc/dq
        U = xi + jnp.concatenate([A_w, A_v]) @ qdot
        l = self.inertia + 0.1 * jnp.diag(jnp.sin(q[:3]) ** 2)
        M = bd.spatial_inertia(2.0, c, l)
        return 0.5 * U @ M @ U + 0.5 * qdot @ qdot


def test_a_and_b_imply_c(key):
    """Why no counter-example breaks (c) alone: (a) and (b) on an open set force (c), although
    the curvature itself is far from zero."""
    k1, k2 = jax.random.split(key)
    energy = _RigidByConstruction(
        0.3 * jax.random.normal(k1, (3, 3)),
        0.5 * jax.random.normal(k2, (2, 3, 3)),
        jnp.diag(jnp.array([0.3, 0.4, 0.5])),
    )
    system = bd.GenericSystem(energy, 3)
    report = bd.checks.galilean_invariance(system, key, 64, tolerance=TOLERANCE)
    assert report.passed, str(report)
    curvature = jax.jit(jax.vmap(lambda q: bd.curvature(system, q)))(jnp.asarray(report.shapes[:8]))
    assert np.min(np.max(np.abs(np.asarray(curvature)), axis=(1, 2, 3))) > 0.1


def test_rigid_structure_matches_bodies_summed_one_by_one(key):
    system = SYSTEMS["chain5"]()
    q = 0.7 * jax.random.uniform(key, (system.shape_dim,), minval=-1.0, maxval=1.0)
    structure = eqx.filter_jit(bd.checks.rigid_structure)(system, q)
    m, c, l = jax.jit(lambda q: body_inertia_data(system, q))(q)  # compiled
    np.testing.assert_allclose(structure.mass, m, rtol=1e-13)
    np.testing.assert_allclose(structure.centre, c, atol=1e-12)
    np.testing.assert_allclose(structure.rotational_inertia, l, atol=1e-12)
    assert jnp.max(structure.residuals) <= TOLERANCE


def test_curvature_by_holonomy_batched_recovers_a_translational_curvature(key):
    """Translations commute, so each small loop translates by exactly -k·area along e_x."""
    k = 1.3
    system = bd.checks.translational_curvature(k)
    shapes = jax.random.normal(key, (8, 2))
    estimate = jax.jit(jax.vmap(lambda q: bd.checks.curvature_by_holonomy(system, q, 1e-2)))(shapes)
    expected = np.zeros((6, 2, 2))
    expected[3, 0, 1], expected[3, 1, 0] = k, -k
    np.testing.assert_allclose(estimate, np.broadcast_to(expected, (8, 6, 2, 2)), atol=1e-9)


class _CountingEnergy(eqx.Module):
    masses: jax.Array

    def __call__(self, q, qdot, xi):
        _CountingEnergy.traces += 1
        return 0.5 * xi[3:] @ (self.masses * xi[3:]) + 0.5 * xi[:3] @ xi[:3] + 0.5 * qdot @ qdot


_CountingEnergy.traces = 0


def test_battery_is_one_compiled_call_reused(key):
    system = bd.GenericSystem(_CountingEnergy(jnp.array([1.0, 1.0, 1.0])), 1)
    bd.checks.galilean_invariance(system, key, 32)
    traced = _CountingEnergy.traces
    assert traced > 0
    other = bd.GenericSystem(_CountingEnergy(jnp.array([1.0, 2.0, 3.0])), 1)
    report = bd.checks.galilean_invariance(other, jax.random.fold_in(key, 1), 32)
    assert _CountingEnergy.traces == traced  # new numbers, same compiled battery
    assert report.failed == ("(a)",)


def test_bad_shapes_are_refused(key):
    with pytest.raises(ValueError, match=r"shapes of shape \(n >= 1, 1\)"):
        bd.checks.galilean_invariance(SYSTEMS["chain2"](), key, shapes=np.zeros((4, 5)))


def test_the_report_refuses_vmap_and_names_the_checks_that_batch():
    system = SYSTEMS["chain2"]()
    keys = jax.random.split(jax.random.key(0), 2)
    with pytest.raises(TypeError, match="galilean_conditions"):
        jax.vmap(lambda k: bd.checks.galilean_invariance(system, k, n=4))(keys)
    # What the message advises: the conditions' residuals, batched over shapes.
    shapes = jax.random.uniform(keys[0], (4, system.shape_dim), minval=-1.0, maxval=1.0)
    residuals = jax.jit(jax.vmap(lambda q: bd.checks.galilean_conditions(system, q).residuals))(
        shapes
    )
    assert residuals.shape == (4, 3) and float(jnp.max(residuals)) < 1e-10
