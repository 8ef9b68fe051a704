"""The field's hand-derived reverse pass (`body_field_vjp`, used by `StoredStepsAdjoint`)
equals autodiff of the reference (Hamel) form and central differences, on every system
kind with a shape, at generic and singular states."""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from systems import SYSTEMS, chain

import bundledyn as bd
from bundledyn._dynamics import reference_accelerations
from bundledyn._effects import Kinematics
from bundledyn._geometry import connection
from bundledyn._reverse_term import (
    _DENSE_MOST_COORDINATES,
    _DENSE_MOST_DRIVEN_COORDINATES,
    _articulated_driven_state_vjp,
    _articulated_state_vjp,
    _driven_state_vjp,
    _field,
    _state_pass,
    _state_vjp,
    written_out,
)
from bundledyn._systems._ball_chart import ball_columns
from bundledyn._term import (
    ReplayedSceneTerm,
    ReverseModeSceneTerm,
    for_replay,
    for_reverse_mode,
)

SHAPED = [name for name, make in SYSTEMS.items() if make().shape_dim > 0]
# Every shaped system at a generic state; the singular states on systems that have them:
# at rest (ω = 0) a tree and the affine body, θ = 0 and θ near π on the ball-joint trees.
# The imported chain's field is the same code as `chain5`'s, with MuJoCo's numbers: a program
# of its own to compile, so in the slow part.
_IMPORTED = pytest.mark.slow
CASES = [
    pytest.param(name, "generic", marks=[_IMPORTED] if name == "mjcf_chain5" else [])
    for name in SHAPED
] + [
    ("chain5", "rest"),
    ("affine_body", "rest"),
    ("chain5", "zero shape"),
    pytest.param("mjcf_chain5", "zero shape", marks=_IMPORTED),
    ("chain5", "ball near pi"),
    pytest.param("mjcf_chain5", "ball near pi", marks=_IMPORTED),
]


def _scene(name):
    system = SYSTEMS[name]()
    d = system.shape_dim
    effects = [
        bd.Gravity(9.81, (0.3, -0.2, -1.0)),
        bd.ShapeSpring(0.7 + 0.1 * jnp.arange(d, dtype=float)),
        bd.ShapeDamper(0.2),
    ]
    return bd.Scene(system, effects)


def _state(system, kind, key):
    """`(g, x)` with `x = [q, U, q̇]`: generic; at rest (ω = 0, q̇ = 0); at the zero shape
    (every ball joint at θ = 0); or with every ball joint's rotation at π - 1e-6."""
    d = system.shape_dim
    k = jax.random.split(key, 4)
    g = bd.lie.se3_exp(0.5 * jax.random.normal(k[0], (6,)))
    q = 0.5 * jax.random.normal(k[1], (d,))
    U = jax.random.normal(k[2], (6,))
    qdot = jax.random.normal(k[3], (d,))
    if kind == "rest":
        U, qdot = jnp.zeros(6), jnp.zeros(d)
    if kind == "zero shape":
        q = jnp.zeros(d)
    if kind == "ball near pi":
        for cols in ball_columns(system):
            q = q.at[cols].set((np.pi - 1e-6) * jnp.array([0.6, 0.0, 0.8]))
    return g, jnp.concatenate([q, U, qdot])


def _reference_field(scene, t, y):
    r"""The field in $(q, U, \dot q)$ from the reference form alone: $\xi = U - A\dot q$,
    $(\dot\xi, \ddot q)$ of `reference_accelerations` (autodiff's metric derivative) and
    $\dot U = \dot\xi + \tfrac{d}{dt}(A\dot q)$."""
    g, x = y
    system = scene.system
    d = system.shape_dim
    q, U, qdot = x[:d], x[d : d + 6], x[d + 6 :]
    xi = U - connection(system, q) @ qdot
    F, Q = scene.forces(Kinematics(t, g, q, xi, qdot))
    xi_dot, qddot = reference_accelerations(system, q, xi, qdot, F, Q)
    _, dA_qdot = jax.jvp(lambda q: connection(system, q) @ qdot, (q,), (qdot,))
    Udot = xi_dot + dA_qdot + connection(system, q) @ qddot
    return xi, jnp.concatenate([qdot, Udot, qddot])


