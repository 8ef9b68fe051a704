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
from ._systems._mujoco_import import FixedTendon, ModelParts, parts_from_mjcf, parts_from_urdf
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
        r"""The scene of an MJCF model: its tree and, when asked, its springs and dampers and
        its gravity (MuJoCo's own parser; the `mujoco` extra).

        **Arguments:**

        - `source`: a path to an MJCF file, an MJCF XML string, or a `mujoco.MjModel`.
        - `section`: the section body, as in `Multibody.from_mjcf`.
        - `passive`: add MuJoCo's linear passive forces: the hinges' and slides' `damping`
          and the fixed tendons' `damping` as one `ShapeDamper` ($-b\,\dot q$ per joint,
          $-b\,c\,c^T\dot q$ per tendon of length $c^T q + L_0$), the joints' `stiffness`
          about `springref` as a `ShapeSpring` ($-k\,(q - q_{\rm spring})$) and each
          tendon's `stiffness` about its `springlength` $L_s$ as a `ShapeSpring` of rank one
          ($\tfrac12 k\,(c^T q + L_0 - L_s)^2$).
        - `gravity`: add the model's `<option gravity>` as a `Gravity` (none if it is zero).

        **Returns:**

        A `Scene` of the `Multibody` with those effects (only those with a non-zero value).
        """
        parts = parts_from_mjcf(source, passive=passive)
        return cls._of_model(parts, section=section, passive=passive, gravity=gravity)

    @classmethod
    def from_urdf(cls, path, *, section=0, passive: bool = False, gravity: bool = False):
        r"""The scene of a URDF model: its tree and, when asked, its joints' dampers and
        gravity (MuJoCo's own URDF parser; the `mujoco` extra).

        **Arguments:**

        - `path`: a path to a `.urdf` file.
        - `section`: the section body, as in `Multibody.from_urdf`.
        - `passive`: add the joints' `<dynamics damping>` as a `ShapeDamper`.
        - `gravity`: add standard gravity, $9.81$ m/s² along $-z$ (URDF states none; this
          is MuJoCo's default).

        **Returns:**

        A `Scene` of the `Multibody` with those effects.
        """
        parts = parts_from_urdf(path, passive=passive)
        return cls._of_model(parts, section=section, passive=passive, gravity=gravity)

    @classmethod
    def _of_model(cls, parts: ModelParts, *, section, passive: bool, gravity: bool):
        effects = _passive_effects(parts) if passive else []
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


def _passive_effects(parts: ModelParts) -> list[AbstractEffect]:
    """MuJoCo's linear passive forces of an imported model: one damper (diagonal unless a
    tendon couples the coordinates), the joints' springs, and one spring per tendon."""
    effects: list[AbstractEffect] = []
    damped = [t for t in parts.tendons if t.damping != 0]
    if damped:
        c = np.diag(parts.damping) + sum(
            t.damping * np.outer(t.coefficients, t.coefficients) for t in damped
        )
        effects.append(ShapeDamper(c))
    elif np.any(parts.damping):
        effects.append(ShapeDamper(parts.damping))
    if np.any(parts.stiffness):
        effects.append(ShapeSpring(parts.stiffness, parts.spring_rest))
    effects += [_tendon_spring(t) for t in parts.tendons if t.stiffness != 0]
    return effects


def _tendon_spring(tendon: FixedTendon) -> ShapeSpring:
    r"""$\tfrac12 k\,(c^T q + L_0 - L_s)^2$ as $\tfrac12 (q - q_0)^T k\,c\,c^T (q - q_0)$,
    with the rest shape $q_0 = c\,(L_s - L_0)/|c|^2$ on the tendon's direction."""
    c = tendon.coefficients
    rest = c * (tendon.spring_length - tendon.length_at_home) / (c @ c)
    return ShapeSpring(tendon.stiffness * np.outer(c, c), rest)
