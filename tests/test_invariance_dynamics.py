"""Dynamic invariance checks: boosted frames (Theorem 2.2) and falling frames (Theorem 3.4)."""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from systems import affine_body, chain, chain3_state

import bundledyn as bd

SYSTEMS = {
    "chain3": lambda: chain(3),
    "affine_body": affine_body,
    "anisotropic_mass": bd.checks.anisotropic_mass,
    "shape_dependent_mass": bd.checks.shape_dependent_mass,
    "drifting_centre": bd.checks.drifting_centre,
    "translational_curvature": bd.checks.translational_curvature,
}
INVARIANT = ("chain3", "affine_body")
RTOL, ATOL = 1e-10, 1e-12
SPEEDS = jnp.array([0.0, 0.5, 1.0, 2.0, 4.0])
DIRECTION = jnp.array([0.6, -0.48, 0.64])


@eqx.filter_jit
def _frame_terms(system, g, q, U, qdot, velocity):
    """Boosted-frame minus Galilean-frame accelerations from the scenes' vector fields, and
    the prediction of (2.9)–(2.10) from the checks, at the velocities `velocity` (batch)."""
    galilean = bd.Scene(system)
    y = bd.SceneTerm(galilean).pack(0.0, g, q, U, qdot)
    d = system.shape_dim

    def accelerations(scene):
        xdot = bd.SceneTerm(scene).vf(jnp.zeros(()), y, None)[1]
        return (xdot[d : d + 6], xdot[d + 6 :]) if d else (xdot, xdot[:0])

    base = accelerations(galilean)

    def one(u):
        boosted = accelerations(bd.Scene(system, frame=bd.Boosted(u)))
        observed = jnp.concatenate([boosted[0] - base[0], boosted[1] - base[1]])
        predicted = jnp.concatenate(bd.checks.boost_terms(system, g, q, U, qdot, u))
        return observed, predicted

    return jax.vmap(one)(velocity)


@pytest.mark.parametrize("name", SYSTEMS)
def test_frame_terms_are_those_of_2_9_and_2_10(name, key):
    """The boosted scene's extra accelerations equal `boost_terms`, which is linear plus
    quadratic in the boost velocity u: f(2u) = 3 f(u) + f(-u)."""
    system = SYSTEMS[name]()
    d = system.shape_dim
    k = jax.random.split(key, 5)
    g = bd.lie.se3_exp(jax.random.normal(k[0], (6,)))
    q, qdot = 0.5 * jax.random.normal(k[1], (d,)), jax.random.normal(k[3], (d,))
    U, u = jax.random.normal(k[2], (6,)), jax.random.normal(k[4], (3,))
    observed, predicted = _frame_terms(system, g, q, U, qdot, jnp.stack([u, -u, 2 * u]))
    observed, predicted = np.asarray(observed), np.asarray(predicted)
    size = np.max(np.abs(observed))
    if name in INVARIANT:
        assert size <= 1e-12 and np.max(np.abs(predicted)) <= 1e-12
        return
    assert size > 1e-2
    np.testing.assert_allclose(observed, predicted, atol=1e-13 * size)
    np.testing.assert_allclose(observed[2], 3 * observed[0] + observed[1], atol=1e-12 * size)


@eqx.filter_jit
def _boosts(system, state):
    return jax.vmap(
        lambda s: bd.checks.boost_discrepancy(
            system, state, s * DIRECTION, 2.0, rtol=RTOL, atol=ATOL
        )
    )(SPEEDS)


def _generic_state(d):
    return bd.State(
        jnp.eye(4), 0.3 * jnp.ones(d), jnp.array([0.3, 0.2, -0.4, 0.1, 0.0, 0.2]), 0.5 * jnp.ones(d)
    )


def test_invariant_chain_moves_alike_in_every_galilean_frame():
    """Revolute, universal joints; boosts up to 4 m/s for 2 s: agreement to the solver tolerance."""
    result = _boosts(chain(3), chain3_state())
    assert np.max(result.shape) <= 1e-9
    assert np.max(result.pose) <= 1e-9  # over translations of up to 8 m


@pytest.mark.parametrize("name", [n for n in SYSTEMS if n not in INVARIANT])
def test_counterexamples_disagree_more_the_faster_the_boost(name):
    pose = np.asarray(_boosts(SYSTEMS[name](), _generic_state(SYSTEMS[name]().shape_dim)).pose)
    assert pose[0] <= 1e-12  # no boost, no difference
    assert np.all(pose[1:] > 1e-2)  # 1e7 times the tolerance of the invariant case
    assert np.all(np.diff(pose) > 0)


@eqx.filter_jit
def _falling(system, state, gravities):
    return jax.vmap(
        # RKMK54: its dense output at the compared times is as accurate as its steps, where
        # the default RKMK87's fifth-order one adds ~1e-9 at this tolerance.
        lambda gravity: bd.checks.gravity_discrepancy(
            system, gravity, state, 2.0, rtol=RTOL, atol=ATOL, solver=bd.RKMK54()
        )
    )(gravities)


