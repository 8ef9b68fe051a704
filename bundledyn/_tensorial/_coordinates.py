r"""Tensor generalized coordinates (seed 000, §3): scalars, unit vectors, rotation tensors.

A configuration is $X = (q_1, \dots, q_m;\ e_1, \dots, e_n;\ Z_1, \dots, Z_p)$: $m$ scalars
(valence 0), $n$ unit vectors (valence 1, two degrees of freedom each) and $p$ orthonormal
tensors (valence 2, three each), all independent. Their rates are carried by velocities
that keep the motion on the manifold: $\dot q$; the angular velocity $\Omega_k$ of each
axis, $\dot e_k = \Omega_k\times e_k$; and the absolute angular velocity $\omega_k$ of each
rotation, $\dot Z_k = \tilde\omega_k Z_k$ (55). The virtual displacements are those of the
seed's derivation of (44): $\delta q$, $\delta e = \delta\pi\times e$ and $\delta Z =
\delta\tilde\kappa\,Z$.
"""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .. import lie

__all__ = [
    "TensorCoordinates",
    "angular_velocity",
    "TensorVelocities",
    "accelerations_of",
    "projected",
    "rates_of",
]


class TensorCoordinates(eqx.Module):
    r"""Tensor coordinates $X$ (seed 000, §3), or their rates $\dot X$ or $\ddot X$.

    **Fields:**

    - `scalars`: $q$, shape `(m,)`.
    - `unit_vectors`: $e_1, \dots, e_n$, shape `(n, 3)`, each of unit length.
    - `rotations`: $Z_1, \dots, Z_p$, shape `(p, 3, 3)`, each orthonormal with determinant 1.

    As rates the same fields hold $\dot q$, $\dot e_k$ (orthogonal to $e_k$) and $\dot Z_k$.
    """

    scalars: Float[Array, " m"]
    unit_vectors: Float[Array, "n 3"]
    rotations: Float[Array, "p 3 3"]

    @property
    def counts(self) -> tuple[int, int, int]:
        """$(m, n, p)$ (static)."""
        return self.scalars.shape[0], self.unit_vectors.shape[0], self.rotations.shape[0]


class TensorVelocities(eqx.Module):
    r"""The velocities of tensor coordinates, or their rates (seed 000, (55)).

    **Fields:**

    - `scalars`: $\dot q$, shape `(m,)`.
    - `unit_vectors`: $\Omega_k$, shape `(n, 3)`: $\dot e_k = \Omega_k\times e_k$. Only the
      part of $\Omega_k$ orthogonal to $e_k$ moves $e_k$; the equations keep the other at
      its initial value.
    - `rotations`: $\omega_k$, shape `(p, 3)`: $\dot Z_k = \tilde\omega_k Z_k$, the
      absolute angular velocity.
    """

    scalars: Float[Array, " m"]
    unit_vectors: Float[Array, "n 3"]
    rotations: Float[Array, "p 3"]


def rates_of(X: TensorCoordinates, V: TensorVelocities) -> TensorCoordinates:
    r"""$\dot X$: $(\dot q,\ \Omega_k\times e_k,\ \tilde\omega_k Z_k)$ (55).

    **Arguments:**

    - `X`: the coordinates; `V`: their velocities.

    **Returns:**

    The rates, as `TensorCoordinates`.
    """
    return TensorCoordinates(
        V.scalars,
        jnp.cross(V.unit_vectors, X.unit_vectors),
        lie.so3_hat(V.rotations) @ X.rotations,
    )


def angular_velocity(
    Z: Float[Array, "... 3 3"], Zdot: Float[Array, "... 3 3"]
) -> Float[Array, "... 3"]:
    r"""$\omega = (\dot ZZ^T)^\vee$ (55), of the skew part, so that it is read alike off a rate
    that left the tangent space by rounding.

    **Arguments:**

    - `Z`: rotations, shape `(..., 3, 3)`; `Zdot`: their rates.

    **Returns:**

    The absolute angular velocities, shape `(..., 3)`.
    """
    spin = Zdot @ jnp.swapaxes(Z, -1, -2)
    return lie.so3_vee(0.5 * (spin - jnp.swapaxes(spin, -1, -2)))


