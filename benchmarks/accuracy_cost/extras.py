"""On the chain: throughput of vmapped batches, the cost of `jax.grad` under two adjoints,
and compile time against the number of bodies."""

import diffrax
import jax
import jax.numpy as jnp

import bundledyn as bd
from benchmarks._models import chain_scene
from benchmarks._rollouts import batch_rollouts, rollout_loss
from benchmarks._timing import timed
from benchmarks.accuracy_cost.problems import Problem, moving


def throughput(problem: Problem, batches, repeats, t1=1.0, rtol=1e-6):
    """Rollouts per second of `jax.vmap(simulate)` over perturbed base twists, per batch size."""
    s = problem.state
    run = batch_rollouts(problem.scene, s, t1, rtol=rtol, atol=rtol * problem.atol_ratio)
    rows = []
    for n in batches:
        xi = s.xi + 0.05 * jax.random.normal(jax.random.key(n), (n, 6))
        (_, steps), compiled, runs = timed(run, xi, repeats=repeats)
        t = runs["median"]
        rows.append(
            {
                "batch": n,
                "time": runs,
                "rollouts_per_second": n / t,
                "instance_steps_per_second": float(jnp.sum(steps)) / t,
                "compile": compiled,
            }
        )
        print(
            f"  throughput batch={n:5d}: {n / t:9.1f} rollouts/s ({t:.3f} s per batch)", flush=True
        )
    return rows


def gradient_cost(problem: Problem, repeats, t1=1.0, rtol=1e-8):
    """Time of `jax.grad` of a rollout loss relative to the forward solve, per adjoint."""
    tolerances = dict(rtol=rtol, atol=rtol * problem.atol_ratio)

    def loss(adjoint):
        return rollout_loss(problem.scene, problem.state, t1, adjoint=adjoint, **tolerances)

    xi = problem.state.xi
    _, _, base = timed(jax.jit(loss(diffrax.RecursiveCheckpointAdjoint())), xi, repeats=repeats)
    rows = [{"adjoint": "forward solve", "time": base, "ratio": 1.0}]
    adjoints = {
        "RecursiveCheckpointAdjoint": diffrax.RecursiveCheckpointAdjoint(),
        "BacksolveAdjoint": diffrax.BacksolveAdjoint(
            stepsize_controller=diffrax.PIDController(**tolerances)
        ),
    }
    for name, adjoint in adjoints.items():
        _, compiled, runs = timed(jax.jit(jax.grad(loss(adjoint))), xi, repeats=repeats)
        ratio = runs["median"] / base["median"]
        rows.append({"adjoint": name, "time": runs, "ratio": ratio, "compile": compiled})
        print(f"  grad ({name}): {ratio:.2f}x the forward solve", flush=True)
    return rows


def compile_times(ns, repeats=3):
    """Compile time of `simulate` for hinge chains of n bodies (n = 1 is a single body)."""
    rows = []
    for n in ns:
        scene = chain_scene(n)
        state = moving(scene.system.shape_dim)
        solve = jax.jit(
            lambda scene=scene, state=state: bd.simulate(scene, state, 1.0, rtol=1e-6, atol=1e-9).g[
                -1
            ]
        )
        _, compiled, runs = timed(solve, repeats=repeats)
        rows.append({"bodies": n, "compile": compiled, "run": runs})
        print(f"  compile n={n:2d}: {compiled:6.1f} s", flush=True)
    return rows
