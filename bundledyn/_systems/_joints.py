r"""Joints of a multibody tree, each a product of elementary motions.

A joint moves a child body relative to its home placement in the parent. Every joint is
a product of elementary factors, each with a closed-form exponential:

- a *screw* factor, one coordinate $\theta$: $\exp(\theta \hat S)$ with $S = (k, a\times k)$
  (rotation about the axis $k$ through the anchor $a$) or $S = (0, k)$ (translation along $k$);
- a *ball* factor, three coordinates $\varphi$ (the rotation vector, exponential coordinates):
  rotation $\exp(\tilde\varphi)$ about the anchor $a$.

The rotation vector has no gimbal lock: its chart is regular for $|\varphi| < 2\pi$ (the
left-trivialized $\operatorname{dexp}$ is invertible there), so a spherical joint can turn
in any direction through any angle below one full turn from its home pose.
All axes and anchors are in the child body's frame at its home placement (MuJoCo's
convention for joint `axis` and `pos`).
"""

import abc
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._validation import check_shape, concrete


def _unit(name: str, axis) -> Array:
    axis = jnp.asarray(axis, dtype=float)
    check_shape(name, axis, (3,))
    a = concrete(axis)
    if a is not None:
        if not np.all(np.isfinite(a)) or np.linalg.norm(a) == 0:
            raise ValueError(f"`{name}` must be a finite non-zero 3-vector, got {a}.")
        return axis / np.linalg.norm(a)
    return axis / jnp.linalg.norm(axis)


def _point(name: str, anchor) -> Array:
    anchor = jnp.asarray(anchor, dtype=float)
    check_shape(name, anchor, (3,))
    return anchor


def _rotation_screw(axis, anchor) -> Array:
    return jnp.concatenate([axis, jnp.cross(anchor, axis)])


class AbstractJoint(eqx.Module):
    """A joint: a product of elementary screw and ball factors (see module docstring)."""

    dof: ClassVar[int]

    @abc.abstractmethod
    def factors(self) -> tuple[tuple[str, Array], ...]:
        r"""The elementary factors in order: `("screw", S)` with $S\in\mathbb{R}^6$ or
        `("ball", a)` with the anchor $a\in\mathbb{R}^3$."""


class Revolute(AbstractJoint):
    r"""Rotation by an angle $\theta$ about `axis` through `anchor` (child frame)."""

    axis: Float[Array, "3"]
    anchor: Float[Array, "3"]
    dof: ClassVar[int] = 1

    def __init__(self, axis, anchor=(0.0, 0.0, 0.0)):
        self.axis = _unit("Revolute.axis", axis)
        self.anchor = _point("Revolute.anchor", anchor)

    def factors(self):
        return (("screw", _rotation_screw(self.axis, self.anchor)),)


class Prismatic(AbstractJoint):
    """Translation by a distance $s$ along `axis` (child frame)."""

    axis: Float[Array, "3"]
    dof: ClassVar[int] = 1

    def __init__(self, axis):
        self.axis = _unit("Prismatic.axis", axis)

    def factors(self):
        return (("screw", jnp.concatenate([jnp.zeros(3, self.axis.dtype), self.axis])),)


class Universal(AbstractJoint):
    r"""Rotation about `axis1` (fixed in the parent), then about `axis2` (fixed in the child).

    Both axes pass through `anchor` and are given in the child frame at home; they must
    not be parallel. Coordinates $(\theta_1, \theta_2)$, motion
    $\exp(\theta_1 \hat S_1)\exp(\theta_2 \hat S_2)$ (a Cardan/Hooke joint).
    """

    axis1: Float[Array, "3"]
    axis2: Float[Array, "3"]
    anchor: Float[Array, "3"]
    dof: ClassVar[int] = 2

    def __init__(self, axis1, axis2, anchor=(0.0, 0.0, 0.0)):
        self.axis1 = _unit("Universal.axis1", axis1)
        self.axis2 = _unit("Universal.axis2", axis2)
        self.anchor = _point("Universal.anchor", anchor)

    def __check_init__(self):
        a1, a2 = concrete(self.axis1), concrete(self.axis2)
        if a1 is not None and a2 is not None and np.linalg.norm(np.cross(a1, a2)) < 1e-8:
            raise ValueError("`Universal.axis1` and `Universal.axis2` must not be parallel.")

    def factors(self):
        return (
            ("screw", _rotation_screw(self.axis1, self.anchor)),
            ("screw", _rotation_screw(self.axis2, self.anchor)),
        )


class Spherical(AbstractJoint):
    r"""Any rotation about `anchor` (child frame), in exponential coordinates $\varphi\in\mathbb{R}^3$.

    The child's rotation relative to its home placement is $\exp(\tilde\varphi)$ and its body
    angular velocity is $\omega = \operatorname{dexp}(\varphi)\dot\varphi$ (left-trivialized
    dexp, the right Jacobian of SO(3)). No gimbal lock: the chart is singular only at
    $|\varphi| = 2\pi$, a full turn away from home, and the Lie-group solvers move every
    ball joint back to $|\varphi| \le \pi$ at the start of each step (`SceneTerm.recharted`:
    the same rotation and angular velocity), so a joint turns any number of times.
    (MuJoCo stores a ball joint as a quaternion; the converters of `Multibody` map
    between the two.)
    """

    anchor: Float[Array, "3"]
    dof: ClassVar[int] = 3

    def __init__(self, anchor=(0.0, 0.0, 0.0)):
        self.anchor = _point("Spherical.anchor", anchor)

    def factors(self):
        return (("ball", self.anchor),)


class Fixed(AbstractJoint):
    """A rigid weld of the child to its parent at the home placement (no coordinates)."""

    dof: ClassVar[int] = 0

    def factors(self):
        return ()


class Composite(AbstractJoint):
    r"""Several joints acting in sequence on one body (MuJoCo bodies with more than one joint).

    **Arguments:**

    - `joints`: the joints, applied left to right: motion $J_1(q_1) J_2(q_2) \cdots$.
    """

    joints: tuple[AbstractJoint, ...]

    def __init__(self, joints):
        self.joints = tuple(joints)
        for j in self.joints:
            if not isinstance(j, AbstractJoint):
                raise ValueError(
                    f"unknown joint type {type(j).__name__!r} in `Composite.joints`; use "
                    "Revolute, Prismatic, Universal, Spherical or Fixed."
                )

    @property
    def dof(self) -> int:  # type: ignore[override]
        return sum(j.dof for j in self.joints)

    def factors(self):
        return tuple(f for j in self.joints for f in j.factors())
