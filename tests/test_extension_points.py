"""The public extension points, and the run-time checks that survive `jax.jit`.

A user's own Lie-group tableau (`AbstractRKMK`), a user's own left-trivialized term
(`AbstractBodyTerm`), a scene's term driven by `diffrax.diffeqsolve` directly through the
state codec (`SceneTerm.encode`/`decode`); and the errors a traced NaN state, a traced pose
off SE(3) and a traced non-physical body raise.
"""

import re
from typing import ClassVar

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from systems import asymmetric_body, chain, chain3_state

import bundledyn as bd
from bundledyn import lie

OMEGA0 = jnp.array([0.3, 1.1, -0.4, 0.2, 0.0, 0.1])


class RKMK2(bd.AbstractRKMK, diffrax.AbstractAdaptiveSolver):
    """Heun's method on the group with the Euler step as its embedded error estimate: a
    user's own tableau, written only with the public names."""

    tableau: ClassVar[bd.LieButcherTableau] = bd.LieButcherTableau(
        a_lower=(np.array([1.0]),),
        b_sol=np.array([0.5, 0.5]),
        c=np.array([1.0]),
        dense=np.array([[1.0, 0.0], [-0.5, 0.5]]),
        b_error=np.array([-0.5, 0.5]),
    )
    dense_output: bool = eqx.field(default=True, static=True)

    def order(self, terms):
        return 2


@eqx.filter_jit
def _final_pose(solver, n):
    scene = bd.Scene(asymmetric_body())
    state = bd.State(jnp.eye(4), (), OMEGA0)
    traj = bd.simulate(
        scene,
        state,
        2.0,
        solver=solver,
        dt0=2.0 / n,
        stepsize_controller=diffrax.ConstantStepSize(),
    )
    return traj.g[-1]


def test_a_users_tableau_is_a_lie_group_solver_of_its_order():
    """The user's RKMK2 converges at order 2 against RKMK87 at a fine step, keeps the
    rotation orthogonal to rounding, and runs adaptively under diffrax's controller."""
    reference = _final_pose(bd.RKMK87(), 400)
    errors = [
        float(jnp.max(jnp.abs(lie.se3_log(lie.se3_inv(reference) @ _final_pose(RKMK2(), n)))))
        for n in (100, 200, 400)
    ]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(orders - 2.0) < 0.1), orders
    R = _final_pose(RKMK2(), 100)[:3, :3]
    assert np.abs(R.T @ R - np.eye(3)).max() < 1e-14
    assert isinstance(RKMK2(), bd.AbstractLieGroupSolver)
    traj = bd.simulate(bd.Scene(asymmetric_body()), bd.State(jnp.eye(4), (), OMEGA0), 2.0,
                       solver=RKMK2(), rtol=1e-6, atol=1e-6)  # fmt: skip
    assert bool(traj.result == diffrax.RESULTS.successful)
    assert "embedding_drift" not in traj.stats  # a Lie-group solver's poses are not projected
    assert float(jnp.max(jnp.abs(lie.se3_log(lie.se3_inv(reference) @ traj.g[-1])))) < 1e-4


class FreeRigidBody(bd.AbstractBodyTerm):
    """Euler's equations of a torque-free body written by hand as a body term: y = (g, ξ)."""

    inertia: jax.Array

    def body_vf(self, t, y, args):
        g, xi = y
        p = self.inertia @ xi
        return xi, jnp.linalg.solve(self.inertia, lie.ad(xi).T @ p)

    def contr(self, t0, t1, **kwargs):
        return t1 - t0

    def prod(self, vf, control):
        return jax.tree.map(lambda v: control * v, vf)


def test_a_users_body_term_and_the_scene_term_agree():
    """A hand-written body term, the scene's own term driven by `diffeqsolve` through the
    codec, and `simulate` give the same motion of the asymmetric body."""
    body = asymmetric_body()
    state = bd.State(jnp.eye(4), (), OMEGA0)
    controller = diffrax.PIDController(rtol=1e-11, atol=1e-11)
    mine = diffrax.diffeqsolve(
        FreeRigidBody(body.spatial_inertia()), bd.RKMK87(), 0.0, 1.5, 0.01,
        (state.g, state.xi), stepsize_controller=controller,
    )  # fmt: skip
    term = bd.SceneTerm(bd.Scene(body))
    theirs = diffrax.diffeqsolve(
        term, bd.RKMK87(), 0.0, 1.5, 0.01, term.encode(0.0, state),
        stepsize_controller=controller,
    )  # fmt: skip
    final = term.decode(1.5, jax.tree.map(lambda a: a[-1], theirs.ys))
    simulated = bd.simulate(bd.Scene(body), state, 1.5, rtol=1e-11, atol=1e-11)
    np.testing.assert_allclose(mine.ys[0][-1], final.g, atol=1e-9)
    np.testing.assert_allclose(mine.ys[1][-1], final.xi, atol=1e-9)
    np.testing.assert_allclose(simulated.g[-1], final.g, atol=1e-9)


