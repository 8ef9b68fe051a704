r"""The fitted parameters of a scene as one vector of unconstrained reals.

Each free body contributes its log-Cholesky coordinates (ten; seven for a body whose centre
of mass is fixed at the section origin), so that every vector is a physical system; each
free joint constant (the stiffness of the scene's `ShapeSpring`, the damping of its
`ShapeDamper`, the rotor inertia of its `Multibody`) contributes its logarithm, so that
it stays positive.
"""

from typing import cast

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._effects import ShapeDamper, ShapeSpring
from .._modes import PrescribedBase
from .._scene import Scene
from .._systems._base import AbstractInertialSystem
from .._systems._multibody import AbstractMultibody, Multibody
from .._systems._pseudo_inertia import (
    inertial_from_pseudo_inertia,
    log_cholesky_from_pseudo_inertia,
    pseudo_inertia_from_log_cholesky,
)

__all__ = ["Parameters"]


def _spring_stiffness(scene: Scene):
    return cast(ShapeSpring, scene.effects[_effect_index(scene, ShapeSpring)]).stiffness


def _damping(scene: Scene):
    return cast(ShapeDamper, scene.effects[_effect_index(scene, ShapeDamper)]).c


def _armature(scene: Scene):
    if not isinstance(scene.system, Multibody):
        raise ValueError("only a `Multibody` has a rotor inertia (`armature`) to fit.")
    return scene.system.armature


# Where each joint constant lives in a scene (also the `where` of `eqx.tree_at`).
_JOINT_CONSTANTS = {"stiffness": _spring_stiffness, "damping": _damping, "armature": _armature}
_COORDINATES = ("alpha", "d1", "d2", "d3", "s12", "s23", "s13", "t1", "t2", "t3")


def _body_names(system) -> tuple[str, ...]:
    if isinstance(system, AbstractMultibody):
        return system.names
    return ("body",)


def _held_body(scene: Scene) -> int | None:
    """The body of a tree whose motion a `PrescribedBase` gives (its section body): its
    inertia enters no equation. None for a floating base, or a single body."""
    if isinstance(scene.base, PrescribedBase) and isinstance(scene.system, AbstractMultibody):
        return getattr(scene.system, "section", 0)
    return None


def _effect_index(scene: Scene, kind) -> int:
    matches = [i for i, e in enumerate(scene.effects) if isinstance(e, kind)]
    if not matches:
        raise ValueError(f"the scene has no {kind.__name__} whose constant could be fitted.")
    return matches[0]


