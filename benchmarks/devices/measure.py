"""One worker of the devices benchmark: the batch on every device this process has, timed
in alternation with MuJoCo's threaded `rollout`."""

import jax
import jax.numpy as jnp
import numpy as np

import bundledyn as bd
from benchmarks._models import chain_scene, initial_state
from benchmarks._rollouts import with_twist
from benchmarks._timing import interleaved
from benchmarks.speed.batch import batch_twists
from benchmarks.speed.config import METHODS, MUJOCO_DT, simulate_options
from benchmarks.speed.mujoco_batch import mujoco_batch

T1 = 1.0
MUJOCO_THREADS = 2


def member_fn(method, setting):
    """One member of the batch: its base twist -> (final pose, steps)."""
    scene = chain_scene(5)
    state = initial_state(scene)
    options = simulate_options(*METHODS[method], setting)

    def member(xi):
        traj = bd.simulate(scene, with_twist(state, xi), T1, **options)
        return traj.g[-1], traj.stats["num_steps"]

    return member


def _sampler(batch, twists):
    def sample():  # returns None: `interleaved` times the call
        jax.block_until_ready(batch(twists))

    return sample


def measure_worker(settings, batch, repeats):
    """Every method of `settings` (name -> setting) on this process's devices, and MuJoCo's
    rollout, timed in alternation."""
    bd.enable_x64()
    samplers, entries = {}, {}
    for method, setting in settings.items():
        member = member_fn(method, setting)
        twists = batch_twists(initial_state(chain_scene(5)), batch)
        spread = bd.vmap_over_devices(member)
        poses, steps = jax.block_until_ready(spread(twists))
        alone, _ = jax.jit(jax.vmap(member))(twists)
        entries[method] = {
            "setting": setting,
            "mean_steps": float(jnp.mean(steps)),
            "lockstep_overhead": spread.lockstep(np.asarray(steps)).overhead,
            "difference_from_one_device": float(jnp.max(jnp.abs(poses - alone))),
        }
        samplers[method] = _sampler(spread, twists)
    samplers["MuJoCo"], mujoco = mujoco_batch(5, batch, T1, MUJOCO_DT, MUJOCO_THREADS)
    timings = interleaved(samplers, repeats)
    for name, (_, runs) in timings.items():
        entry = entries.setdefault(name, dict(mujoco))
        entry |= {"time": runs, "rollouts_per_second": batch / runs["median"]}
    return {"devices": jax.device_count(), "methods": entries}
