"""Equations of motion (issue: dynamics): (2.6)–(2.7) against the reference form; static effects."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from systems import affine_body, asymmetric_body, chain, random_shapes

import bundledyn as bd
from bundledyn import lie

N_STATES = 128

SCENES = {
    "rigid_body": lambda: bd.Scene(asymmetric_body()),
    "chain5": lambda: bd.Scene(chain(5)),
    "affine_spring": lambda: bd.Scene(
        affine_body(), effects=(bd.ShapeSpring(jnp.linspace(1.0, 3.0, 6), 0.1),)
    ),
}


@functools.cache
def compare_forms(name):
    """Both vector fields on a batch of random states, with random external forces."""
    scene = SCENES[name]()
    system = scene.system

    @jax.jit
    @jax.vmap
    def both(q, xi, qdot, g_log, F_ext, Q_ext):
        g = lie.se3_exp(g_log)
        U = xi + bd.connection(system, q) @ qdot if system.shape_dim else xi
        kin = bd.Kinematics(0.0, g, q, xi, qdot)
        F, Q = scene.forces(kin)
        F, Q = F + F_ext, Q + Q_ext
        geo = bd.bundle_geometry(system, q, U, qdot)
        Udot = bd.locked_acceleration(geo, F)
        if system.shape_dim:
            qddot = bd.shape_acceleration(geo, F, Q)
            # ξ = U − A q̇  ⇒  ξ̇ = U̇ − (∂_q̇ A) q̇ − A q̈
            xidot = Udot - geo.dA_qdot - geo.A @ qddot
        else:
            qddot, xidot = qdot, Udot
        xidot_ref, qddot_ref = bd.reference_accelerations(system, q, xi, qdot, F, Q)
        return jnp.concatenate([xidot, qddot]), jnp.concatenate([xidot_ref, qddot_ref])

    return system, both


@pytest.mark.parametrize("name", SCENES)
def test_chevallier_form_equals_reference_form(name, key):
    """(2.6)–(2.7) term by term agree with the Hamel/Euler–Poincaré form to 1e-10 on 128 states."""
    system, both = compare_forms(name)
    k = jax.random.split(key, 6)
    d = system.shape_dim
    args = (
        random_shapes(system, k[0], N_STATES),
        jax.random.normal(k[1], (N_STATES, 6)),
        jax.random.normal(k[2], (N_STATES, d)),
        jax.random.normal(k[3], (N_STATES, 6)),
        jax.random.normal(k[4], (N_STATES, 6)),
        jax.random.normal(k[5], (N_STATES, d)),
    )
    chevallier, reference = both(*args)
    scale = np.abs(reference).max(axis=1, keepdims=True)
    assert np.abs(chevallier - reference).max(axis=1).max() / scale.min() < 1e-10


def _count_primitives(jaxpr, names=None):
    """Number of equations in a jaxpr, recursively (optionally only those with given primitive names)."""
    total = 0
    for eqn in jaxpr.eqns:
        if names is None or eqn.primitive.name in names:
            total += 1
        for param in eqn.params.values():
            for sub in param if isinstance(param, tuple | list) else (param,):
                inner = getattr(sub, "jaxpr", None)
                if inner is not None:
                    total += _count_primitives(getattr(inner, "jaxpr", inner), names)
    return total


def _vector_field_jaxpr(scene, d):
    term = bd.SceneTerm(scene)
    y = term.pack(0.0, jnp.eye(4), jnp.zeros(d), jnp.zeros(6), jnp.zeros(d))
    return jax.make_jaxpr(term.vf)(0.0, y, None).jaxpr


def test_scene_compiles_only_the_effects_it_names():
    """Effects are static structure: absent effects add no operations, zero-valued ones do."""
    system = chain(3)
    d = system.shape_dim
    bare = _count_primitives(_vector_field_jaxpr(bd.Scene(system), d))
    gravity = _count_primitives(_vector_field_jaxpr(bd.Scene(system, (bd.Gravity(),)), d))
    zero_gravity = _count_primitives(_vector_field_jaxpr(bd.Scene(system, (bd.Gravity(0.0),)), d))
    spring = _count_primitives(_vector_field_jaxpr(bd.Scene(system, (bd.ShapeSpring(1.0),)), d))
    assert gravity > bare and spring > bare
    assert zero_gravity == gravity  # a zero-valued parameter is not an absent effect


def test_rigid_body_integrates_no_shape_block():
    """A rigid body's vector field factorizes no shape metric (its 6×6 inertia is inverted in
    closed form; no LAPACK factorization, no square root of `spd_solve`'s unrolled Cholesky)
    and is a fraction of a chain's; the dense field of a chain past the unrolled sizes
    (d = 9) calls LAPACK's Cholesky once."""
    factorizations = {"lu", "cholesky", "triangular_solve", "sqrt"}
    jaxpr = _vector_field_jaxpr(bd.Scene(asymmetric_body()), 0)
    assert _count_primitives(jaxpr, factorizations) == 0
    chain_jaxpr = _vector_field_jaxpr(bd.Scene(chain(2)), chain(2).shape_dim)
    large = chain(7)
    large_jaxpr = _vector_field_jaxpr(bd.Scene(large, algorithm=bd.DenseField()), large.shape_dim)
    assert large.shape_dim == 9 and _count_primitives(large_jaxpr, {"cholesky"}) == 1
    assert _count_primitives(jaxpr) < _count_primitives(chain_jaxpr) / 4


def test_tree_of_one_body_is_its_rigid_body():
    """A `Multibody` with no links (d = 0) has the base's spatial inertia as its metric and
    moves as that rigid body (Euler's equations, through the same vector field)."""
    body = asymmetric_body()
    tree = bd.Multibody(body, [])
    np.testing.assert_allclose(tree.metric(jnp.zeros(0)), body.metric(jnp.zeros(0)), atol=1e-15)
    state = bd.State(
        jnp.eye(4), jnp.zeros(0), jnp.array([0.3, -0.2, 0.5, 0.1, 0.0, -0.1]), jnp.zeros(0)
    )
    a = bd.simulate(bd.Scene(tree), state, 1.0, rtol=1e-10, atol=1e-12)
    b = bd.simulate(bd.Scene(body), state, 1.0, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(a.g[-1], b.g[-1], atol=1e-12)
