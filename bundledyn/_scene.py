"""Scenes: a system, the effects acting on it, its shape and base modes and its frame of reference."""

import warnings

import equinox as eqx
import numpy as np

from ._coupled_effects import on_full_shape
from ._effects import (
    AbstractEffect,
    Gravity,
    Kinematics,
    ShapeDamper,
    ShapeSpring,
    total_force,
)
from ._frames import AbstractFrame
from ._modes import (
    AbstractFieldAlgorithm,
    AbstractMode,
    FloatingBase,
    Free,
    Prescribed,
    PrescribedBase,
    default_algorithm,
    mode_of,
)
from ._systems._base import AbstractSystem
from ._systems._constrained import ConstrainedSystem, JointCoupling
from ._systems._mujoco_import import (
    WORLD,
    FixedTendon,
    ModelParts,
    model_gravity,
    model_turns_off,
    parts_from_mjcf,
    parts_from_urdf,
)
from ._systems._multibody import Multibody
from ._tendons import SitePath, TendonDamper, TendonSpring


class Scene(eqx.Module):
    """A system, the effects acting on it, its mode and the frame it is seen from.

    The effects, the mode and the frame are static structure: only what a scene names is
    compiled into its vector field (a rigid body gets no shape block, a scene without
    gravity no gravity code).

    **Arguments:**

    - `system`: any `AbstractSystem`.
    - `effects`: a tuple of effects (`Gravity`, `ShapeSpring`, `ExternalWrench`, ...).
    - `shape`: `Free()` (default) or `Prescribed(q_of_t)`.
    - `frame`: `None` for the Galilean frame (default) or an `AbstractFrame`
      (`Boosted`, `FreeFalling`, `MovingFrame`); the state is then relative to that frame.
    - `base`: `FloatingBase()` (default) or `PrescribedBase(g_of_t)`.
    - `mode`: an `AbstractMode` of your own, in place of `shape` and `base` (which choose
      among the built-in modes: `FreeShapeMode`, `RigidBodyMode`, `PrescribedShapeMode`,
      `PrescribedBaseMode`).
    - `algorithm`: how the field solves for the accelerations, an `AbstractFieldAlgorithm`:
      `ArticulatedBodyField()` (the default for a `Multibody` at its base with shape
      coordinates, work growing with the bodies) or `DenseField()` (the default for every
      other system; the shorter compile for long chains). Both give the same motion to
      rounding.
    """

    system: AbstractSystem
    effects: list[AbstractEffect]
    frame: AbstractFrame | None
    mode: AbstractMode
    algorithm: AbstractFieldAlgorithm

    def __init__(
        self, system, effects=(), shape=None, frame=None, *, base=None, mode=None, algorithm=None
    ):
        if not isinstance(system, AbstractSystem):
            raise ValueError(f"`Scene.system` must be a system, got {type(system).__name__}.")
        self.system = system
        # A list, not a tuple: `equinox.tree_at` (used by diffrax's BacksolveAdjoint on the
        # solver state, which holds the scene's cotangent) fails on an empty tuple.
        self.effects = list(effects)
        self.frame = frame
        if mode is None:
            shape = Free() if shape is None else shape
            mode = mode_of(system, shape, FloatingBase() if base is None else base)
        elif shape is not None or base is not None:
            raise ValueError("give a `Scene` either `mode` or `shape` and `base`, not both.")
        self.mode = mode
        self.algorithm = default_algorithm(system) if algorithm is None else algorithm

    def __check_init__(self):
        for e in self.effects:
            if not isinstance(e, AbstractEffect):
                raise ValueError(
                    f"unknown effect {e!r} in `Scene.effects`; use Gravity, GravityGradient, "
                    "BodywiseGravityGradient, ShapePotential, ShapeSpring, ShapeDamper, "
                    "ExternalWrench or ShapeForce (or an AbstractEffect of your own)."
                )
        if self.frame is not None and not isinstance(self.frame, AbstractFrame):
            raise ValueError("`Scene.frame` must be None (Galilean) or an AbstractFrame.")
        if not isinstance(self.mode, AbstractMode):
            raise ValueError(f"`Scene.mode` must be an AbstractMode, got {self.mode!r}.")
        self.mode.check(self.system, self.frame)
        if not isinstance(self.algorithm, AbstractFieldAlgorithm):
            raise ValueError(
                "`Scene.algorithm` must be an AbstractFieldAlgorithm (`ArticulatedBodyField()` "
                f"or `DenseField()`), got {self.algorithm!r}."
            )
        self.algorithm.check(self.system)

    @property
    def shape(self) -> Free | Prescribed:
        """The shape's motion: `Free()` or `Prescribed(q_of_t)` (the mode's)."""
        return self.mode.shape

    @property
    def base(self) -> FloatingBase | PrescribedBase:
        """The base's motion: `FloatingBase()` or `PrescribedBase(g_of_t)` (the mode's)."""
        return self.mode.base

    @classmethod
    def from_mjcf(
        cls, source, *, section=0, passive: bool = False, gravity: bool = False, algorithm=None
    ):
        r"""The scene of an MJCF model: its tree and, when asked, its springs and dampers and
        its gravity (MuJoCo's own parser; the `mujoco` extra).

        **Arguments:**

        - `source`: a path to an MJCF file, an MJCF XML string, or a `mujoco.MjModel`.
        - `section`: the section body, as in `Multibody.from_mjcf`.
        - `passive`: add MuJoCo's linear passive forces: the hinges' and slides' `damping`
          and the fixed tendons' `damping` as one `ShapeDamper` ($-b\,\dot q$ per joint,
          $-b\,c\,c^T\dot q$ per tendon of length $c^T q + L_0$), the joints' `stiffness`
          about `springref` as a `ShapeSpring` ($-k\,(q - q_{\rm spring})$) and each fixed
          tendon's `stiffness` about its `springlength` $L_s$ as a `ShapeSpring` of rank one
          ($\tfrac12 k\,(c^T q + L_0 - L_s)^2$); a spatial tendon from site to site, its
          `stiffness` and `damping` as a `TendonSpring` and a `TendonDamper`. The springs
          or dampers the model's `<flag spring="disable">` or `<flag damper="disable">`
          turns off are not added (which warns).
        - `gravity`: add the model's `<option gravity>` as a `Gravity` (none if it is zero,
          or if the model's `<flag gravity="disable">` turns it off, which warns).
        - `algorithm`: as for `Scene` (by default the articulated-body recursions for any
          tree they cover).

        **Returns:**

        A `Scene` of the `Multibody` with those effects (only those with a non-zero value),
        its base held at the root's pose where the model welds the root to the world (a
        root without a joint, as MuJoCo does; a `<freejoint/>` on the root floats it).
        """
        parts = parts_from_mjcf(source, passive=passive)
        system = system_of_parts(parts, section=section)
        effects = model_effects(parts, passive=passive, gravity=gravity)
        return cls(system, effects, base=model_base(parts, section=section), algorithm=algorithm)

    @classmethod
    def from_urdf(
        cls, path, *, section=0, passive: bool = False, gravity: bool = False, algorithm=None
    ):
        r"""The scene of a URDF model: its tree and, when asked, its joints' dampers and
        gravity (MuJoCo's own URDF parser; the `mujoco` extra).

        **Arguments:**

        - `path`: a path to a `.urdf` file.
        - `section`: the section body, as in `Multibody.from_urdf`.
        - `passive`: add the joints' `<dynamics damping>` as a `ShapeDamper`.
        - `gravity`: add standard gravity, $9.81$ m/s² along $-z$ (URDF states none; this
          is MuJoCo's default).
        - `algorithm`: as for `Scene`.

        **Returns:**

        A `Scene` of the `Multibody` with those effects.
        """
        parts = parts_from_urdf(path, passive=passive)
        system = system_of_parts(parts, section=section)
        effects = model_effects(parts, passive=passive, gravity=gravity)
        return cls(system, effects, algorithm=algorithm)

    def forces(self, kin: Kinematics):
        """Total generalized force `(F_b, Q_H)` of the scene's effects at `kin`."""
        return total_force(self.effects, self.system, kin)


