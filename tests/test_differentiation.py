"""Differentiation and batching through `simulate` (issue: dynamics)."""

import functools

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from systems import affine_body, chain, chain3_state

import bundledyn as bd

THREE = chain(3)
THREE_STATE = chain3_state()


def _rollout_loss(params, adjoint=None):
    """A loss on the final state; params = (ξ0 (6), body masses (3), spring stiffness (1)).

    Without an adjoint: fixed-step RKMK4, whose discrete map the checkpoint adjoint
    differentiates exactly. With one: adaptive RKMK54 at rtol 1e-10 (the backsolve adjoint
    integrates the continuous adjoint equation, backwards, on the group).
    """
    system = eqx.tree_at(lambda s: s.mass, THREE, params[6:9])
    scene = bd.Scene(system, (bd.ShapeSpring(params[9]),))
    state = eqx.tree_at(lambda s: s.xi, THREE_STATE, params[:6])
    if adjoint is None:
        traj = bd.simulate(scene, state, 0.5, solver=bd.RKMK4(), dt0=0.005)
    else:
        traj = bd.simulate(scene, state, 0.5, rtol=1e-10, atol=1e-10, adjoint=adjoint)
    return (
        jnp.sin(jnp.arange(1, 4)) @ traj.q[-1] + traj.g[-1, 0, 3] + 0.1 * traj.xi[-1] @ traj.xi[-1]
    )


PARAMS = jnp.concatenate([THREE_STATE.xi, THREE.mass, jnp.array([2.0])])


def _central_differences(f, x, h, compiled=False):
    """Rows (f(x + h eᵢ) - f(x - h eᵢ)) / 2h. One compiled unbatched `f`, called 2n times:
    for the rollout, cheaper than compiling a vmap of them. `compiled`: `f` reads the
    values off a program compiled already (compiling it again inside a new one, not)."""
    f = f if compiled else jax.jit(f)
    x = np.asarray(x)
    return np.array(
        [(np.asarray(f(x + e)) - np.asarray(f(x - e))) / (2 * h) for e in h * np.eye(x.shape[0])]
    )


# The loss and its gradient (checkpoint adjoint) in one compiled program: the differences
# below take its values, the gradient test its gradient (one solve compiled, not two).
_ROLLOUT_VALUE_AND_GRAD = jax.jit(jax.value_and_grad(_rollout_loss))


@functools.cache
def _finite_difference_gradient(h=1e-5):
    return _central_differences(lambda p: _ROLLOUT_VALUE_AND_GRAD(p)[0], PARAMS, h, True)


def test_gradient_through_simulate_matches_finite_differences():
    """jax.grad (checkpoint adjoint) w.r.t. initial state, masses and spring stiffness, 1e-6."""
    _, grad = _ROLLOUT_VALUE_AND_GRAD(PARAMS)
    np.testing.assert_allclose(grad, _finite_difference_gradient(), rtol=1e-6, atol=1e-9)


def test_backsolve_gradient_matches_finite_differences():
    """diffrax.BacksolveAdjoint through the default Lie-group solver agrees too."""
    adjoint = diffrax.BacksolveAdjoint(
        stepsize_controller=diffrax.PIDController(rtol=1e-10, atol=1e-10)
    )
    grad = jax.jit(jax.grad(lambda p: _rollout_loss(p, adjoint)))(PARAMS)
    fd = _finite_difference_gradient()
    # 1e-6 relative to the gradient's scale: the continuous adjoint is compared with a
    # discrete map whose own error is ~1e-7 on the smallest components.
    np.testing.assert_allclose(grad, fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())


def test_backsolve_on_a_scene_without_effects():
    """A scene with no effects (an empty effect list) differentiates under BacksolveAdjoint."""
    body = bd.RigidBody(2.0, [0.05, -0.02, 0.1], np.diag([0.3, 0.45, 0.6]))

    def loss(xi, adjoint):
        traj = bd.simulate(
            bd.Scene(body),
            bd.State(jnp.eye(4), (), xi),
            2.0,
            rtol=1e-10,
            atol=1e-10,
            adjoint=adjoint,
        )
        return traj.g[-1, 0, 3] + traj.g[-1, 1, 0]

    xi = jnp.array([0.3, 1.0, -0.2, 0.1, 0.0, 0.2])
    backsolve = diffrax.BacksolveAdjoint(
        stepsize_controller=diffrax.PIDController(rtol=1e-10, atol=1e-10)
    )
    grad = jax.jit(jax.grad(lambda x: loss(x, backsolve)))(xi)
    reference = jax.jit(jax.grad(lambda x: loss(x, diffrax.RecursiveCheckpointAdjoint())))(xi)
    np.testing.assert_allclose(grad, reference, rtol=1e-6, atol=1e-8)