def accelerations_of(
    X: TensorCoordinates, V: TensorVelocities, A: TensorVelocities
) -> TensorCoordinates:
    r"""$\ddot X$ for the velocities' rates $A = (\ddot q, \dot\Omega_k, \dot\omega_k)$.

    $\ddot e = \dot\Omega\times e + \Omega\times(\Omega\times e)$ and
    $\ddot Z = (\tilde{\dot\omega} + \tilde\omega\tilde\omega)Z$, the derivatives of (55).

    **Arguments:**

    - `X`: the coordinates; `V`: their velocities; `A`: the velocities' rates.

    **Returns:**

    The second rates, as `TensorCoordinates`.
    """
    axis_rate = jnp.cross(V.unit_vectors, X.unit_vectors)
    omega = lie.so3_hat(V.rotations)
    return TensorCoordinates(
        A.scalars,
        jnp.cross(A.unit_vectors, X.unit_vectors) + jnp.cross(V.unit_vectors, axis_rate),
        (lie.so3_hat(A.rotations) + omega @ omega) @ X.rotations,
    )


def projected(
    X: TensorCoordinates, bracket: TensorCoordinates, A: TensorVelocities
) -> TensorVelocities:
    r"""The projection $\tilde X_i \wedge_{\nu_i} [\,\cdot\,]$ of (44), one equation per unknown.

    For each coordinate, the coefficients of its virtual displacement in the virtual work
    of `bracket` $B$: $B$ itself for a scalar; $e\times B$ for a unit vector ($\delta e =
    \delta\pi\times e$, two equations), closed by $(\dot\Omega\cdot e)\,e$, which fixes the
    part of $\dot\Omega$ that does not move $e$ at zero; and for a rotation the vector
    $w_c = B : (\tilde\epsilon_c Z)$ ($\delta Z = \delta\tilde\kappa Z$), which for a
    rigid body's $T$ is $\tfrac{d}{dt}(J\omega)$ (54).

    **Arguments:**

    - `X`: the coordinates.
    - `bracket`: $\tfrac{d}{dt}\partial T/\partial\dot X - \partial T/\partial X - Q$, as
      `TensorCoordinates` of tensors.
    - `A`: the velocities' rates (for the unit vectors' closing equation).

    **Returns:**

    The projected equations, as `TensorVelocities` (zero on the motion).
    """
    e = X.unit_vectors
    generators = lie.so3_hat(jnp.eye(3, dtype=X.rotations.dtype))  # ε̃_c
    moved = jnp.einsum("cab,pbd->pcad", generators, X.rotations)  # ε̃_c Z_p
    return TensorVelocities(
        bracket.scalars,
        jnp.cross(e, bracket.unit_vectors)
        + jnp.sum(A.unit_vectors * e, axis=-1, keepdims=True) * e,
        jnp.einsum("pad,pcad->pc", bracket.rotations, moved),
    )


def checked_state(y) -> tuple[TensorCoordinates, TensorVelocities]:
    """`y` as `(X, V)`, refused with the fix if it is not `TensorCoordinates` and
    `TensorVelocities`."""
    X, V = y if isinstance(y, tuple) and len(y) == 2 else (y, None)
    if not isinstance(X, TensorCoordinates) or not isinstance(V, TensorVelocities):
        raise ValueError(
            "Tensorial terms and solvers step states `(X, V)`: `TensorCoordinates` and "
            f"`TensorVelocities`; got {type(y).__name__} "
            f"{tuple(type(x).__name__ for x in y) if isinstance(y, tuple) else ''}."
        )
    return X, V


def zeros_like_velocities(X: TensorCoordinates) -> TensorVelocities:
    """Zero velocities for the coordinates `X`."""
    m, n, p = X.counts
    dtype = X.rotations.dtype
    return TensorVelocities(jnp.zeros(m, dtype), jnp.zeros((n, 3), dtype), jnp.zeros((p, 3), dtype))
