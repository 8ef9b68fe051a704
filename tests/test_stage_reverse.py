"""The stages of a Runge–Kutta–Munthe-Kaas step differentiated by their written-out reverse
pass (`_stage_reverse.py`, what `StoredStepsAdjoint`'s reverse sweep takes) give autodiff's
cotangents: for every Lie-group solver on a spinning body whose stages turn by up to about
2.7 rad, and for `RKMK87` on a chain under gravity, a spring and a damper; with respect to
the step's start, its two times and the scene's numbers, and on every output of the step
(the end, the error estimate, the dense output, the field's values). The first stage is
always at Ω = 0."""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import pytest
from registry import RK_SOLVERS, RKMK87_STEP_STAGES_ONLY
from systems import asymmetric_body, chain

import bundledyn as bd

SOLVERS = {**RK_SOLVERS, "RKMK87, stages of the step only": RKMK87_STEP_STAGES_ONLY}


def _chain():
    effects = [bd.Gravity(9.81, (0.2, 0.0, -1.0)), bd.ShapeSpring(0.8), bd.ShapeDamper(0.3)]
    xi = jnp.array([2.5, -1.5, 1.0, 0.1, 0.0, 0.2])
    state = bd.State(jnp.eye(4), jnp.array([0.2, -0.1, 0.3]), xi, jnp.array([0.5, -0.4, 0.3]))
    return bd.Scene(chain(3), effects), state


def _spinning_body():
    xi = jnp.array([6.0, -4.0, 3.0, 0.1, 0.0, 0.2])
    return bd.Scene(asymmetric_body(), [bd.Gravity(9.81)]), bd.State(jnp.eye(4), xi=xi)


# (start, step): the chain's stages stay in the coefficients' series branch; the body's,
# turning at 7.8 rad/s, reach about 2.7 rad, past it.
CASES = {"chain, 0.01 s": (_chain, 0.01), "spinning body, 0.35 s": (_spinning_body, 0.35)}


def _step(solver, reverse_pass, inputs):
    y0, t0, t1, scene = inputs
    term = bd.SceneTerm(scene)
    return solver.stage_step(
        term, t0, t1, y0, None, stage_terms=lambda i: term, reverse_pass=reverse_pass
    )


def _random_like(tree, key):
    leaves, treedef = jax.tree.flatten(tree)
    keys = jax.random.split(key, len(leaves))
    return jax.tree.unflatten(
        treedef, [jax.random.normal(k, jnp.shape(x)) for k, x in zip(keys, leaves, strict=True)]
    )


# Every solver on the spinning body; the chain (a shape, effects with numbers of their own,
# a dearer compile) with `RKMK87`'s tableau, the largest, with and without its dense output.
PAIRS = [(name, "spinning body, 0.35 s") for name in SOLVERS] + [
    (name, "chain, 0.01 s") for name in SOLVERS if name.startswith("RKMK87")
]


@pytest.mark.parametrize("name, case", PAIRS)
def test_the_written_out_reverse_pass_gives_autodiffs_cotangents(name, case):
    solver = SOLVERS[name]
    start, h = CASES[case]
    scene, state = start()
    y0 = bd.SceneTerm(scene).encode(0.0, state)
    inputs = (y0, jnp.asarray(0.3), jnp.asarray(0.3 + h), scene)
    cotangents = {}
    for reverse_pass in (False, True):
        step = functools.partial(_step, solver, reverse_pass)
        out, vjp = eqx.filter_vjp(step, inputs)
        # The skipped stages' dense output is NaN, and depends on nothing.
        ct = _random_like(out, jax.random.key(0))
        ct = jax.tree.map(lambda c, o: jnp.where(jnp.isfinite(o), c, 0.0), ct, out)
        (cotangents[reverse_pass],) = vjp(ct)
    ours, autodiff = (jax.tree.leaves(cotangents[k]) for k in (True, False))
    assert len(ours) == len(autodiff) > 4  # the start, the times and the scene's numbers
    for a, b in zip(ours, autodiff, strict=True):
        if b.size == 0:
            continue
        scale = float(jnp.max(jnp.abs(b))) + 1e-300
        assert float(jnp.max(jnp.abs(a - b))) <= 1e-10 * max(scale, 1.0)