@eqx.filter_jit  # one program, not one per primitive
def _translational_mass(system, q):
    return system.metric(q)[3, 3]


# The discrepancies compiled whole: eagerly, the poses' logarithms and the comparisons
# around the solve compile primitive by primitive.
_boost_discrepancy = eqx.filter_jit(bd.checks.boost_discrepancy)
_gravity_discrepancy = eqx.filter_jit(bd.checks.gravity_discrepancy)


def test_gravity_disappears_in_a_falling_frame_unless_the_centres_or_masses_differ():
    """Theorem 3.4 on a chain; the seed's remark: a centre of gravity 1 cm off the centre of mass,
    or a gravitational mass 1% above the inertial one, breaks it. In the latter case the whole
    system falls with 1.01 g, so from the falling frame it drifts by 0.01·g t²/2 (closed form)."""
    system, state = chain(3), chain3_state()
    m = _translational_mass(system, state.q)
    direction = jnp.array([0.1, 0.2, -1.0])
    variants = [
        bd.Gravity(9.81, direction, gravitational_mass=m, centre_offset=jnp.zeros(3)),
        bd.Gravity(
            9.81, direction, gravitational_mass=m, centre_offset=jnp.array([0.0, 0.01, 0.0])
        ),
        bd.Gravity(9.81, direction, gravitational_mass=1.01 * m, centre_offset=jnp.zeros(3)),
    ]
    result = _falling(system, state, jax.tree.map(lambda *x: jnp.stack(x), *variants))
    result = jax.tree.map(np.asarray, result)
    assert result.shape[0] <= 1e-9 and result.pose[0] <= 1e-9  # fell 19.6 m
    assert result.shape[1] > 1e-2 and result.pose[1] > 1e-2
    assert result.shape[2] <= 1e-9
    np.testing.assert_allclose(result.pose[2], 0.01 * 9.81 * 2.0**2 / 2, rtol=1e-8)


def test_an_imported_model_with_passive_joints_is_galilean_and_falls_with_its_gravity():
    """A gymnasium-style MJCF (rotor inertia, joint springs and dampers, a tendon's spring
    and damper, a ball joint, its own gravity):
    its motion is the same seen from a frame boosted by 3 m/s, and from a frame falling
    with the model's gravity it moves as without gravity (Theorems 2.2 and 3.4)."""
    from systems import PASSIVE

    with pytest.warns(UserWarning, match="tendon"), pytest.warns(UserWarning, match=r"'j2' \(ref"):
        scene = bd.Scene.from_mjcf(PASSIVE, passive=True, gravity=True)
    *passive, gravity = scene.effects
    assert isinstance(gravity, bd.Gravity) and len(passive) == 3
    state = _generic_state(scene.system.shape_dim)
    options = dict(rtol=RTOL, atol=ATOL, solver=bd.RKMK54())
    velocity = jnp.array([3.0, -1.0, 0.5])
    boosted = _boost_discrepancy(
        scene.system, state, velocity, 1.0, effects=tuple(passive), **options
    )
    falling = _gravity_discrepancy(
        scene.system, gravity, state, 1.0, effects=tuple(passive), **options
    )
    for result in (boosted, falling):
        assert np.max(result.shape) <= 1e-9 and np.max(result.pose) <= 1e-9


def test_gravity_discrepancy_is_differentiable_in_the_gravitational_mass():
    """A body whose gravitational mass is m_g ≠ m drifts from the falling frame by
    $(m_g/m - 1)\\,g t^2/2$, so the discrepancy's derivative in $m_g$ is $g t^2 / 2m$ (the
    poses agree exactly at t0, where a norm's gradient would be NaN)."""
    body = bd.RigidBody(2.0, jnp.zeros(3), jnp.diag(jnp.array([1.0, 2.0, 3.0])))
    state = bd.State(jnp.eye(4), xi=jnp.array([0.0, 0.0, 0.0, 0.5, 0.0, 0.2]))
    # Without rotation the motions are quadratic in t, which RK4's fixed steps integrate exactly.
    steps = dict(solver=bd.RKMK4(), dt0=0.25, stepsize_controller=diffrax.ConstantStepSize())

    def pose(m_g):
        gravity = bd.Gravity(9.81, jnp.array([0.0, 0.0, -1.0]), gravitational_mass=m_g)
        return bd.checks.gravity_discrepancy(body, gravity, state, 1.0, **steps).pose

    value, slope = jax.jit(jax.value_and_grad(pose))(2.02)
    np.testing.assert_allclose(value, 0.01 * 9.81 / 2, rtol=1e-12)
    np.testing.assert_allclose(slope, 9.81 / (2 * 2.0), rtol=1e-12)