def _reverse_field(scene, t, y):
    return ReverseModeSceneTerm(scene).body_vf(t, y, None)


@functools.cache
def _pullback(name, both):
    """The hand-derived field's value and VJP on system `name`, compiled once for every
    state of the system: with respect to the state and the scene's numbers, or to the state
    alone (the scene held constant). The central differences below read the value off it."""
    static = eqx.partition(_scene(name), eqx.is_inexact_array)[1]

    def run(params, y, cotangent):
        if both:
            out, vjp = jax.vjp(
                lambda p, y: _reverse_field(eqx.combine(p, static), 0.3, y), params, y
            )
        else:
            out, vjp = jax.vjp(lambda y: _reverse_field(eqx.combine(params, static), 0.3, y), y)
        return out, vjp(cotangent)

    return jax.jit(run)


@functools.cache
def _reference_pullback(name, both):
    """The reference field's VJP with respect to the scene's numbers and the state, or to
    the state alone, from its Jacobian in forward mode (which shares no transposition with
    the hand-derived pass, and compiles faster than its reverse mode)."""
    static = eqx.partition(_scene(name), eqx.is_inexact_array)[1]

    def run(params, y, cotangent):
        field = lambda p, y: _reference_field(eqx.combine(p, static), 0.3, y)
        jacobians = jax.jacfwd(field, argnums=(0, 1) if both else (1,))(params, y)

        def contract(c, jacobian):  # Σ_o c_o ∂out_o/∂input, leaf by leaf
            return jax.tree.map(lambda j: jnp.tensordot(c, j, axes=c.ndim), jacobian)

        parts = [contract(c, j) for c, j in zip(cotangent, jacobians, strict=True)]
        return jax.tree.map(lambda a, b: a + b, *parts)

    return jax.jit(run)


def _cotangent(system):
    """A cotangent on the field's outputs $(\\xi, \\dot x)$."""
    k = jax.random.split(jax.random.PRNGKey(4), 2)
    return jax.random.normal(k[0], (6,)), jax.random.normal(k[1], (2 * system.shape_dim + 6,))


# Where the scene's numbers are differentiated too, `ReverseModeSceneTerm` transposes the
# field by autodiff, whatever the system: checked on one tree with every joint kind. The
# written-out pass (the state's cotangent alone) is checked on every case.
WITH_SCENE = {("tree4", "generic")}


def _pullbacks(name, kind):
    """Both fields' VJPs at one state, keyed by `(field, both)`: with respect to the
    state alone (`both=False`) and, on `WITH_SCENE`, to the scene's numbers too (a tuple
    of cotangents: the scene's and the state's, or the state's alone)."""
    scene = _scene(name)
    y = _state(scene.system, kind, jax.random.PRNGKey(3))
    cotangent = _cotangent(scene.system)
    params = eqx.filter(scene, eqx.is_inexact_array)
    vjps = {}
    for both in (False, True) if (name, kind) in WITH_SCENE else (False,):
        vjps["_reverse_field", both] = _pullback(name, both)(params, y, cotangent)[1]
        vjps["_reference_field", both] = _reference_pullback(name, both)(params, y, cotangent)
    return vjps, (params, y)


