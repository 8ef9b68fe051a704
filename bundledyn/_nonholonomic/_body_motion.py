r"""A rigid body moving in kinematic characteristics, $\xi = He$: what Maggi's and Appell's
equations on the bundle read."""

from typing import NamedTuple

from jaxtyping import Array, Float


class BodyMotion(NamedTuple):
    r"""A rigid body whose body twist is $\xi = He$ (seed 001, (77) on SE(3)), with its
    inertia and the wrench of its effects.

    - `H`: the body twist per unit characteristic, shape `(6, nu)`.
    - `H_dot_e`: $\dot He$, shape `(6,)`.
    - `xi`: the body twist $(\omega, v)$, shape `(6,)`.
    - `inertia`: the spatial inertia about the body's origin, shape `(6, 6)`.
    - `wrench`: the body wrench $F = (\tau, f)$ of the effects, shape `(6,)`.
    """

    H: Float[Array, "6 nu"]
    H_dot_e: Float[Array, "6"]
    xi: Float[Array, "6"]
    inertia: Float[Array, "6 6"]
    wrench: Float[Array, "6"]
