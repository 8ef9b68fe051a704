"""Rows shared by the cases: how well a torque-free motion keeps its invariants."""

import jax.numpy as jnp
import numpy as np

from .._scene import Scene
from .._simulate import simulate
from .._state import State
from .._trajectory import Trajectory
from ._row import StressRow


def relative_change(values) -> float:
    """The largest change of `values` (over its first axis) relative to their size."""
    values = np.asarray(values, dtype=float).reshape(len(values), -1)
    scale = max(float(np.abs(values).max()), np.finfo(float).tiny)
    return float(np.abs(values - values[0]).max() / scale)


def energy_row(case: str, traj: Trajectory, bound: float, note: str = "") -> StressRow:
    """Relative change of the total energy over the trajectory."""
    return StressRow(case, "energy, relative change", relative_change(traj.energy()), bound, note)


def momentum_row(case: str, traj: Trajectory, bound: float, note: str = "") -> StressRow:
    """Relative change of the spatial momentum (exactly conserved without external forces)."""
    return StressRow(
        case, "spatial momentum, relative change", relative_change(traj.spatial_momentum()),
        bound, note,
    )  # fmt: skip


def orthogonality_row(case: str, traj: Trajectory, bound: float) -> StressRow:
    r"""The largest $|R^T R - I|$ over the saved poses."""
    return StressRow(
        case, "rotation's orthogonality error", float(jnp.max(traj.orthogonality_error())), bound
    )


def free_run(case: str, scene: Scene, state: State, *, t1: float, rtol: float):
    """`scene` solved from `state` at `rtol`: the trajectory, and its energy and momentum rows
    (bound 100 rtol; the energy row's note gives the steps). The horizon is traced, so one
    compiled solve serves every case of the same model."""
    traj = simulate(scene, state, jnp.asarray(t1), rtol=rtol, atol=rtol)
    note = f"{int(traj.stats['num_steps'])} steps"
    return traj, energy_row(case, traj, 1e2 * rtol, note), momentum_row(case, traj, 1e2 * rtol)
