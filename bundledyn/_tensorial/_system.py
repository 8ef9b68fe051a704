r"""Systems in tensor generalized coordinates (seed 000, §3): $T(t, X, \dot X)$, $\Pi(t, X)$, $Q$."""

import abc
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._coordinates import TensorCoordinates, TensorVelocities, rates_of

__all__ = ["AbstractTensorialSystem", "TensorialSystem", "generalized_forces_at_points"]


class AbstractTensorialSystem(eqx.Module):
    r"""A holonomic system in tensor generalized coordinates $X$ (seed 000, §3).

    Subclasses give the kinetic energy $T(X, \dot X, t)$ and the tensor generalized forces
    $Q_i(X, \dot X, t)$ ((44): $Q_i = \int [1]\partial r/\partial X_i\cdot df$, including
    $-\partial\Pi/\partial X_i$), and optionally the potential $\Pi$ for the energy. $T$
    and $Q$ are functions on the embedding (any $3\times3$ matrix $Z$, any vector $e$): the
    projection of (44) removes what an extension off the manifold adds.
    """

    @abc.abstractmethod
    def kinetic_energy(self, X: TensorCoordinates, Xdot: TensorCoordinates, t) -> Float[Array, ""]:
        r"""$T(X, \dot X, t)$.

        **Arguments:**

        - `X`: the coordinates; `Xdot`: their rates $\dot X$ (`TensorCoordinates`); `t`: the time.

        **Returns:**

        A scalar.
        """

    def potential_energy(self, X: TensorCoordinates, t) -> Float[Array, ""]:
        r"""$\Pi(X, t)$; zero unless the system has a potential.

        **Arguments:**

        - `X`: the coordinates; `t`: the time.

        **Returns:**

        A scalar.
        """
        return jnp.zeros((), X.rotations.dtype)

    def energy(self, X: TensorCoordinates, V: TensorVelocities, t) -> Float[Array, ""]:
        r"""$T + \Pi$ at the coordinates `X` and velocities `V`: conserved when $T$ and $\Pi$
        do not depend on time and no other force acts.

        **Arguments:**

        - `X`: the coordinates; `V`: their velocities; `t`: the time.

        **Returns:**

        A scalar.
        """
        t = jnp.asarray(t, dtype=X.rotations.dtype)
        return self.kinetic_energy(X, rates_of(X, V), t) + self.potential_energy(X, t)

    @abc.abstractmethod
    def generalized_forces(
        self, X: TensorCoordinates, Xdot: TensorCoordinates, t
    ) -> TensorCoordinates:
        r"""The tensor generalized forces $Q_i$ of (44), as `TensorCoordinates` of tensors.

        **Arguments:**

        - `X`: the coordinates; `Xdot`: their rates; `t`: the time.

        **Returns:**

        $Q$: a scalar per scalar coordinate, a vector per unit vector, a $3\times3$ tensor
        per rotation.
        """


class TensorialSystem(AbstractTensorialSystem):
    r"""A system in tensor coordinates given by functions: $T(X, \dot X, t)$, $\Pi(X, t)$, $Q$.

    The forces are $Q_i = -\partial\Pi/\partial X_i + Q_i^{\rm other}$, the gradient by
    autodiff (45). A heavy top in its rotation tensor $Z$, symmetry axis $Ze_3$:

    ```python
    def T(X, Xdot, t):
        Z, Zdot = X.rotations[0], Xdot.rotations[0]
        omega = bd.lie.so3_vee(Zdot @ Z.T)     # (55): Ż = ω̃ Z
        return 0.5 * omega @ (Z @ J0 @ Z.T) @ omega

    top = bd.TensorialSystem(T, Pi=lambda X, t: M * g * l * (X.rotations[0] @ e3)[2])
    ```

    **Arguments:**

    - `T`: the kinetic energy `T(X, Xdot, t) -> scalar`, `X` and `Xdot` `TensorCoordinates`.
    - `Pi`: the potential `Pi(X, t) -> scalar`, or `None`.
    - `Q`: other tensor forces `Q(X, Xdot, t) -> TensorCoordinates` (forces at points:
      `generalized_forces_at_points`), or `None`.

    Make the functions `equinox.Module`s (or close over arrays) to differentiate with
    respect to their parameters.
    """

    T: Callable
    Pi: Callable | None = None
    Q: Callable | None = None

    def __check_init__(self):
        if not callable(self.T):
            raise ValueError("`TensorialSystem.T` must be a callable T(X, Xdot, t) -> scalar.")
        for name, value, signature in (("Pi", self.Pi, "Pi(X, t)"), ("Q", self.Q, "Q(X, Xdot, t)")):
            if value is not None and not callable(value):
                raise ValueError(
                    f"`TensorialSystem.{name}` must be a callable {signature}, or None."
                )

    def kinetic_energy(self, X, Xdot, t):
        return self.T(X, Xdot, t)

    def potential_energy(self, X, t):
        if self.Pi is None:
            return super().potential_energy(X, t)
        return self.Pi(X, t)

    def generalized_forces(self, X, Xdot, t):
        forces = jax.tree.map(jnp.zeros_like, X)
        if self.Pi is not None:
            forces = jax.tree.map(jnp.subtract, forces, jax.grad(self.Pi)(X, t))
        if self.Q is not None:
            forces = jax.tree.map(jnp.add, forces, self.Q(X, Xdot, t))
        return forces


def generalized_forces_at_points(
    position: Callable[[TensorCoordinates], Float[Array, "k 3"]],
    X: TensorCoordinates,
    forces: Float[Array, "k 3"],
) -> TensorCoordinates:
    r"""The tensor generalized forces of forces applied at points, $Q_i = \sum_a [1]\partial r_a/\partial X_i\cdot f_a$ (44).

    The seed's $Q_i = \int [1]\partial r/\partial X_i\cdot df$ for forces $f_a$ at the
    points $r_a(X)$: one vector-Jacobian product of the points' positions. Return it from a
    `TensorialSystem`'s `Q` for forces that have no potential (a thrust, a drag, a
    follower load).

    **Arguments:**

    - `position`: `position(X) -> (k, 3)`, where the forces act.
    - `X`: the coordinates.
    - `forces`: $f_a$, shape `(k, 3)`, in the inertial frame.

    **Returns:**

    $Q$, as `TensorCoordinates` of tensors.
    """
    _, pullback = jax.vjp(position, X)
    (forces_on_coordinates,) = pullback(jnp.asarray(forces, dtype=X.rotations.dtype))
    return forces_on_coordinates
