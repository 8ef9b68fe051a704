"""One member's field costs with and without gravity, timed in alternation with `mj_forward`."""

import mujoco
import numpy as np

import bundledyn as bd
from benchmarks._timing import interleaved
from benchmarks.family.members import Member, initial_qpos_qvel, mujoco_model
from benchmarks.speed.field import data_forward_sampler, scene_field_sampler
from benchmarks.speed.gradient import replayed_field_vjp_sampler

GRAVITY = bd.Gravity(9.81)
# The Earth's gravity gradient on the model, 400 km above the ground.
GRAVITY_GRADIENT = bd.GravityGradient(3.986004418e14, (0.0, 0.0, -6.771e6))


class PotentialGravity(bd.AbstractPotential):
    """`gravity` with its forces by autodiff of its potential (`AbstractPotential`'s rule)."""

    gravity: bd.Gravity

    def potential(self, system, t, g, q):
        return self.gravity.potential(system, t, g, q)


def _agreement(system, state):
    """The largest difference between `Gravity`'s generalized forces and those by autodiff of
    its potential at `state`, over their largest entry."""
    kin = bd.Kinematics(0.0, state.g, state.q, state.xi, state.qdot)
    written_out = np.concatenate(GRAVITY.generalized_force(system, kin))
    by_autodiff = np.concatenate(PotentialGravity(GRAVITY).generalized_force(system, kin))
    return float(np.max(np.abs(written_out - by_autodiff)) / np.max(np.abs(by_autodiff)))


def member_run(member: Member, repeats: int):
    """`{"label", "dofs", "agreement", "times"}`: the member's per-evaluation times (seconds,
    `summary` of each) and how closely `Gravity`'s forces equal its potential's gradient."""
    system = bd.Multibody.from_mjcf(member.xml)
    model = mujoco_model(member, 1e-2)
    model.opt.gravity[:] = (0.0, 0.0, -9.81)
    qpos, qvel = initial_qpos_qvel(model, member.rate, 0)
    state = bd.state_from_mujoco(system, qpos, qvel, qpos0=model.qpos0)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = qpos, qvel
    bare, weighed = bd.Scene(system), bd.Scene(system, [GRAVITY])
    by_potential = bd.Scene(system, [PotentialGravity(GRAVITY)])
    samplers = {
        "field": scene_field_sampler(bare, state),
        "gravity": scene_field_sampler(weighed, state),
        "potential_gradient": scene_field_sampler(by_potential, state),
        "gravity_gradient": scene_field_sampler(bd.Scene(system, [GRAVITY_GRADIENT]), state),
        "field_vjp": replayed_field_vjp_sampler(bare, state),
        "gravity_vjp": replayed_field_vjp_sampler(weighed, state),
        "potential_gradient_vjp": replayed_field_vjp_sampler(by_potential, state),
        "mj_forward": data_forward_sampler(model, data),
    }
    times = {name: stats for name, (_, stats) in interleaved(samplers, repeats).items()}
    return {
        "label": member.name,
        "dofs": int(model.nv),
        "agreement": _agreement(system, state),
        "times": times,
    }
