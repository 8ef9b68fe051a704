"""`StoredStepsAdjoint` gives the gradients of diffrax's `RecursiveCheckpointAdjoint`:
for every Lie-group solver, with saves between steps, at the steps, and at an event; and,
on a chain under gravity, a spring and a damper, those of forward-mode sensitivities."""

import functools

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pytest
from registry import ADJOINTS, SOLVERS
from systems import asymmetric_body, chain

import bundledyn as bd
from bundledyn import _reverse_term
from bundledyn._simulate import default_adjoint

T1 = 1.0
TS = jnp.linspace(0.0, T1, 7)


def _rigid_case():
    scene = bd.Scene(asymmetric_body())
    xi = jnp.array([0.3, 2.0, -0.4, 0.1, 0.0, 0.2])
    return scene, bd.State(jnp.eye(4), jnp.zeros(0), xi, jnp.zeros(0))


def _chain_case():
    scene = bd.Scene(chain(3))  # a hinge and a universal joint
    xi = jnp.array([0.3, 0.2, -0.4, 0.1, 0.0, 0.2])
    return scene, bd.State(jnp.eye(4), jnp.array([0.2, -0.1, 0.3]), xi, jnp.array([0.5, -0.4, 0.3]))


def _chain_effects_case():
    scene, state = _chain_case()
    effects = [bd.Gravity(9.81, (0.2, 0.0, -1.0)), bd.ShapeSpring(0.8), bd.ShapeDamper(0.3)]
    return bd.Scene(scene.system, effects), state


CASES = {"rigid": _rigid_case, "chain": _chain_case, "chain, effects": _chain_effects_case}


def _finite(a):
    return jnp.where(jnp.isfinite(a), a, 0.0)


def _loss(case, adjoint, options, params):
    """A loss on everything a trajectory saves (poses, shapes, velocities, times), as a
    function of the initial twist and the bodies' rotational inertias."""
    scene, state = CASES[case]()
    xi, inertia = params
    scene = eqx.tree_at(lambda s: s.system.inertia, scene, inertia)
    state = bd.State(state.g, state.q, xi, state.qdot)
    traj = bd.simulate(scene, state, T1, adjoint=adjoint, rtol=1e-8, atol=1e-8, **options)
    # Each save counts differently.
    weights = 1.0 + jnp.arange(traj.ts.shape[0], dtype=float)[:, None]
    parts = [traj.g.reshape(len(traj.ts), -1), traj.U, traj.q, traj.ts[:, None]]
    steps = (traj.stats["num_accepted_steps"], traj.stats["num_rejected_steps"])
    return sum(jnp.sum(weights * _finite(p) ** 2) for p in parts), steps


def _params(case):
    scene, state = CASES[case]()
    return state.xi, scene.system.inertia


@functools.cache
def _gradient(case, adjoint, options_key):
    options = dict(OPTIONS[options_key])
    # diffrax's forward-mode sensitivities: a reference in forward mode (`jacfwd`).
    derivative = jax.jacfwd if isinstance(adjoint, diffrax.ForwardMode) else jax.grad
    return jax.jit(derivative(functools.partial(_loss, case, adjoint, options), has_aux=True))


CROSSING = 0.15  # the chain's section frame crosses it after 6 steps (4 with thrice the twist)


def _crossing(t, y, args, **kwargs):
    return y[0][0, 3] - CROSSING  # the section frame's x


def _past(t, y, args, **kwargs):
    return y[0][0, 3] > 0.05


OPTIONS = {
    "RKMK87 ts": dict(saveat=diffrax.SaveAt(t0=True, ts=TS, t1=True)),
    # A first step far too long: the controller rejects steps, which the record skips.
    "RKMK54 ts": dict(solver=SOLVERS["RKMK54"], dt0=0.8, saveat=diffrax.SaveAt(ts=TS, t1=True)),
    "RKMK4 ts": dict(solver=SOLVERS["RKMK4"], dt0=0.05, saveat=diffrax.SaveAt(ts=TS, t1=True)),
    "LieEuler ts": dict(
        solver=SOLVERS["LieEuler"], dt0=0.05, saveat=diffrax.SaveAt(ts=TS, t1=True)
    ),
    "VariationalMidpoint ts": dict(
        solver=SOLVERS["VariationalMidpoint"], dt0=0.05, saveat=diffrax.SaveAt(ts=TS, t1=True)
    ),
    # Where the saves or the event are the point, not the solver: RKMK4, 4 stages a step.
    "RKMK4 steps": dict(
        solver=SOLVERS["RKMK4"],
        dt0=0.1,
        stepsize_controller=diffrax.ConstantStepSize(),
        saveat=diffrax.SaveAt(t0=True, steps=True),
    ),
    "RKMK87 event": dict(
        event=diffrax.Event(_crossing, optx.Newton(1e-12, 1e-12)),
        saveat=diffrax.SaveAt(ts=TS, t1=True),
    ),
    "RKMK4 boolean event": dict(solver=SOLVERS["RKMK4"], dt0=0.05, event=diffrax.Event(_past)),
}

