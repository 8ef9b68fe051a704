"""Rows shared by the cases: how well a torque-free motion keeps its invariants."""

import jax.numpy as jnp
import numpy as np

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
