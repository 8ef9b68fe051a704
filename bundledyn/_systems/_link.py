r"""A body of a tree and the joint that attaches it to its parent."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._validation import check_shape, concrete, rounding_tolerance
from ._joints import AbstractJoint
from ._rigid_body import RigidBody


class Link(eqx.Module):
    r"""A body attached to its parent by a joint.

    **Arguments:**

    - `body`: the `RigidBody` (its frame is the child frame of the joint).
    - `joint`: a joint (`Revolute`, `Prismatic`, `Universal`, `Spherical`, `Fixed`, `Composite`).
    - `parent`: index of the parent body; 0 is the floating base, $i \ge 1$ is `links[i-1]`.
      Parents come before children.
    - `placement`: 4×4 pose of the child frame in the parent frame when the joint is at
      zero (MuJoCo's body `pos`/`quat`). Default: identity.
    """

    body: RigidBody
    joint: AbstractJoint
    parent: int = eqx.field(static=True)
    placement: Float[Array, "4 4"]

    def __init__(self, body, joint, parent, placement=None):
        self.body = body
        self.joint = joint
        self.parent = int(parent)
        self.placement = jnp.eye(4) if placement is None else jnp.asarray(placement, dtype=float)

    def __check_init__(self):
        if not isinstance(self.body, RigidBody):
            raise ValueError(f"`Link.body` must be a RigidBody, got {type(self.body).__name__}.")
        if not isinstance(self.joint, AbstractJoint):
            raise ValueError(
                f"unknown joint type {type(self.joint).__name__!r} in `Link.joint`; use "
                "Revolute, Prismatic, Universal, Spherical, Fixed or Composite."
            )
        check_shape("Link.placement", self.placement, (4, 4))
        T = concrete(self.placement)
        if T is not None:
            R = T[:3, :3]
            if (
                not np.allclose(R.T @ R, np.eye(3), atol=rounding_tolerance(T, 1e-8))
                or np.linalg.det(R) <= 0
                or not np.allclose(T[3], [0, 0, 0, 1], atol=1e-12)
            ):
                raise ValueError(f"`Link.placement` must be a rigid transform (SE(3)), got\n{T}.")