class Parameters(eqx.Module):
    r"""Which parameters of a scene an identification fits, as a vector $\theta$ of reals.

    **Arguments:**

    - `scene`: the nominal scene: its system (an `AbstractInertialSystem`) and effects give
      the structure, the known values and the starting point.
    - `bodies`: the bodies whose inertial parameters are free, by index or name (static;
      default all whose inertia enters the equations: for a tree on a `PrescribedBase`,
      all but the section body, whose motion is given, e.g. an imported model's world
      stand-in). The others keep the nominal values.
    - `joint_constants`: which joint constants are free (static): `"stiffness"` (of the
      scene's first `ShapeSpring`), `"damping"` (of its first `ShapeDamper`) and
      `"armature"` (the `Multibody`'s rotor inertia); each must be positive in the nominal
      scene (a scalar or one value per coordinate).
    """

    scene: Scene
    bodies: tuple[int, ...] = eqx.field(static=True)
    joint_constants: tuple[str, ...] = eqx.field(static=True)

    def __init__(self, scene: Scene, *, bodies=None, joint_constants=()):
        system = scene.system
        if not isinstance(system, AbstractInertialSystem):
            raise ValueError(
                f"{type(system).__name__} has no inertial parameters to fit; identification "
                "fits RigidBody, Multibody and AffineBody systems."
            )
        names = _body_names(system)
        held = _held_body(scene)
        moving = [b for b in range(len(names)) if b != held]
        chosen = moving if bodies is None else bodies
        indices = tuple(names.index(b) if isinstance(b, str) else int(b) for b in chosen)
        for b in indices:
            if not 0 <= b < len(names):
                raise ValueError(f"`bodies` names body {b}; the system has bodies {names}.")
        for name in joint_constants:
            if name not in _JOINT_CONSTANTS:
                raise ValueError(
                    f"unknown joint constant {name!r}; use 'stiffness', 'damping' or 'armature'."
                )
            value = np.asarray(_JOINT_CONSTANTS[name](scene))
            if value.ndim > 1 or not np.all(value > 0):
                raise ValueError(
                    f"the nominal {name} must be positive, a scalar or one value per "
                    f"coordinate, to be fitted (as its logarithm); got {value}."
                )
        self.scene = scene
        self.bodies = tuple(sorted(set(indices)))
        self.joint_constants = tuple(joint_constants)

    @property
    def system(self) -> AbstractInertialSystem:
        """The nominal system (an `AbstractInertialSystem`, checked at construction)."""
        return cast(AbstractInertialSystem, self.scene.system)

    @property
    def body_names(self) -> tuple[str, ...]:
        """The names of all the system's bodies (free or not)."""
        return _body_names(self.scene.system)

    @property
    def _coordinates(self) -> int:
        return 7 if self.system.fixed_centres else 10

    def _constant(self, name):
        return _JOINT_CONSTANTS[name](self.scene)

    def initial(self):
        r"""$\theta$ of the nominal scene, shape `(size,)`."""
        P = self.system.pseudo_inertias()[np.array(self.bodies, int)]
        theta = log_cholesky_from_pseudo_inertia(P)[:, : self._coordinates].reshape(-1)
        logs = [jnp.log(jnp.atleast_1d(self._constant(n))) for n in self.joint_constants]
        return jnp.concatenate([theta, *logs])

    @property
    def size(self) -> int:
        """The number of free parameters."""
        constants = sum(np.size(self._constant(n)) for n in self.joint_constants)
        return len(self.bodies) * self._coordinates + int(constants)

    def labels(self) -> tuple[str, ...]:
        r"""A name for each entry of $\theta$: body and log-Cholesky coordinate, or constant."""
        names = _body_names(self.scene.system)
        labels = [f"{names[b]}.{c}" for b in self.bodies for c in _COORDINATES[: self._coordinates]]
        for n in self.joint_constants:
            size = np.size(self._constant(n))
            labels += [f"log {n}"] if size == 1 else [f"log {n}[{k}]" for k in range(size)]
        return tuple(labels)

    def scales(self, theta) -> np.ndarray:
        r"""Each entry's natural unit at $\theta$: 1 for the logarithms, the body's radius of
        gyration for the log-Cholesky entries that are lengths ($s_{ij}$, $t_i$)."""
        n = self._coordinates
        m, _, J = inertial_from_pseudo_inertia(self.pseudo_inertias(theta))
        radius = np.sqrt(np.trace(np.asarray(J), axis1=1, axis2=2) / (2 * np.asarray(m)))
        per_body = [np.where(np.arange(n) >= 4, r, 1.0) for r in radius]
        return np.concatenate([*per_body, np.ones(self.size - len(self.bodies) * n)])

    def pseudo_inertias(self, theta):
        r"""The free bodies' pseudo-inertias at $\theta$, shape `(k, 4, 4)`."""
        k, n = len(self.bodies), self._coordinates
        coordinates = theta[: k * n].reshape(k, n)
        if n < 10:
            coordinates = jnp.concatenate([coordinates, jnp.zeros((k, 10 - n), theta.dtype)], 1)
        return pseudo_inertia_from_log_cholesky(coordinates)

    def joint_constant_values(self, theta) -> dict:
        r"""The free joint constants at $\theta$ (positive), by name."""
        offset, values = len(self.bodies) * self._coordinates, {}
        for n in self.joint_constants:
            nominal = self._constant(n)
            size = int(np.size(nominal))
            values[n] = jnp.exp(theta[offset : offset + size]).reshape(jnp.shape(nominal))
            offset += size
        return values

    def with_joint_constant(self, scene: Scene, name: str, value) -> Scene:
        """`scene` with the joint constant `name` (`"stiffness"`, `"damping"`, `"armature"`)
        set to `value`."""
        return eqx.tree_at(_JOINT_CONSTANTS[name], scene, value)

    def to_scene(self, theta) -> Scene:
        r"""The scene at $\theta$: the nominal scene with the free parameters replaced."""
        system = self.system
        P = system.pseudo_inertias().at[np.array(self.bodies, int)].set(self.pseudo_inertias(theta))
        scene = eqx.tree_at(lambda s: s.system, self.scene, system.with_pseudo_inertias(P))
        for name, value in self.joint_constant_values(theta).items():
            scene = self.with_joint_constant(scene, name, value)
        return scene
