"""MuJoCo beside bundledyn: one state in both simulators' variables, through the public
converters `bd.state_to_mujoco` and `bd.state_from_mujoco`."""

import bundledyn as bd


def float64_cpu_run_with_mujoco() -> bool:
    """Set up a float64 CPU run with bundledyn's XLA flags; whether MuJoCo is there to
    compare against (printing how to install it if not)."""
    bd.use_cpu_xla_flags()
    bd.enable_x64()
    try:
        import mujoco  # noqa: F401
    except ImportError:
        print("mujoco is not installed (pip install '.[bench]'): nothing to compare against")
        return False
    return True


def physics_state(model, system, state: bd.State):
    """`(data, full physics state)`: MuJoCo's `MjData` and `mjSTATE_FULLPHYSICS` vector
    (what `mujoco.rollout` starts from) for bundledyn's `state` of `system`, the same
    model as `model`."""
    import mujoco
    import numpy as np

    qpos, qvel = bd.state_to_mujoco(system, state, qpos0=model.qpos0)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = np.asarray(qpos), np.asarray(qvel)
    mujoco.mj_forward(model, data)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    initial = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, initial, spec)
    return data, initial


def qpos_qvel(model, physics):
    """The `(qpos, qvel)` parts of full physics states (the last axis; time comes first)."""
    return physics[..., 1 : 1 + model.nq], physics[..., 1 + model.nq : 1 + model.nq + model.nv]


def final_state(model, system, states) -> bd.State:
    """bundledyn's state at the end of the first rollout of `mujoco.rollout`'s `states`."""
    qpos, qvel = qpos_qvel(model, states[0, -1])
    return bd.state_from_mujoco(system, qpos, qvel, qpos0=model.qpos0)


def rollout_final_state(model, t1, system, state: bd.State):
    """MuJoCo's rollout (`mujoco.rollout`, its C loop at `model`'s integrator and step) from
    bundledyn's `state` of `system` to `t1`: `(final state in bundledyn's variables, a
    sampler of the rollout)`."""
    from mujoco import rollout

    data, initial = physics_state(model, system, state)
    nstep = round(t1 / model.opt.timestep)

    def run():
        return rollout.rollout(model, data, initial[None], nstep=nstep)[0]

    final = final_state(model, system, run())

    def sample():
        run()

    return final, sample