CHECKPOINTED = ADJOINTS["checkpointed"]
# Where the solver is not the point (the chain under effects, its field's reverse pass), the
# reference is forward-mode sensitivities: a derivation sharing nothing with either reverse
# sweep, and cheaper to compile than the checkpointed gradient.
FORWARD = ADJOINTS["forward"]
STORED = ADJOINTS["stored steps"]
AUTODIFF_FIELD = ADJOINTS["stored steps, autodiff field"]


def _kept_bytes(stages):
    """What `StoredStepsAdjoint` keeps of a step on the chain: its start state (a pose and
    x = (q, U, qdot), 16 + 12 float64) and the field's values at its stages (a twist and
    the rate of x, 6 + 12 float64 each)."""
    return (16 + 12 + stages * (6 + 12)) * 8


# Two steps of RKMK87 with its dense output (14 stages): the reverse sweep steps the others
# again, in blocks of two steps.
KEPT_STEPS = 2
REFILLED = bd.StoredStepsAdjoint(stage_memory=KEPT_STEPS * _kept_bytes(14))


def _assert_gradients_equal(ours, reference):
    """Equal to 1e-10 of each gradient's largest entry, from solves that took the same
    steps (a step accepted in one and rejected in the other, after rounding differences
    between the two compiled programs, would move the solution by the tolerance)."""
    (ours, our_steps), (reference, reference_steps) = ours, reference
    assert [int(n) for n in our_steps] == [int(n) for n in reference_steps]
    for a, b in zip(jax.tree.leaves(ours), jax.tree.leaves(reference), strict=True):
        a, b = np.asarray(a), np.asarray(b)
        scale = float(np.max(np.abs(b)))
        assert scale > 0.0  # every input moves the loss
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-10 * scale)


# LieEuler's and RKMK4's step reverse passes are checked everyday by test_stage_reverse.py
# and RKMK4's solve by the chain below; their whole-solve gradients are in the slow part.
_SLOW_OPTIONS = ("LieEuler ts", "RKMK4 ts")


@pytest.mark.parametrize(
    "case, options",
    [
        pytest.param("rigid", key, marks=[pytest.mark.slow] if key in _SLOW_OPTIONS else [])
        for key in OPTIONS
        if key != "RKMK87 event"
    ],
)
def test_stored_steps_gradients_equal_checkpointed_ones(case, options):
    params = _params(case)
    ours = _gradient(case, STORED, options)(params)
    if options == "RKMK54 ts":
        assert int(ours[1][1]) > 0  # rejected steps
    _assert_gradients_equal(ours, _gradient(case, CHECKPOINTED, options)(params))


@functools.cache
def _twist_gradient(case, adjoint, options_key):
    """The gradient with respect to the initial twist alone: the scene held constant,
    whose numbers the reverse sweep then does not differentiate."""
    options = dict(OPTIONS[options_key])

    def loss(xi):
        return _loss(case, adjoint, options, (xi, CASES[case]()[0].system.inertia))

    return jax.jit(jax.grad(loss, has_aux=True))


@pytest.mark.parametrize("adjoint", [STORED, AUTODIFF_FIELD], ids=["hand-derived", "autodiff"])
def test_through_a_chains_field_gradients_equal_forward_mode_ones(adjoint):
    # A chain under gravity, a spring and a damper, its scene differentiated too:
    # `StoredStepsAdjoint` steps the field with its reverse pass (`ReverseModeSceneTerm`,
    # by default) or autodiff's; the reference pushes tangents forward through the solve.
    case, options = "chain, effects", "RKMK4 ts"
    params = _params(case)
    _assert_gradients_equal(
        _gradient(case, adjoint, options)(params), _gradient(case, FORWARD, options)(params)
    )


