"""The operations XLA compiles for `simulate` and for its `jax.grad`, over a family of scenes.

An op count is what a refactoring must leave alone for no speed to be lost (a program with
the same operations runs the same kernels); it is deterministic, so one run per member is
enough, and it is compared between commits, never asserted in tests.
"""

import jax
import jax.numpy as jnp

import bundledyn as bd
from benchmarks._models import chain_scene, initial_state


def _members(quick):
    """`name -> (scene, state)`: chains of several sizes, and each mode the chains take."""
    sizes = (3,) if quick else (3, 5, 10)
    members = {f"chain{n}": chain_scene(n) for n in sizes}
    chain = chain_scene(3)
    d = chain.system.shape_dim
    bend = lambda t: 0.3 * jnp.sin(t + jnp.arange(d, dtype=float))
    members["chain3, prescribed shape"] = bd.Scene(chain.system, shape=bd.Prescribed(bend))
    members["chain3, fixed base"] = bd.Scene(
        chain.system, (bd.Gravity(),), base=bd.PrescribedBase.fixed()
    )
    members["chain3, falling frame"] = bd.Scene(
        chain.system, (bd.Gravity(),), frame=bd.FreeFalling(9.81)
    )
    return {name: (scene, initial_state(scene)) for name, scene in members.items()}


def operations(fn, *args) -> int:
    """The instructions of `fn`'s optimized XLA program (every computation, loops' bodies
    included)."""
    text = jax.jit(fn).lower(*args).compile().as_text()
    return sum(1 for line in text.splitlines() if " = " in line.split("metadata")[0])


def count(quick):
    """`name -> {"simulate": n, "grad": n}` for every member."""
    rows = {}
    for name, (scene, state) in _members(quick).items():

        def final(velocities, scene=scene, state=state):
            start = bd.State(state.g, state.q, *velocities)
            traj = bd.simulate(scene, start, 1.0, rtol=1e-8, atol=1e-8)
            return jnp.sum(traj.xi[-1] ** 2) + jnp.sum(traj.g[-1, :3, 3]) + jnp.sum(traj.qdot[-1])

        velocities = (state.xi, state.qdot)  # a given base's twist is not the state's
        rows[name] = {
            "simulate": operations(final, velocities),
            "grad": operations(jax.grad(final), velocities),
        }
        print(f"  {name}: {rows[name]}", flush=True)
    return rows
