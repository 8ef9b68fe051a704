r"""A single rigid body: the simplest system, a trivial bundle with no shape."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .. import lie
from .._validation import check_shape
from ._base import AbstractInertialSystem
from ._metric_jet import DenseMetricJet
from ._pseudo_inertia import inertial_from_pseudo_inertia, pseudo_inertia
from ._validation import check_inertia, check_mass, checked_inertia, checked_mass


def spatial_inertia(mass, com, inertia):
    r"""Spatial inertia about a frame's origin, in that frame's axes (angular first).

    **Arguments:**

    - `mass`: $m > 0$, shape `(...)`.
    - `com`: centre of mass $c$ in the frame, shape `(..., 3)`.
    - `inertia`: rotational inertia $J_c$ about the centre of mass, shape `(..., 3, 3)`;
      its symmetric part is used, so that derivatives with respect to it are symmetric.

    **Returns:**

    $\begin{bmatrix} J_c - m\tilde c\tilde c & m\tilde c \\ m\tilde c^T & m 1\end{bmatrix}$,
    shape `(..., 6, 6)`, so that $T = \tfrac12 \nu^T M \nu$ for a body twist $\nu=(\omega, v)$.
    """
    m = jnp.asarray(mass)[..., None, None]
    c = jnp.asarray(com)
    inertia = jnp.asarray(inertia)
    inertia = 0.5 * (inertia + jnp.swapaxes(inertia, -1, -2))
    c_hat = lie.hat(c)
    eye = jnp.broadcast_to(jnp.eye(3, dtype=c_hat.dtype), c_hat.shape)
    # c̃c̃ = c cᵀ - |c|² 1: elementwise, so the whole matrix is one fused kernel.
    c_hat2 = c[..., :, None] * c[..., None, :] - jnp.sum(c * c, axis=-1)[..., None, None] * eye
    top = jnp.concatenate([inertia - m * c_hat2, m * c_hat], axis=-1)
    bottom = jnp.concatenate([-m * c_hat, m * eye], axis=-1)
    return jnp.concatenate([top, bottom], axis=-2)


class RigidBody(AbstractInertialSystem):
    r"""A rigid body: mass, centre of mass and rotational inertia in its own frame.

    As a system it moves freely with no shape ($d = 0$): the section frame is the body
    frame and the metric is its spatial inertia. It is also the building block of
    `Multibody`.

    **Arguments:**

    - `mass`: $m > 0$.
    - `com`: centre of mass in the body frame, shape `(3,)`.
    - `inertia`: rotational inertia about the centre of mass in body axes, shape `(3, 3)`,
      symmetric positive definite and obeying the triangle inequality.
    """

    mass: Float[Array, ""]
    com: Float[Array, "3"]
    inertia: Float[Array, "3 3"]
    fixed_centres: ClassVar[bool] = False

    def __init__(self, mass, com, inertia):
        self.mass = jnp.asarray(mass, dtype=float)
        self.com = jnp.asarray(com, dtype=float)
        self.inertia = jnp.asarray(inertia, dtype=float)

    def __check_init__(self):
        check_shape("RigidBody.mass", self.mass, ())
        check_shape("RigidBody.com", self.com, (3,))
        check_shape("RigidBody.inertia", self.inertia, (3, 3))
        check_mass("RigidBody.mass", self.mass)
        check_inertia("RigidBody.inertia", self.inertia)

    @property
    def shape_dim(self) -> int:
        return 0

    def spatial_inertia(self) -> Float[Array, "6 6"]:
        """The 6×6 spatial inertia about the body origin (see `spatial_inertia`)."""
        return spatial_inertia(self.mass, self.com, self.inertia)

    def metric(self, q):
        return self.spatial_inertia()

    def metric_jet(self, q):
        G = self.spatial_inertia()
        return DenseMetricJet(G, jnp.zeros((0, 6, 6), G.dtype))

    def pseudo_inertias(self):
        return pseudo_inertia(self.mass, self.com, self.inertia)[None]

    def with_pseudo_inertias(self, P) -> "RigidBody":
        m, c, J = inertial_from_pseudo_inertia(P[0])
        return eqx.tree_at(lambda b: (b.mass, b.com, b.inertia), self, (m, c, J))

    def checked(self) -> "RigidBody":
        mass = checked_mass("RigidBody.mass", self.mass)
        inertia = checked_inertia("RigidBody.inertia", self.inertia)
        return eqx.tree_at(lambda b: (b.mass, b.inertia), self, (mass, inertia))