def test_the_codec_round_trips_and_uses_the_locked_velocity():
    """encode puts U = ξ + A q̇ (`locked_velocity`) in the integration state; decode inverts it."""
    system = chain(3)
    state = chain3_state()
    term = bd.SceneTerm(bd.Scene(system))
    y = term.encode(0.0, state)
    _, q, U, qdot = term.unpack(0.0, y)
    np.testing.assert_allclose(U, bd.locked_velocity(system, state.q, state.xi, state.qdot))
    back = term.decode(0.0, y)
    for a, b in zip(jax.tree.leaves(back), jax.tree.leaves(state), strict=True):
        np.testing.assert_allclose(a, b, atol=1e-15)


# Run-time checks: values that are traced pass construction unchecked, and are checked
# when a solve uses them.


@jax.jit
def _solve_from(g, xi):
    scene = bd.Scene(asymmetric_body())
    return bd.simulate(scene, bd.State(g, (), xi), 0.5).g[-1]


@pytest.mark.parametrize(
    "g, xi, message",
    [
        (jnp.eye(4), OMEGA0.at[2].set(jnp.nan), "NaN or infinite"),
        (jnp.eye(4).at[0, 3].set(jnp.inf), OMEGA0, "NaN or infinite"),
        (jnp.eye(4).at[0, 1].set(1e-3), OMEGA0, "must be a pose in SE(3)"),
        (jnp.diag(jnp.array([1.0, 1.0, -1.0, 1.0])), OMEGA0, "must be a pose in SE(3)"),
        (jnp.eye(4).at[3, 0].set(0.5), OMEGA0, "must be a pose in SE(3)"),
    ],
    ids=["nan-velocity", "inf-position", "not-orthogonal", "reflection", "bottom-row"],
)
def test_a_traced_bad_state_raises_inside_jit(g, xi, message):
    with pytest.raises(Exception, match=re.escape(message)):
        jax.block_until_ready(_solve_from(g, xi))


def test_a_traced_good_state_passes_and_a_batch_with_one_bad_member_raises():
    np.testing.assert_allclose(
        _solve_from(jnp.eye(4), OMEGA0),
        bd.simulate(bd.Scene(asymmetric_body()), bd.State(jnp.eye(4), (), OMEGA0), 0.5).g[-1],
        atol=1e-14,
    )
    batch = jnp.stack([OMEGA0, OMEGA0.at[0].set(jnp.nan)])
    with pytest.raises(Exception, match="NaN or infinite"):
        jax.block_until_ready(jax.vmap(_solve_from, in_axes=(None, 0))(jnp.eye(4), batch))


@jax.jit
def _solve_with(mass, inertia):
    body = eqx.tree_at(lambda b: (b.mass, b.inertia), asymmetric_body(), (mass, inertia))
    return bd.simulate(bd.Scene(body), bd.State(jnp.eye(4), (), OMEGA0), 0.5).g[-1]


J = jnp.asarray(asymmetric_body().inertia)


@pytest.mark.parametrize(
    "mass, inertia, message",
    [
        (-2.0, J, "RigidBody.mass` must be finite and positive"),
        (2.0, J.at[0, 0].set(-0.3), "positive definite"),
        (2.0, J.at[0, 1].add(0.05), "must be symmetric"),
        (2.0, jnp.diag(jnp.array([0.1, 0.1, 0.5])), "triangle inequality"),
    ],
    ids=["negative-mass", "indefinite", "non-symmetric", "triangle"],
)
def test_a_traced_non_physical_body_raises(mass, inertia, message):
    """What an unconstrained optimizer step can produce is refused, not simulated."""
    with pytest.raises(Exception, match=re.escape(message)):
        jax.block_until_ready(_solve_with(jnp.asarray(mass), inertia))


def test_checks_do_not_change_gradients_and_inertia_gradients_are_symmetric():
    """The gradient of a rollout in a raw 3×3 inertia is symmetric (only the symmetric part
    enters the dynamics) and equals central differences along symmetric perturbations."""

    def loss(inertia):
        g = _solve_with(jnp.asarray(2.0), inertia)
        return jnp.sum(jnp.sin(jnp.arange(1.0, 13.0)) * g[:3].ravel())

    grad = jax.grad(loss)(J)
    np.testing.assert_allclose(grad, grad.T, rtol=0, atol=1e-15)
    E = jnp.zeros((3, 3)).at[0, 1].set(1.0).at[1, 0].set(1.0)
    h = 1e-6
    fd = (loss(J + h * E) - loss(J - h * E)) / (2 * h)
    np.testing.assert_allclose(jnp.sum(grad * E), fd, rtol=1e-7)


@pytest.mark.parametrize(
    "cls, abstract",
    [
        (bd.AbstractMetricJet, {"along", "along_applied", "forms", "forms_along", "along_both",
                                "derivative"}),
        (bd.AbstractEffect, {"generalized_force"}),
    ],
    ids=["metric-jet", "effect"],
)  # fmt: skip
def test_the_extension_points_have_abstract_methods_only(cls, abstract):
    """An abstract class that users subclass holds no behaviour to override: its methods are
    all abstract (the metric jet's shared forms are module-level functions its final jets
    call; a potential is `AbstractPotential`'s, not every effect's)."""
    methods = {
        name
        for name, value in vars(cls).items()
        if callable(value) and not (name.startswith("__") and name.endswith("__"))
    }
    assert methods == abstract
    assert all(getattr(cls, name).__isabstractmethod__ for name in methods)
    assert not hasattr(bd.AbstractEffect, "potential")
    assert bd.AbstractPotential.potential.__isabstractmethod__
