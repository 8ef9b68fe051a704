"""One member: its metric and recursive field checked, then its field, the dense field,
`mj_forward`, the field's VJP and its gradient over the forward solve, timed."""

import mujoco
import numpy as np

import bundledyn as bd
from benchmarks._timing import interleaved
from benchmarks.family.members import Member, initial_qpos_qvel, mujoco_model
from benchmarks.speed.field import data_forward_sampler, scene_field_sampler
from benchmarks.speed.gradient import replayed_field_vjp_sampler
from benchmarks.survey.gradient import gradient_cost
from benchmarks.survey.measure import agreement, metric_error

# Gradients are timed up to the 150 degrees of freedom (with a margin for the
# free base's six); above, compiling them costs minutes and no target asks for them.
GRADIENT_MOST_DOFS = 160


def depth(model) -> int:
    """The most bodies on a path from the root to a leaf of `model`'s tree."""
    levels = np.zeros(model.nbody, int)
    for body in range(1, model.nbody):  # MuJoCo orders parents before children
        levels[body] = levels[model.body_parentid[body]] + 1
    return int(levels.max())


def condition(model, data) -> float:
    """The condition number of MuJoCo's mass matrix at `data`'s state: the two fields'
    solves of it carry rounding of about this times the machine's epsilon."""
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    return float(np.linalg.cond(M))


def _times(scene, state, model, data, repeats):
    dense = bd.Scene(scene.system, scene.effects, algorithm=bd.DenseField())
    samplers = {
        "field": scene_field_sampler(scene, state),
        "dense": scene_field_sampler(dense, state),
        "mj_forward": data_forward_sampler(model, data),
        "field_vjp": replayed_field_vjp_sampler(scene, state),
    }
    timed = {name: stats for name, (_, stats) in interleaved(samplers, repeats).items()}
    return timed, agreement(scene, dense, state)


def member_run(member: Member, repeats: int, t1: float) -> dict:
    """`{"label", "kind", "bodies", "dofs", "depth", "condition", "metric_error", "agreement",
    "times", "gradient"}`: times in seconds (`summary` of each), `gradient` as `gradient_cost`'s
    (None above `GRADIENT_MOST_DOFS`)."""
    scene = bd.Scene(bd.Multibody.from_mjcf(member.xml))
    model = mujoco_model(member, 1e-2)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = initial_qpos_qvel(model, member.rate, 0)
    mujoco.mj_forward(model, data)
    error, state = metric_error(model, data, scene, held=False)
    times, agreed = _times(scene, state, model, data, repeats)
    gradient = gradient_cost(scene, state, t1, repeats) if model.nv <= GRADIENT_MOST_DOFS else None
    return {
        "label": member.name,
        "kind": member.kind,
        "bodies": member.bodies,
        "dofs": int(model.nv),
        "depth": depth(model),
        "condition": condition(model, data),
        "metric_error": error,
        "agreement": agreed,
        "times": times,
        "gradient": gradient,
    }