def _on_tangents(cotangent, value):
    """A cotangent as the covector it is on the tangent space: for a pose (a `(..., 4, 4)`
    leaf, a state's pose or a link's placement) its values on $P\\hat e_i$, $i < 6$, which
    is all that any two derivations must agree on; for a symmetric matrix (an inertia) its
    symmetric part, likewise; any other leaf as it is."""
    if value.shape[-2:] == (4, 4):
        basis = jax.vmap(bd.lie.hat)(jnp.eye(6, dtype=value.dtype))
        return jnp.einsum("...ab,...ac,icb->...i", cotangent, value, basis)
    square = value.ndim >= 2 and value.shape[-1] == value.shape[-2]
    if square and np.allclose(value, np.swapaxes(value, -1, -2)):
        return 0.5 * (cotangent + jnp.swapaxes(cotangent, -1, -2))
    return cotangent


def _assert_same_cotangents(ours, reference, values):
    ours, reference, values = (jax.tree.leaves(x) for x in (ours, reference, values))
    assert len(ours) == len(reference) == len(values)
    for a, b, value in zip(ours, reference, values, strict=True):
        a, b = _on_tangents(a, value), _on_tangents(b, value)
        assert np.all(np.isfinite(np.asarray(a)))
        scale = max(float(jnp.max(jnp.abs(b), initial=0.0)), 1.0)
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=0, atol=1e-10 * scale)


@pytest.mark.parametrize("name, kind", CASES)
def test_reverse_pass_equals_autodiff_of_the_reference_form(name, kind):
    if kind in ("zero shape", "ball near pi"):
        assert ball_columns(SYSTEMS[name]()).size > 0  # the singular point is there
    vjps, primals = _pullbacks(name, kind)
    for both in {both for _, both in vjps}:
        _assert_same_cotangents(
            vjps["_reverse_field", both],
            vjps["_reference_field", both],
            primals if both else primals[1],
        )


@functools.cache
def _articulated_pullback(name):
    """The articulated-body recursions' written-out VJP on the state (`_state_pass` takes it
    on large trees only), at the plain field's values."""
    scene = _scene(name)
    assert isinstance(scene.algorithm, bd.ArticulatedBodyField)

    def run(y, cotangent):
        return (_articulated_state_vjp(scene, y, 0.3, _field(scene, 0.3, y), cotangent),)

    return jax.jit(run)


ARTICULATED = [  # the cases whose system's default field is the recursions' (the 5-body
    # chain standing for the 2-body one: a program less to compile)
    case
    for case in CASES
    if jax.tree.leaves(case)[0] != "chain2"
    and isinstance(bd.Scene(SYSTEMS[jax.tree.leaves(case)[0]]()).algorithm, bd.ArticulatedBodyField)
]


@pytest.mark.parametrize("name, kind", ARTICULATED)
def test_the_articulated_reverse_pass_equals_autodiff_of_the_reference_form(name, kind):
    scene = _scene(name)
    y = _state(scene.system, kind, jax.random.PRNGKey(3))
    cotangent = _cotangent(scene.system)
    params = eqx.filter(scene, eqx.is_inexact_array)
    _assert_same_cotangents(
        _articulated_pullback(name)(y, cotangent),
        _reference_pullback(name, False)(params, y, cotangent),
        y,
    )


@pytest.mark.parametrize("name", SHAPED)
def test_reverse_pass_matches_central_differences(name):
    scene = _scene(name)
    y = _state(scene.system, "generic", jax.random.PRNGKey(5))
    g, x = y
    k = jax.random.split(jax.random.PRNGKey(6), 2)
    cotangent = _cotangent(scene.system)
    params = eqx.filter(scene, eqx.is_inexact_array)
    pullback = _pullback(name, False)  # compiled above
    _, ((g_bar, x_bar),) = pullback(params, y, cotangent)
    xi_dir, x_dir = jax.random.normal(k[0], (6,)), jax.random.normal(k[1], x.shape)

    def value(h):  # the pose moved along its tangent g·ξ̂, the rest along x_dir: the field's
        # value from the same compiled program (its VJP not used here)
        moved = (g @ bd.lie.se3_exp(h * xi_dir), x + h * x_dir)
        out, _ = pullback(params, moved, cotangent)
        return sum(
            float(np.vdot(np.asarray(c), np.asarray(o)))
            for c, o in zip(cotangent, out, strict=True)
        )

    h = 1e-5
    differences = (value(h) - value(-h)) / (2 * h)
    predicted = jnp.vdot(g_bar, g @ bd.lie.hat(xi_dir)) + jnp.vdot(x_bar, x_dir)
    np.testing.assert_allclose(float(predicted), float(differences), rtol=1e-7, atol=1e-8)


