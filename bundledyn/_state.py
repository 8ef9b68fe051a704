r"""The user-facing state of a system: pose, shape and their velocities."""

import equinox as eqx
import jax.numpy as jnp
import jax.tree_util as jtu
import numpy as np
from jaxtyping import Array, Float

from ._validation import concrete

_ORTHOGONALITY = 1e-8
_NOT_FINITE = "`State` has a NaN or infinite entry."
_NOT_A_POSE = (
    "`State.g` must be a pose in SE(3): its rotation must be orthogonal to 1e-8 and proper, "
    "its bottom row [0, 0, 0, 1]; build it with `bundledyn.lie.se3_exp` or re-orthogonalize"
)


class State(eqx.Module):
    r"""A state $(g, q, \xi, \dot q)$ of a system on the bundle.

    **Arguments:**

    - `g`: 4×4 pose of the section frame in the scene's frame (rotation must be orthogonal
      to 1e-8; no silent re-orthogonalization).
    - `q`: shape coordinates, `(d,)` (length 0 for a single rigid body).
    - `xi`: $g^{-1}\dot g$, the body velocity of the section frame, `(6,)`, angular first.
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
        g, q, xi, qdot = (concrete(v) for v in (self.g, self.q, self.xi, self.qdot))
        if g is None or q is None or xi is None or qdot is None:
            return
        if not all(np.all(np.isfinite(v)) for v in (g, q, xi, qdot)):
            raise ValueError(_NOT_FINITE)
        R = g[:3, :3]
        error = np.abs(R.T @ R - np.eye(3)).max()
        if error > _ORTHOGONALITY or np.linalg.det(R) <= 0:
            raise ValueError(f"{_NOT_A_POSE} (its rotation is off orthogonal by {error:.1e}).")
        if not np.allclose(g[3], [0.0, 0.0, 0.0, 1.0]):
            raise ValueError(f"`State.g` must have bottom row [0, 0, 0, 1], got {g[3]}.")

    def checked(self) -> "State":
        """This state with run-time checks attached, which hold under `jax.jit` and `jax.vmap`.

        Construction checks only concrete values; a state built from traced values (inside
        `jax.jit`, `jax.vmap`, `jax.grad`) is checked here instead, when it is used
        (`simulate` and `SceneTerm.encode` call this): every entry finite, and `g` a pose in
        SE(3) (rotation orthogonal to 1e-8 and proper, bottom row `[0, 0, 0, 1]`). A failed
        check raises `equinox`'s run-time error with the message construction would give.

        **Returns:**

        The same state, its entries passed through `equinox.error_if`.
        """
        finite = jnp.all(jnp.stack([jnp.all(jnp.isfinite(v)) for v in jtu.tree_leaves(self)]))
        R = self.g[:3, :3]
        off = jnp.max(jnp.abs(R.T @ R - jnp.eye(3, dtype=R.dtype)))
        bottom = jnp.any(self.g[3] != jnp.array([0.0, 0.0, 0.0, 1.0], dtype=R.dtype))
        not_a_pose = (off > _ORTHOGONALITY) | (jnp.linalg.det(R) <= 0) | bottom
        leaves = [eqx.error_if(v, ~finite, _NOT_FINITE) for v in jtu.tree_leaves(self)]
        g = eqx.error_if(leaves[0], finite & not_a_pose, _NOT_A_POSE + ".")
        return jtu.tree_unflatten(jtu.tree_structure(self), [g, *leaves[1:]])