@pytest.mark.parametrize(
    "case, options, reference",
    [("rigid", "RKMK87 ts", CHECKPOINTED), ("chain, effects", "RKMK4 ts", FORWARD)],
    ids=["rigid", "chain, effects"],
)
def test_with_the_scene_held_constant_gradients_equal_the_references(case, options, reference):
    # On the chain, the field's written-out reverse pass alone (no autodiff for the scene).
    # (That pass at single states: tests/test_field_vjp.py.) The reference's gradient with
    # respect to the twist is the twist's part of its gradient with respect to both.
    params = _params(case)
    (expected, _), steps = _gradient(case, reference, options)(params)
    _assert_gradients_equal(_twist_gradient(case, STORED, options)(params[0]), (expected, steps))


def test_the_recursions_reverse_pass_gives_the_forward_mode_gradient(monkeypatch):
    # On large trees the reverse sweep differentiates the field by the articulated-body
    # recursions' written-out pass (`_reverse_term._state_pass`); with the dense pass's
    # threshold lowered, the chain takes it. (That pass at single states:
    # tests/test_field_vjp.py.)
    monkeypatch.setattr(_reverse_term, "_DENSE_MOST_COORDINATES", 0)
    case, options = "chain, effects", "RKMK4 ts"
    scene = CASES[case]()[0]
    assert _reverse_term._state_pass(scene) is _reverse_term._articulated_state_vjp
    params = _params(case)
    (expected, _), steps = _gradient(case, FORWARD, options)(params)
    ours = _twist_gradient.__wrapped__(case, STORED, options)(params[0])  # traced here
    _assert_gradients_equal(ours, (expected, steps))


def test_a_derivative_in_the_horizon_is_refused_naming_the_adjoint_that_gives_it():
    scene, state = CASES["rigid"]()

    def final(t1, adjoint):
        traj = bd.simulate(scene, state, t1, adjoint=adjoint, rtol=1e-10, atol=1e-10)
        return jnp.sum(traj.g[-1, :3, 3]) + jnp.sum(traj.xi[-1])

    with pytest.raises(
        RuntimeError, match=r"`t1`.*adjoint=diffrax\.RecursiveCheckpointAdjoint\(\)"
    ):
        jax.grad(final)(T1, STORED)
    # Compiled whole: one program for both horizons (`t1` is traced), one for the gradient.
    h = 1e-5
    value = jax.jit(final, static_argnums=1)
    differences = (float(value(T1 + h, STORED)) - float(value(T1 - h, STORED))) / (2 * h)
    gradient = jax.jit(jax.grad(final), static_argnums=1)(T1, CHECKPOINTED)
    np.testing.assert_allclose(float(gradient), differences, rtol=1e-7)


def test_an_unknown_field_reverse_pass_is_refused():
    with pytest.raises(ValueError, match="'autodiff' or 'hand-derived'"):
        bd.StoredStepsAdjoint(field_reverse="manual")


def test_the_event_stops_the_solve_at_its_root():
    # The event case measures what it claims: the solve ends at the condition's root,
    # before t1 and at none of the other save times.
    traj = bd.simulate(*CASES["chain"](), T1, **OPTIONS["RKMK87 event"], rtol=1e-8, atol=1e-8)
    ts, g = np.asarray(traj.ts), np.asarray(traj.g)
    last = int(np.argmax(np.where(np.isfinite(ts), ts, -np.inf)))
    assert 0.0 < ts[last] < T1
    assert not np.any(ts[last] == np.asarray(TS))
    np.testing.assert_allclose(g[last, 0, 3], CROSSING, atol=1e-12)


def test_past_its_memory_budget_the_adjoint_falls_back_to_checkpointing():
    case, options = "rigid", "RKMK87 ts"
    frugal = bd.StoredStepsAdjoint(max_memory=1024)
    scene, state = CASES[case]()
    y0 = bd.SceneTerm(scene).encode(0.0, state)
    state_bytes = sum(x.size * x.dtype.itemsize for x in jax.tree.leaves(y0))
    assert 16384 * state_bytes > frugal.max_memory  # simulate's max_steps do not fit
    calls = []
    fallback = frugal.fallback

    class Counting(type(fallback)):
        def loop(self, **kwargs):
            calls.append(True)
            return super().loop(**kwargs)

    frugal = eqx.tree_at(lambda a: a.fallback, frugal, Counting())
    loss = functools.partial(_loss, case, frugal, dict(OPTIONS[options]))
    ours = jax.jit(jax.grad(loss, has_aux=True))(_params(case))
    assert calls  # the fallback differentiated the solve
    _assert_gradients_equal(ours, _gradient(case, CHECKPOINTED, options)(_params(case)))


