r"""Frames of reference in which a scene is written (seed 004, §2 (2.8)–(2.10), §3).

A frame $\mathcal R'$ moves relative to the Galilean frame $\mathcal R$ by $M(t)\in SE(3)$:
a configuration seen as $\sigma$ from $\mathcal R'$ is $s = M(t)\cdot\sigma$ in $\mathcal R$.
A scene in a moving frame integrates the true (Galilean) dynamics expressed in
$\mathcal R'$, i.e. (2.9)–(2.10) with all their frame terms.
"""

import abc
from collections.abc import Callable
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.typing import ArrayLike
from jaxtyping import Array, Float

from . import lie


class AbstractFrame(eqx.Module):
    """A frame of reference moving by $M(t)$ relative to the Galilean frame."""

    # The frame in words, for titles and printed summaries.
    name: ClassVar[str] = "the moving frame"

    @abc.abstractmethod
    def motion(self, t) -> Float[Array, "4 4"]:
        """$M(t)$, the pose of the frame in the Galilean frame."""

    def motion_and_velocity(self, t):
        r"""$M$, the frame's body velocity $\vartheta = (M^{-1}\dot M)^\vee$ and its derivative $\dot\vartheta$."""

        def theta(t):
            M, Mdot = jax.jvp(self.motion, (t,), (jnp.ones_like(t),))
            return lie.vee(lie.se3_inv(M) @ Mdot)

        theta_t, theta_dot = jax.jvp(theta, (t,), (jnp.ones_like(t),))
        return self.motion(t), theta_t, theta_dot


class MovingFrame(AbstractFrame):
    """Any frame motion given as a JAX function of time.

    **Arguments:**

    - `fn`: `M(t) -> (4, 4)`, a pose in SE(3) for every t; its first and second derivatives
      are taken by autodiff.
    """

    fn: Callable

    def motion(self, t):
        return self.fn(t)


def _translation(x):
    return jnp.eye(4, dtype=x.dtype).at[:3, 3].set(x)


class Boosted(AbstractFrame):
    r"""A Galilean boost: the frame translates with constant `velocity`, $M(t) = (1, t\,u)$.

    Under Theorem 2.2's conditions the equations are the same in this frame.

    **Arguments:**

    - `velocity`: $u$, shape `(3,)`, in the Galilean frame.
    """

    name: ClassVar[str] = "the boosted frame"

    velocity: Float[Array, "3"]

    def __init__(self, velocity):
        self.velocity = jnp.asarray(velocity, dtype=float)

    def motion(self, t):
        return _translation(t * self.velocity)


class FreeFalling(AbstractFrame):
    r"""A frame falling freely in uniform gravity: $M(t) = \exp(z(t)\chi)$, $z = \tfrac12 g t^2$ (Theorem 3.4).

    **Arguments:**

    - `g`: magnitude of gravity; `direction`: its unit direction $\chi$ (default $-e_z$).
    """

    name: ClassVar[str] = "the falling frame"

    g: Float[Array, ""]
    direction: Float[Array, "3"]

    def __init__(self, g: ArrayLike = 9.81, direction=(0.0, 0.0, -1.0)):
        self.g = jnp.asarray(g, dtype=float)
        direction = jnp.asarray(direction, dtype=float)
        self.direction = direction / jnp.linalg.norm(direction)

    def motion(self, t):
        return _translation(0.5 * self.g * t**2 * self.direction)
