"""Scenes: a system, the effects acting on it, its shape mode and its frame of reference."""

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp

from ._effects import AbstractEffect, Kinematics
from ._frames import AbstractFrame
from ._systems._base import AbstractSystem


class Free(eqx.Module):
    """The shape moves dynamically: both equations (2.6) are integrated."""


class Prescribed(eqx.Module):
    r"""The shape follows a given motion $q(t)$ (kinematic shape control).

    Only (2.7) for the locked velocity and the reconstruction $\xi = U - A\dot q$ are
    integrated: the falling cat, a satellite moving its arm.

    **Arguments:**

    - `q_of_t`: a JAX function `t -> q (d,)`; $\dot q$ and $\ddot q$ come by autodiff.
    """

    q_of_t: Callable

    def at(self, t):
        r"""$(q, \dot q)$ at time `t`."""
        return jax.jvp(self.q_of_t, (t,), (jnp.ones_like(t),))


class Scene(eqx.Module):
    """A system, the effects acting on it, its shape mode and the frame it is seen from.

    The effects, the shape mode and the frame are static structure: only what a scene
    names is compiled into its vector field (a rigid body gets no shape block, a scene
    without gravity no gravity code).

    **Arguments:**

    - `system`: any `AbstractSystem`.
    - `effects`: a tuple of effects (`Gravity`, `ShapeSpring`, `ExternalWrench`, ...).
    - `shape`: `Free()` (default) or `Prescribed(q_of_t)`.
    - `frame`: `None` for the Galilean frame (default) or an `AbstractFrame`
      (`Boosted`, `FreeFalling`, `MovingFrame`); the state is then relative to that frame.
    """

    system: AbstractSystem
    effects: list[AbstractEffect]
    shape: Free | Prescribed
    frame: AbstractFrame | None

    def __init__(self, system, effects=(), shape=None, frame=None):
        self.system = system
        # A list, not a tuple: `equinox.tree_at` (used by diffrax's BacksolveAdjoint on the
        # solver state, which holds the scene's cotangent) fails on an empty tuple.
        self.effects = list(effects)
        self.shape = Free() if shape is None else shape
        self.frame = frame

    def __check_init__(self):
        if not isinstance(self.system, AbstractSystem):
            raise ValueError(f"`Scene.system` must be a system, got {type(self.system).__name__}.")
        for e in self.effects:
            if not isinstance(e, AbstractEffect):
                raise ValueError(
                    f"unknown effect {e!r} in `Scene.effects`; use Gravity, GravityGradient, "
                    "BodywiseGravityGradient, ShapePotential, ShapeSpring, ShapeDamper, "
                    "ExternalWrench or ShapeForce (or an AbstractEffect of your own)."
                )
        if not isinstance(self.shape, Free | Prescribed):
            raise ValueError("`Scene.shape` must be `Free()` or `Prescribed(q_of_t)`.")
        if self.frame is not None and not isinstance(self.frame, AbstractFrame):
            raise ValueError("`Scene.frame` must be None (Galilean) or an AbstractFrame.")
        if isinstance(self.shape, Prescribed) and self.system.shape_dim == 0:
            raise ValueError("`Prescribed` needs a system with shape coordinates (d > 0).")

    @property
    def free_shape(self) -> bool:
        """Whether the shape equation (2.6) is integrated: a `Free` shape with $d > 0$."""
        return isinstance(self.shape, Free) and self.system.shape_dim > 0

    def forces(self, kin: Kinematics):
        """Total generalized force `(F_b, Q_H)` of the scene's effects at `kin`."""
        F = jnp.zeros(6, kin.q.dtype)
        Q = jnp.zeros_like(kin.q)
        for effect in self.effects:
            dF, dQ = effect.generalized_force(self.system, kin)
            F, Q = F + dF, Q + dQ
        return F, Q
