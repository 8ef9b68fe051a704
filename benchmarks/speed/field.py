"""Part 1: one vector-field evaluation against MuJoCo's `mj_forward` and RK4 step."""

import time

import bundledyn as bd
from benchmarks._models import chain_scene, initial_state, mujoco_model
from benchmarks._mujoco import physics_state
from benchmarks._timing import interleaved, loop_sampler
from benchmarks.speed.config import LOOP_EVALS, MUJOCO_DT


def scene_field_sampler(scene, state):
    """A sampler of seconds per evaluation of `scene`'s vector field at `state`
    (`loop_sampler`)."""
    term = bd.SceneTerm(scene)
    y = term.encode(0.0, state)
    return loop_sampler(lambda i, y: term.vf(1e-6 * i, y, None), y, LOOP_EVALS)


def field_sampler(n):
    """A sampler of seconds per vector-field evaluation of the n-body chain."""
    scene = chain_scene(n)
    return scene_field_sampler(scene, initial_state(scene))


def _mujoco_chain(n):
    """MuJoCo's model of the n-body chain and `(data, full physics state)` at its
    initial state."""
    scene = chain_scene(n)
    model = mujoco_model(n, MUJOCO_DT)
    return model, *physics_state(model, scene.system, initial_state(scene))


def mj_forward_sampler(n, calls=2000):
    """A sampler of seconds per `mj_forward` of the n-body chain."""
    model, data, _ = _mujoco_chain(n)
    return data_forward_sampler(model, data, calls)


def data_forward_sampler(model, data, calls=2000):
    """A sampler of seconds per `mj_forward` at `data` (a Python loop over the C call)."""
    import mujoco

    def sample():
        start = time.perf_counter()
        for _ in range(calls):
            mujoco.mj_forward(model, data)
        return (time.perf_counter() - start) / calls

    return sample


def mujoco_rk4_step(n, repeats, calls=2000):
    """Seconds per MuJoCo RK4 step (`mujoco.rollout`, a C loop)."""
    from mujoco import rollout

    model, data, initial = _mujoco_chain(n)

    def sample():
        start = time.perf_counter()
        rollout.rollout(model, data, initial[None], nstep=calls)
        return (time.perf_counter() - start) / calls

    return {"rk4_step": interleaved({"rk4": sample}, repeats)["rk4"][1]}


def field_cost(n, repeats):
    """Part 1 in a worker: the field's cost and `mj_forward`'s, timed in alternation."""
    (first, field), (_, forward) = interleaved(
        {"field": field_sampler(n), "mj_forward": mj_forward_sampler(n)}, repeats
    ).values()
    return {
        "per_evaluation": field,
        "mj_forward": forward,
        "compile": LOOP_EVALS * max(first - field["median"], 0.0),
    }
