"""Scenes: a system, the effects acting on it, its shape and base modes and its frame of reference."""

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from . import lie
from ._effects import AbstractEffect, Gravity, Kinematics, ShapeDamper, ShapeSpring
from ._frames import AbstractFrame
from ._systems._base import AbstractSystem
from ._systems._mujoco_import import parts_from_mjcf
from ._systems._multibody import Multibody


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


class FloatingBase(eqx.Module):
    """The section frame moves freely: (2.7) is integrated (the default)."""


class PrescribedBase(eqx.Module):
    r"""The section frame follows a given motion $g(t)$: a fixed base, or one moving like a
    ship's deck; only the shape equation is integrated, driven by the base's motion (the
    dual of `Prescribed`). The base's motion is given in the Galilean frame.

    **Arguments:**

    - `g_of_t`: a JAX function `t -> g (4, 4)`, a pose in SE(3) for every $t$; its body
      velocity $\xi = (g^{-1}\dot g)^\vee$ and $\dot\xi$ come by autodiff.
    """

    g_of_t: Callable

    @classmethod
    def fixed(cls, g=None) -> "PrescribedBase":
        """A base held still at the pose `g` (default the identity)."""
        pose = jnp.eye(4) if g is None else jnp.asarray(g, dtype=float)
        return cls(_Constant(pose))

    def at(self, t):
        r"""$(g, \xi, \dot\xi)$ at time `t`."""

        def velocity(t):
            g, g_dot = jax.jvp(self.g_of_t, (t,), (jnp.ones_like(t),))
            return lie.vee(lie.se3_inv(g) @ g_dot)

        xi, xi_dot = jax.jvp(velocity, (t,), (jnp.ones_like(t),))
        return self.g_of_t(t), xi, xi_dot


class _Constant(eqx.Module):
    value: jax.Array

    def __call__(self, t):
        return self.value + 0.0 * t


class Scene(eqx.Module):
    """A system, the effects acting on it, its shape mode and the frame it is seen from.

    The effects, the shape mode and the frame are static structure: only what a scene
    names is compiled into its vector field (a rigid body gets no shape block, a scene
    without gravity no gravity code).

    **Arguments:**

    - `system`: any `AbstractSystem`.
    - `effects`: a tuple of effects (`Gravity`, `ShapeSpring`, `ExternalWrench`, ...).
    - `shape`: `Free()` (default) or `Prescribed(q_of_t)`.
    - `base`: `FloatingBase()` (default) or `PrescribedBase(g_of_t)`.
    - `frame`: `None` for the Galilean frame (default) or an `AbstractFrame`
      (`Boosted`, `FreeFalling`, `MovingFrame`); the state is then relative to that frame.
    """

    system: AbstractSystem
    effects: list[AbstractEffect]
    shape: Free | Prescribed
    frame: AbstractFrame | None
    base: FloatingBase | PrescribedBase

    def __init__(self, system, effects=(), shape=None, frame=None, *, base=None):
        self.system = system
        # A list, not a tuple: `equinox.tree_at` (used by diffrax's BacksolveAdjoint on the
        # solver state, which holds the scene's cotangent) fails on an empty tuple.
        self.effects = list(effects)
        self.shape = Free() if shape is None else shape
        self.frame = frame
        self.base = FloatingBase() if base is None else base

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
        if not isinstance(self.base, FloatingBase | PrescribedBase):
            raise ValueError("`Scene.base` must be `FloatingBase()` or `PrescribedBase(g_of_t)`.")
        if isinstance(self.base, PrescribedBase):
            if not isinstance(self.shape, Free) or self.system.shape_dim == 0:
                raise ValueError(
                    "`PrescribedBase` integrates the shape equation: it needs a free shape with "
                    "d > 0 (with a prescribed shape too, nothing would be left to integrate)."
                )
            if self.frame is not None:
                raise ValueError(
                    "give a `PrescribedBase`'s motion in the Galilean frame (frame=None)."
                )

    @classmethod
    def from_mjcf(cls, source, *, section=0, passive: bool = False, gravity: bool = False):
        r"""The scene of an MJCF model: its tree and, when asked, its joints' springs and
        dampers and its gravity (MuJoCo's own parser; the `mujoco` extra).

        **Arguments:**

        - `source`: a path to an MJCF file, an MJCF XML string, or a `mujoco.MjModel`.
        - `section`: the section body, as in `Multibody.from_mjcf`.
        - `passive`: add the hinges' and slides' `damping` as a `ShapeDamper` and their
          `stiffness` about `springref` as a `ShapeSpring` (MuJoCo's passive joint forces
          $-b\,\dot q$ and $-k\,(q - q_{\rm spring})$).
        - `gravity`: add the model's `<option gravity>` as a `Gravity` (none if it is zero).

        **Returns:**

        A `Scene` of the `Multibody` with those effects (only those with a non-zero value).
        """
        parts = parts_from_mjcf(source, passive=passive)
        effects = []
        if passive and np.any(parts.damping):
            effects.append(ShapeDamper(parts.damping))
        if passive and np.any(parts.stiffness):
            effects.append(ShapeSpring(parts.stiffness, parts.spring_rest))
        acceleration = np.asarray(parts.model.opt.gravity, dtype=float)
        if gravity and np.any(acceleration):
            size = float(np.linalg.norm(acceleration))
            effects.append(Gravity(size, acceleration / size))
        return cls(Multibody.from_parts(parts, section=section), effects)

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
