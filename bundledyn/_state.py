"""The user-facing state of a system: pose, shape and their velocities."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ._systems._validation import concrete


class State(eqx.Module):
    """A state $(g, q, \\xi, \\dot q)$ of a system on the bundle.

    **Arguments:**

    - `g`: 4×4 pose of the section frame in the scene's frame (rotation must be orthogonal
      to 1e-8; no silent re-orthogonalization).
    - `q`: shape coordinates, `(d,)` (length 0 for a single rigid body).
    - `xi`: $g^{-1}\\dot g$, the body velocity of the section frame, `(6,)`, angular first.
    - `qdot`: shape velocity, `(d,)`.
    """

    g: Float[Array, "4 4"]
    q: Float[Array, " d"]
    xi: Float[Array, "6"]
    qdot: Float[Array, " d"]

    def __init__(self, g, q=(), xi=(0.0,) * 6, qdot=None):
        self.g = jnp.asarray(g, dtype=float)
        self.q = jnp.asarray(q, dtype=float).reshape(-1) if np.ndim(q) <= 1 else jnp.asarray(q)
        self.xi = jnp.asarray(xi, dtype=float)
        self.qdot = jnp.zeros_like(self.q) if qdot is None else jnp.asarray(qdot, dtype=float)

    def __check_init__(self):
        for name, value, shape in (("g", self.g, (4, 4)), ("xi", self.xi, (6,))):
            if value.shape != shape:
                raise ValueError(f"`State.{name}` must have shape {shape}, got {value.shape}.")
        if self.q.ndim != 1 or self.qdot.shape != self.q.shape:
            raise ValueError(
                f"`State.q` and `State.qdot` must be 1-D of equal length, got {self.q.shape} "
                f"and {self.qdot.shape}."
            )
        values = [concrete(v) for v in (self.g, self.q, self.xi, self.qdot)]
        if any(v is None for v in values):
            return
        g, *rest = values
        if not all(np.all(np.isfinite(v)) for v in values):
            raise ValueError("`State` has a NaN or infinite entry.")
        R = g[:3, :3]
        error = np.abs(R.T @ R - np.eye(3)).max()
        if error > 1e-8 or np.linalg.det(R) <= 0:
            raise ValueError(
                f"`State.g` must be a pose in SE(3): its rotation is off orthogonal by {error:.1e} "
                "(> 1e-8) or not proper; build it with `bundledyn.lie.se3_exp` or re-orthogonalize."
            )
        if not np.allclose(g[3], [0.0, 0.0, 0.0, 1.0]):
            raise ValueError(f"`State.g` must have bottom row [0, 0, 0, 1], got {g[3]}.")
