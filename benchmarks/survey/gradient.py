"""One model's `jax.grad` over its forward solve: a loss on the final shape, as a function
of the initial shape velocity (every model has a shape; a held base has no twist to vary),
with `bd.simulate`'s default solver, step control and adjoint at `TOLERANCE`."""

import time

import jax
import jax.numpy as jnp

import bundledyn as bd
from benchmarks._timing import blocking, interleaved

TOLERANCE = 1e-8  # rtol = atol, the family's gradient part's rtol


def shape_loss(scene, state, t1):
    r"""`qdot -> |q(t_1)|^2 + |\dot q(t_1)|^2` of `bd.simulate(scene, state with initial
    shape velocity qdot, t1)`."""

    def loss(qdot):
        start = bd.State(state.g, state.q, state.xi, qdot)
        traj = bd.simulate(scene, start, t1, rtol=TOLERANCE, atol=TOLERANCE, max_steps=200_000)
        return jnp.sum(traj.q[-1] ** 2) + jnp.sum(traj.qdot[-1] ** 2)

    return loss


def _first_call(fn, x):
    began = time.perf_counter()
    out = jax.block_until_ready(fn(x))
    return out, time.perf_counter() - began


def gradient_cost(scene, state, t1, repeats):
    """The loss (forward solve) and its gradient, each compiled once and timed in
    alternation: `{"forward", "grad", "ratio", "compile": {"forward", "grad"}}`, or
    `{"error"}` where the gradient is not finite."""
    loss = shape_loss(scene, state, t1)
    forward, grad = jax.jit(loss), jax.jit(jax.grad(loss))
    _, forward_first = _first_call(forward, state.qdot)
    gradient, grad_first = _first_call(grad, state.qdot)
    if not bool(jnp.all(jnp.isfinite(gradient))):
        return {"error": "non-finite gradient"}
    timed = interleaved(
        {"forward": blocking(forward, state.qdot), "grad": blocking(grad, state.qdot)}, repeats
    )
    forward_time, grad_time = timed["forward"][1], timed["grad"][1]
    return {
        "forward": forward_time,
        "grad": grad_time,
        "ratio": grad_time["median"] / forward_time["median"],
        "compile": {
            "forward": max(forward_first - forward_time["median"], 0.0),
            "grad": max(grad_first - grad_time["median"], 0.0),
        },
    }
