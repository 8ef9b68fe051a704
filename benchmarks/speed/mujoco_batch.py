"""Part 3, MuJoCo's side: `mujoco.rollout` over the batch on threads, and MJX (MuJoCo in
JAX) on the same initial states, with the step at which MJX is as accurate as MuJoCo."""

import time

import bundledyn as bd
from benchmarks._errors import state_error
from benchmarks._models import chain_scene, initial_state, mujoco_model
from benchmarks._mujoco import physics_state, qpos_qvel
from benchmarks._timing import blocking
from benchmarks.speed.config import MUJOCO_DT


def mujoco_batch_initials(model, n, batch):
    """MuJoCo's full physics states of part 3's batch: the n-body chain's initial state with
    noise of 0.05 on the base velocity, `(batch, state size)`."""
    import numpy as np

    scene = chain_scene(n)
    _, initial = physics_state(model, scene.system, initial_state(scene))
    rng = np.random.default_rng(0)
    initials = np.repeat(initial[None], batch, axis=0)
    vel = slice(1 + model.nq, 1 + model.nq + 6)
    initials[:, vel] += 0.05 * rng.standard_normal((batch, 6))
    return initials


def mujoco_batch(n, batch, t1, dt, threads=2):
    """`(sampler, info)` of `mujoco.rollout` over `batch` states on `threads` threads."""
    import mujoco
    from mujoco import rollout

    model = mujoco_model(n, dt)
    initials = mujoco_batch_initials(model, n, batch)
    datas = [mujoco.MjData(model) for _ in range(threads)]
    nstep = round(t1 / dt)

    def sample():
        rollout.rollout(model, datas, initials, nstep=nstep, persistent_pool=True)

    return sample, {"threads": threads, "steps": nstep}


def mjx_rollout(model):
    """MJX (MuJoCo in JAX) from MuJoCo's `model`: a jitted `jax.vmap` of `nstep` steps of
    `dt` from batches of `(qpos, qvel)` to the final `(qpos, qvel)`, `run(qpos, qvel, dt,
    nstep)` (one compile for every step); None without `mujoco.mjx`."""
    try:
        from mujoco import mjx
    except ImportError:
        return None
    import jax

    mjx_model = mjx.put_model(model)

    @jax.jit
    def run(qpos, qvel, dt, nstep):
        m = mjx_model.tree_replace({"opt.timestep": dt})

        def one(qpos, qvel):
            data = mjx.make_data(m).replace(qpos=qpos, qvel=qvel)
            data = jax.lax.fori_loop(0, nstep, lambda _, d: mjx.step(m, d), data)
            return data.qpos, data.qvel

        return jax.vmap(one)(qpos, qvel)

    return run


def mjx_batch(n, batch, t1, dt):
    """`(sampler, info)` of MJX on the batch of `mujoco_batch` (its initial states, RK4 and
    dt), or None without `mujoco.mjx`; `info["first_call"]` is the first call's seconds."""
    import jax.numpy as jnp

    model = mujoco_model(n, dt)
    run = mjx_rollout(model)
    if run is None:
        return None
    qpos, qvel = map(jnp.asarray, qpos_qvel(model, mujoco_batch_initials(model, n, batch)))
    nstep = round(t1 / dt)
    sample = blocking(run, qpos, qvel, dt, nstep)
    start = time.perf_counter()
    sample()
    return sample, {"steps": nstep, "first_call": time.perf_counter() - start}


def mjx_calibration(t1, scene, states, refs, target, divisions=(1, 2, 5, 10, 20, 50, 100)):
    """MJX's RK4 on part 3's calibration rollouts, at MuJoCo's step divided by each of
    `divisions`: the largest final-state error over the rollouts (against `refs`) at each
    step, and the longest step whose error is at most `target`; None without `mujoco.mjx`."""
    import numpy as np

    model = mujoco_model(5, MUJOCO_DT)
    run = mjx_rollout(model)
    if run is None:
        return None
    datas = [physics_state(model, scene.system, state)[0] for state in states]
    qpos0, qvel0 = np.stack([d.qpos for d in datas]), np.stack([d.qvel for d in datas])
    points = []
    for k in divisions:
        steps = round(k * t1 / MUJOCO_DT)
        qpos, qvel = run(qpos0, qvel0, MUJOCO_DT / k, steps)
        error = max(
            state_error(bd.state_from_mujoco(scene.system, p, v, qpos0=model.qpos0), r)
            for p, v, r in zip(qpos, qvel, refs, strict=True)
        )
        points.append({"dt": MUJOCO_DT / k, "steps": steps, "error": error})
    matched = next((p for p in points if p["error"] <= target), None)
    return {"points": points, "at_target": matched}