def system_of_parts(parts: ModelParts, *, section=0) -> AbstractSystem:
    """The system of an imported model's parts: its tree (`Multibody.from_parts`) and, if
    the model couples joints (`<equality><joint>`), the tree on its free coordinates
    (`ConstrainedSystem` with the couplings as a `JointCoupling`)."""
    tree = Multibody.from_parts(parts, section=section)
    if not parts.couplings:
        return tree
    return ConstrainedSystem(tree, JointCoupling(tree.shape_dim, parts.couplings))


def model_effects(parts: ModelParts, *, passive: bool, gravity: bool) -> list[AbstractEffect]:
    """The effects an imported model asks for: its linear springs and dampers (`passive`)
    and its `<option gravity>` (`gravity`; none if it is zero), as `Scene.from_mjcf` adds.
    A model that couples joints has its springs and dampers on its full shape
    (`on_full_shape`)."""
    effects = _passive_effects(parts, model_turns_off(parts.model)) if passive else []
    if parts.couplings:
        effects = [on_full_shape(effect) for effect in effects]
    if not gravity:
        return effects
    acceleration = model_gravity(parts.model)
    if acceleration is None:
        warnings.warn(
            'the model turns gravity off (<flag gravity="disable">): no `Gravity` is added.',
            stacklevel=3,
        )
    elif np.any(acceleration):
        size = float(np.linalg.norm(acceleration))
        effects.append(Gravity(size, acceleration / size))
    return effects


