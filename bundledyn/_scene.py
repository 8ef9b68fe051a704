"""Scenes: a system, the effects acting on it, its shape mode and its frame of reference."""

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.tree_util as jtu

from . import lie
from ._dynamics import bundle_geometry, locked_acceleration, shape_acceleration
from ._effects import AbstractEffect, Kinematics
from ._frames import AbstractFrame
from ._geometry import connection
from ._linalg import matmul
from ._solver._state import AbstractBodyTerm, tangent_of_twist
from ._systems._base import AbstractSystem


class Free(eqx.Module):
    """The shape moves dynamically: both equations (2.6) are integrated."""


class Prescribed(eqx.Module):
    """The shape follows a given motion $q(t)$ (kinematic shape control).

    Only (2.7) for the locked velocity and the reconstruction $\\xi = U - A\\dot q$ are
    integrated: the falling cat, a satellite moving its arm.

    **Arguments:**

    - `q_of_t`: a JAX function `t -> q (d,)`; $\\dot q$ and $\\ddot q$ come by autodiff.
    """

    q_of_t: Callable

    def at(self, t):
        """$(q, \\dot q)$ at time `t`."""
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
                    "ShapePotential, ShapeSpring, ShapeDamper, ExternalWrench or ShapeForce."
                )
        if not isinstance(self.shape, Free | Prescribed):
            raise ValueError("`Scene.shape` must be `Free()` or `Prescribed(q_of_t)`.")
        if self.frame is not None and not isinstance(self.frame, AbstractFrame):
            raise ValueError("`Scene.frame` must be None (Galilean) or an AbstractFrame.")
        if isinstance(self.shape, Prescribed) and self.system.shape_dim == 0:
            raise ValueError("`Prescribed` needs a system with shape coordinates (d > 0).")

    @property
    def free_shape(self) -> bool:
        return isinstance(self.shape, Free) and self.system.shape_dim > 0

    # State layout: y = (g, x), x = [q, U, q̇] for a free shape, x = U otherwise.
    def split(self, t, x):
        """`(q, U, qdot)` from the flat part `x` of the integration state at time `t`."""
        if isinstance(self.shape, Prescribed):
            q, qdot = self.shape.at(t)
            return q, x, qdot
        d = self.system.shape_dim
        return x[:d], x[d : d + 6], x[d + 6 :]

    def join(self, q, U, qdot):
        """The flat part `x` of the integration state."""
        if self.free_shape:
            return jnp.concatenate([q, U, qdot])
        return U

    def _frame_shift(self, t, g):
        """$\\operatorname{Ad}_{g^{-1}}\\vartheta$, $\\operatorname{Ad}_{g^{-1}}\\dot\\vartheta$ and $M$: what the frame adds to the velocities."""
        M, theta, theta_dot = self.frame.motion_and_velocity(t)
        Ad_inv = lie.Ad(lie.se3_inv(g))
        return matmul(Ad_inv, theta), matmul(Ad_inv, theta_dot), M

    def forces(self, kin: Kinematics):
        """Total generalized force `(F_b, Q_H)` of the scene's effects at `kin`."""
        F = jnp.zeros(6, kin.q.dtype)
        Q = jnp.zeros_like(kin.q)
        for effect in self.effects:
            dF, dQ = effect.generalized_force(self.system, kin)
            F, Q = F + dF, Q + dQ
        return F, Q

    def vector_field(self, t, y, args=None):
        """The vector field of (2.6)–(2.7) on the integration state `y = (g, x)`.

        **Returns:**

        `(gdot, xdot)` with $\\dot g = g\\hat\\xi$ (the embedding's derivative) and $\\dot x$ =
        $(\\dot q, \\dot U, \\ddot q)$ or $\\dot U$; `body_field` gives $\\xi$ instead of $\\dot g$.
        """
        xi, xdot = self.body_field(t, y, args)
        return tangent_of_twist(y[0], xi), xdot

    def body_field(self, t, y, args=None):
        """The vector field of (2.6)–(2.7) left-trivialized: the pose's rate as its body twist.

        **Returns:**

        `(xi, xdot)`: the body twist $\\xi$ of the pose, $\\dot g = g\\hat\\xi$, shape `(6,)`, and
        $\\dot x$ as in `vector_field`. The Lie-group solvers step in $\\xi$ (see
        `AbstractBodyTerm`).
        """
        g, x = y
        q, U, qdot = self.split(t, x)
        if self.frame is not None:
            shift, shift_dot, M = self._frame_shift(t, g)
            U, g_true = U + shift, matmul(M, g)
        else:
            g_true = g
        geo = bundle_geometry(self.system, q, U, qdot)
        xi = U - matmul(geo.A, qdot)
        F, Q = self.forces(Kinematics(t, g_true, q, xi, qdot))
        Udot = locked_acceleration(geo, F)
        if self.frame is not None:
            xi = xi - shift
            Udot = Udot + lie.bracket(xi, shift) - shift_dot
        if self.free_shape:
            return xi, jnp.concatenate([qdot, Udot, shape_acceleration(geo, F, Q)])
        return xi, Udot

    def kinematics(self, t, y) -> Kinematics:
        """The state at `y` as `Kinematics` in the Galilean frame (true pose and velocities)."""
        g, x = y
        q, U, qdot = self.split(t, x)
        xi = U - connection(self.system, q) @ qdot if self.system.shape_dim else U
        if self.frame is not None:
            shift, _, M = self._frame_shift(t, g)
            return Kinematics(t, M @ g, q, xi + shift, qdot)
        return Kinematics(t, g, q, xi, qdot)


@eqx.filter_jit
def _body_field(scene, t, y, args):
    # A jitted call: diffrax traces a solver's step up to three times (shapes, loop body,
    # starting step), and JAX then reuses the field's jaxpr, and under `jax.grad` its
    # derivative, instead of tracing and differentiating the field each time.
    return scene.body_field(t, y, args)


class SceneTerm(AbstractBodyTerm):
    """The diffrax term of a scene: its vector field, with the scene itself at hand.

    Behaves as `diffrax.ODETerm(scene.vector_field)`, and gives the Lie-group solvers the
    field left-trivialized (`Scene.body_field`); solvers that need more than the vector
    field (the variational integrator needs the metric and the forces) read `scene`.

    **Arguments:**

    - `scene`: the `Scene`.
    """

    scene: Scene

    def body_vf(self, t, y, args):
        return _body_field(self.scene, t, y, args)

    def contr(self, t0, t1, **kwargs):
        return t1 - t0

    def prod(self, vf, control):
        return jtu.tree_map(lambda v: control * v, vf)