def test_vmap_over_initial_states_and_parameters_equals_a_loop(key):
    """jax.vmap over 64 initial states and spring stiffnesses gives what single solves give,
    with the default solver (measured: 2.8e-13; RKMK54 6.9e-15). Before `simulate` chose a
    starting step, RKMK87's first step of 0.01 had an error estimate at the level of
    rounding, so batched and single solves chose different step sequences (1e-9)."""
    xi0 = 0.5 * jax.random.normal(key, (64, 6))
    stiffness = jnp.linspace(0.5, 5.0, 64)

    @jax.jit
    def run(xi, k):
        state = eqx.tree_at(lambda s: s.xi, THREE_STATE, xi)
        scene = bd.Scene(THREE, (bd.ShapeSpring(k),))
        return bd.simulate(scene, state, 1.0).g[-1]

    batched = jax.jit(jax.vmap(run))(xi0, stiffness)
    looped = jnp.stack([run(x, k) for x, k in zip(xi0[:8], stiffness[:8], strict=True)])
    np.testing.assert_allclose(batched[:8], looped, rtol=1e-9, atol=1e-11)


def test_gradient_of_the_affine_body_field_at_its_undeformed_shape():
    """jax.grad of the affine body's vector field at q = 0, where all three eigenvalues of the
    stretch coincide (the closed-form metric jet's eigenvectors are undefined there and are
    not differentiated), w.r.t. the whole state x = (q, U, q̇), against central differences
    (1e-7). Gradients through `simulate` differentiate this field; the solver's part is
    checked on the chain above."""
    scene = bd.Scene(affine_body(), (bd.ShapeSpring(jnp.linspace(1.0, 3.0, 6)),))
    g0 = jnp.eye(4)

    def loss(x):
        return jnp.sin(jnp.arange(1.0, 19.0)) @ bd.SceneTerm(scene).vf(0.0, (g0, x), None)[1]

    x0 = jnp.concatenate(
        [jnp.zeros(6), jnp.array([0.3, -0.2, 0.5, 0.1, 0.0, 0.2]), jnp.cos(jnp.arange(6.0))]
    )
    grad = jax.jit(jax.grad(loss))(x0)
    fd = _central_differences(loss, x0, 1e-6)
    assert np.all(np.isfinite(grad))
    np.testing.assert_allclose(grad, fd, rtol=1e-7, atol=1e-8 * np.abs(fd).max())


def test_second_derivatives_of_the_affine_stretch_jet_at_its_undeformed_shape():
    """Differentiating a gradient (Hessians, or grad of a loss on a gradient) of the affine
    metric jet at q = 0 stays finite and equals central differences of the gradient (1e-8):
    it goes through autodiff of `expm`, never through the eigenvectors."""
    from bundledyn._systems._affine_body import stretch_derivatives

    def f(q):
        U, dU, d2U = stretch_derivatives(q)
        return jnp.sum(jnp.sin(U)) + jnp.sum(jnp.sin(dU)) + jnp.sum(jnp.sin(d2U))

    hessian = jax.jit(jax.hessian(f))(jnp.zeros(6))
    fd = _central_differences(jax.grad(f), jnp.zeros(6), 1e-5)
    assert np.all(np.isfinite(hessian))
    np.testing.assert_allclose(hessian, fd, rtol=0, atol=1e-8 * np.abs(fd).max())


def test_second_derivatives_of_a_solver_step_at_the_undeformed_shape():
    """Forward-over-forward second derivatives of one Lie–Euler step of the affine body in
    its shape q, at q = 0 (all three stretches equal), are finite and equal central
    differences of its Jacobian (1e-8 of the largest entry; the differences' own error is
    ~1e-10). Reverse-first ones (`jax.hessian`) are NaN there: inside the stage loop's
    `lax.scan`, JAX drops custom JVP rules (see `stretch_derivatives`)."""
    scene = bd.Scene(affine_body())
    xi = jnp.array([0.3, -0.2, 0.1, 0.5, 0.0, 0.2])
    term, solver = bd.SceneTerm(scene), bd.LieEuler()
    g0, x0 = term.encode(0.0, bd.State(jnp.eye(4), jnp.zeros(6), xi, 0.1 * jnp.ones(6)))

    def step(q):
        (g1, x1), *_ = solver.step(term, 0.0, 0.05, (g0, x0.at[:6].set(q)), None, None, False)
        return jnp.concatenate([x1, g1[:3].ravel()])

    # One program gives both: the second derivatives, and the Jacobian as its auxiliary output
    # (the differences take that, at the shifted shapes).
    def jacobian_twice(q):
        jacobian = jax.jacfwd(step)(q)
        return jacobian, jacobian

    both = jax.jit(jax.jacfwd(jacobian_twice, has_aux=True))
    second, _ = both(jnp.zeros(6))
    fd = np.moveaxis(_central_differences(lambda q: both(q)[1], jnp.zeros(6), 1e-5, True), 0, -1)
    assert np.all(np.isfinite(second))
    np.testing.assert_allclose(second, fd, rtol=0, atol=1e-8 * np.abs(fd).max())