def test_every_scene_is_swapped_and_the_pass_is_written_out_where_it_applies():
    five = _scene("chain5")
    rigid = bd.Scene(SYSTEMS["rigid_body"]())
    framed = bd.Scene(five.system, frame=bd.FreeFalling(9.81, (0.0, 0.0, -1.0)))
    held = bd.Scene(five.system, five.effects, base=bd.PrescribedBase.fixed())
    long_chain = chain(37)
    floating_long = bd.Scene(long_chain)
    longer_chain = chain(90)
    held_long = bd.Scene(longer_chain, base=bd.PrescribedBase.fixed())
    held_mid = bd.Scene(long_chain, base=bd.PrescribedBase.fixed())
    dense_long = bd.Scene(long_chain, algorithm=bd.DenseField())
    for scene in (five, rigid, framed, held, floating_long):
        assert isinstance(for_reverse_mode(bd.SceneTerm(scene)), ReverseModeSceneTerm)
        values = (jnp.zeros(6), jnp.zeros(2 * scene.system.shape_dim + 6))
        assert isinstance(for_replay(bd.SceneTerm(scene), values), ReplayedSceneTerm)
    assert long_chain.shape_dim > _DENSE_MOST_COORDINATES >= five.system.shape_dim
    assert longer_chain.shape_dim > _DENSE_MOST_DRIVEN_COORDINATES >= long_chain.shape_dim
    assert [_state_pass(s) for s in (five, dense_long, floating_long)] == [
        _state_vjp,
        _state_vjp,
        _articulated_state_vjp,
    ]
    assert [_state_pass(s) for s in (held, held_mid, held_long)] == [
        _driven_state_vjp,
        _driven_state_vjp,
        _articulated_driven_state_vjp,
    ]
    assert not any(map(written_out, (rigid, framed)))


def test_the_replayed_field_gives_its_values_back_with_the_fields_reverse_pass():
    # `StoredStepsAdjoint`'s reverse sweep: the values the forward solve kept, and the
    # cotangents of the field at the state, on the state alone (the written-out pass) and
    # on the scene's numbers too (autodiff's), as `ReverseModeSceneTerm`'s (whose
    # cotangents the tests above check) with the field evaluated.
    name = "tree4"
    scene = _scene(name)
    y = _state(scene.system, "generic", jax.random.PRNGKey(3))
    cotangent = _cotangent(scene.system)
    params, static = eqx.partition(scene, eqx.is_inexact_array)
    values = bd.SceneTerm(scene).body_vf(0.3, y, None)

    @jax.jit
    def replayed(params, y, values):
        def field(params, y):
            return ReplayedSceneTerm(eqx.combine(params, static), values).body_vf(0.3, y, None)

        out, vjp = jax.vjp(field, params, y)
        return out, vjp(cotangent), jax.vjp(lambda y: field(params, y), y)[1](cotangent)

    out, both, state_only = replayed(params, y, values)
    for a, b in zip(jax.tree.leaves(out), jax.tree.leaves(values), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    written_out = [_pullback(name, both)(params, y, cotangent)[1] for both in (True, False)]
    for a, b in zip(jax.tree.leaves((both, state_only)), jax.tree.leaves(written_out), strict=True):
        scale = float(jnp.max(jnp.abs(b), initial=0.0)) + 1.0
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=0, atol=1e-12 * scale)