def model_base(parts: ModelParts, *, section=0) -> PrescribedBase | None:
    """The base of an imported model as MuJoCo has it: held at the root's pose where the
    model welds its root to the world (no joint on the root), at the world's frame where
    it attaches its root to the world by joints (the base is the world's stand-in), else
    None (floating).

    **Raises:**

    `ValueError` for a held base with the section at another body, which would float.
    """
    if parts.root_pose is None:
        return None
    if section not in (0, parts.names[0]):
        held = (
            "attaches its root body to the world by joints, so the world"
            if parts.names[0] == WORLD
            else f"welds its root body '{parts.names[0]}' to the world (it has no joint), so "
            "the root"
        )
        raise ValueError(
            f"the model {held} is the scene's fixed base and the section frame: use "
            "section=0, or put a <freejoint/> on the root to float the model."
        )
    return PrescribedBase.fixed(parts.root_pose)


def _passive_effects(parts: ModelParts, off: tuple[str, ...]) -> list[AbstractEffect]:
    """MuJoCo's linear passive forces of an imported model: one damper (diagonal unless a
    fixed tendon couples the coordinates), the joints' springs, one spring per fixed tendon,
    and a spring and a damper along each spatial tendon; without the springs or the
    dampers that the model's flags turn `off` (which warns)."""
    if off:
        flags = " ".join(f'<flag {kind}="disable">' for kind in off)
        warnings.warn(
            f"the model turns its {' and '.join(k + 's' for k in off)} off ({flags}): "
            "bundledyn adds none either.",
            stacklevel=4,
        )
    return [e for e in _model_passive_effects(parts) if _kind(e) not in off]


def _kind(effect: AbstractEffect) -> str:
    return "damper" if isinstance(effect, (ShapeDamper, TendonDamper)) else "spring"


def _model_passive_effects(parts: ModelParts) -> list[AbstractEffect]:
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
    for tendon in parts.spatial_tendons:
        path = SitePath(tendon.bodies, tendon.points)
        if tendon.stiffness != 0:
            effects.append(TendonSpring(path, tendon.stiffness, tendon.spring_length))
        if tendon.damping != 0:
            effects.append(TendonDamper(path, tendon.damping))
    return effects


def _tendon_spring(tendon: FixedTendon) -> ShapeSpring:
    r"""$\tfrac12 k\,(c^T q + L_0 - L_s)^2$ as $\tfrac12 (q - q_0)^T k\,c\,c^T (q - q_0)$,
    with the rest shape $q_0 = c\,(L_s - L_0)/|c|^2$ on the tendon's direction."""
    c = tendon.coefficients
    rest = c * (tendon.spring_length - tendon.length_at_home) / (c @ c)
    return ShapeSpring(tendon.stiffness * np.outer(c, c), rest)