@pytest.mark.parametrize(
    "case, options, adjoint",
    [
        ("rigid", "RKMK87 ts", STORED),
        # The chain's two checkpointed gradients, batched: a minute's compiling, so slow;
        # refilled blocks are checked everyday by the evaluation counts below.
        pytest.param("chain", "RKMK87 event", REFILLED, marks=pytest.mark.slow),
    ],
    ids=["rigid", "chain, event, refilled"],
)
def test_batched_gradients_of_members_taking_different_steps(case, options, adjoint):
    # Under vmap the reverse sweep runs to the longest member's steps; the others must
    # discard the extra sweeps. On the chain each member stops at its own event, and the
    # stage values of only a few steps are kept, so each member evaluates those of its
    # other steps again, in its own blocks.
    xi, inertia = _params(case)
    xis = jnp.stack([xi, 3.0 * xi])

    def batched(adjoint):
        loss = functools.partial(_loss, case, adjoint, dict(OPTIONS[options]))
        grad = jax.vmap(jax.grad(loss, has_aux=True), in_axes=((0, None),))
        return jax.jit(grad)((xis, inertia))

    # Against diffrax's, batched too: a batched solve rounds otherwise than one member's
    # alone (3e-10 of the gradient on the chain, either adjoint), the steps being the same.
    ours, reference = batched(adjoint), batched(CHECKPOINTED)
    accepted = ours[1][0]
    assert accepted[0] != accepted[1]
    # Blocks refilled: in each member, and in one of them more than one block.
    assert case == "rigid" or (min(accepted) > KEPT_STEPS and max(accepted) > 2 * KEPT_STEPS)
    for i in range(len(xis)):
        member = functools.partial(jax.tree.map, lambda a, i=i: a[i])
        _assert_gradients_equal(member(ours), member(reference))


def test_simulate_differentiates_its_lie_group_solvers_with_stored_steps():
    assert isinstance(default_adjoint(bd.RKMK87()), bd.StoredStepsAdjoint)
    assert isinstance(default_adjoint(bd.VariationalMidpoint()), bd.StoredStepsAdjoint)
    assert isinstance(default_adjoint(diffrax.Dopri8()), diffrax.RecursiveCheckpointAdjoint)


def _counted_evaluations(adjoint, differentiate, base=None):
    """How many times the chain's field is evaluated in a fixed-step solve of 20 RKMK4
    steps, or in its gradient with respect to the initial twist (initial shape velocity
    on a `base`)."""
    scene, state = CASES["chain"]()
    count = []

    def shape_force(t, q, qdot):
        jax.debug.callback(lambda: count.append(1))
        return -0.3 * qdot

    scene = bd.Scene(scene.system, [bd.ShapeForce(shape_force)], base=base)

    def loss(velocity):
        xi, qdot = (velocity, state.qdot) if base is None else (state.xi, velocity)
        traj = bd.simulate(
            scene,
            bd.State(state.g, state.q, xi, qdot),
            T1,
            solver=bd.RKMK4(),
            dt0=T1 / 20,
            stepsize_controller=diffrax.ConstantStepSize(),
            adjoint=adjoint,
        )
        return jnp.sum(traj.xi[-1] ** 2) + jnp.sum(traj.qdot[-1] ** 2)

    velocity = state.xi if base is None else state.qdot
    jax.block_until_ready((jax.grad(loss) if differentiate else loss)(velocity))
    jax.effects_barrier()
    return len(count)


@pytest.mark.slow  # seven solves compiled, each forward and reverse
def test_the_reverse_sweep_replays_the_fields_values_kept_by_the_forward_solve():
    # The reverse sweep evaluates the field's forces once per stage, in its written-out
    # pass, and the field itself only at the steps that were not kept, stepped again.
    forward = _counted_evaluations(STORED, differentiate=False)
    assert forward == 20 * 4
    assert _counted_evaluations(STORED, differentiate=True) - forward == forward
    # REFILLED keeps 5 of the 20 RKMK4 steps; the others are stepped again.
    kept = REFILLED.stage_memory // _kept_bytes(4)
    assert kept == 5
    refilled = _counted_evaluations(REFILLED, differentiate=True) - forward
    assert refilled == forward + (20 - kept) * 4
    # Without kept values, every stage's field is evaluated again (at least).
    unkept = bd.StoredStepsAdjoint(stage_memory=0)
    assert _counted_evaluations(unkept, differentiate=True) - forward >= 2 * forward
    # On a held base, where the pass is autodiff's VJP of the field, the reverse sweep
    # evaluates each kept stage's field once, inside that VJP, and no stage again.
    held = bd.PrescribedBase.fixed()
    forward = _counted_evaluations(STORED, differentiate=False, base=held)
    assert forward == 20 * 4
    assert _counted_evaluations(STORED, differentiate=True, base=held) - forward == forward