def _swaying(t):
    """A base moving like a ship's deck: turning and accelerating at every instant."""
    return bd.lie.se3_exp(
        jnp.array([0.3, -0.2, 0.5, 0.1, 0.0, -0.1]) * t
        + jnp.array([0.4, 0.1, -0.3, 0.2, -0.5, 0.3]) * jnp.sin(2.0 * t)
    )


_NOT_ITS_OWN = {  # scene -> whether its reverse pass is written out
    "held base": True,
    "moving base": True,
    "moving base, five bodies, dense field": True,
    "falling frame": False,
}


@pytest.mark.parametrize("where", list(_NOT_ITS_OWN))
def test_the_reverse_mode_fields_cotangents_are_the_plain_fields(where):
    # The reverse-mode and replayed terms of scenes beside the floating base's (tested
    # above): a prescribed base's written-out pass (`driven_field_vjp`), and autodiff's VJP
    # of the field elsewhere. Their cotangents on the state equal the plain field's Jacobian
    # (forward mode, which goes through no custom VJP) contracted with the cotangent; on a
    # prescribed base so do the articulated-body recursions' (which `_state_pass` takes on
    # large trees only), at the same values (the two fields agree to rounding).
    two = _scene("chain2")  # the smallest chain: the test is about the wiring, not the tree
    scene = {
        "held base": lambda: bd.Scene(two.system, two.effects, base=bd.PrescribedBase.fixed()),
        "moving base": lambda: bd.Scene(two.system, two.effects, base=bd.PrescribedBase(_swaying)),
        "moving base, five bodies, dense field": lambda: bd.Scene(
            _scene("chain5").system,
            _scene("chain5").effects,
            base=bd.PrescribedBase(_swaying),
            algorithm=bd.DenseField(),
        ),
        "falling frame": lambda: bd.Scene(
            two.system, two.effects, frame=bd.FreeFalling(9.81, (0.0, 0.0, -1.0))
        ),
    }[where]()
    assert written_out(scene) == _NOT_ITS_OWN[where]
    term = bd.SceneTerm(scene)
    d = scene.system.shape_dim
    k = jax.random.split(jax.random.PRNGKey(8), 3)
    state = bd.State(
        bd.lie.se3_exp(0.5 * jax.random.normal(k[0], (6,))),
        0.5 * jax.random.normal(k[1], (d,)),
        jnp.array([0.3, -0.2, 0.5, 0.1, 0.0, -0.1]),
        jax.random.normal(k[2], (d,)),
    )
    y = term.encode(0.4, state)

    @jax.jit
    def cotangents(y):
        values = term.body_vf(0.4, y, None)
        cotangent = jax.tree.map(lambda v: jnp.cos(jnp.arange(v.size, dtype=v.dtype)), values)
        jacobian = jax.jacfwd(lambda y: term.body_vf(0.4, y, None))(y)
        expected = jax.tree.map(
            lambda *parts: sum(parts),
            *[
                jax.tree.map(lambda j, c=c: jnp.tensordot(c, j, axes=c.ndim), jac)
                for c, jac in zip(cotangent, jacobian, strict=True)
            ],
        )
        ours = [
            jax.vjp(lambda y, t=t: t.body_vf(0.4, y, None), y)[1](cotangent)[0]
            for t in (ReverseModeSceneTerm(scene), ReplayedSceneTerm(scene, values))
        ]
        if isinstance(scene.mode, bd.PrescribedBaseMode):
            recursions = eqx.tree_at(lambda s: s.algorithm, scene, bd.ArticulatedBodyField())
            ours.append(_articulated_driven_state_vjp(recursions, y, 0.4, values, cotangent))
        return expected, ours

    expected, ours = cotangents(y)
    for theirs in ours:
        for a, b in zip(jax.tree.leaves(theirs), jax.tree.leaves(expected), strict=True):
            scale = max(float(jnp.max(jnp.abs(b))), 1.0)
            np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=0, atol=1e-12 * scale)
