"""Part 4: tracing and XLA compile time of `simulate`, and of its `jax.grad`."""

import bundledyn as bd
from benchmarks._models import chain_scene, initial_state
from benchmarks._rollouts import with_twist
from benchmarks._timing import compile_seconds


def compile_costs(ns, t1=1.0):
    """Tracing + XLA compile time of `simulate` for each n (and of `jax.grad` for the last n),
    in one process in this order: the last n's gradient reuses its forward field's trace."""
    import jax
    import jax.numpy as jnp

    rows = {}
    for n in ns:
        scene = chain_scene(n)
        state = initial_state(scene)

        def loss(xi, scene=scene, state=state):
            traj = bd.simulate(scene, with_twist(state, xi), t1, rtol=1e-6, atol=1e-8)
            return jnp.sum(traj.g[-1, :3, 3] ** 2)

        rows[str(n)] = {"simulate": compile_seconds(jax.jit(loss), state.xi)}
        if n == ns[-1]:
            rows[str(n)]["grad"] = compile_seconds(jax.jit(jax.grad(loss)), state.xi)
        print(f"  compile n={n}: {rows[str(n)]}", flush=True)
    return rows
