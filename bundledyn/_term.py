r"""The term layer: a scene's equations as a diffrax term, and the one codec of its state.

The user's state of a system is $(g, q, \xi, \dot q)$ (`State`). The integration variables
are $y = (g, x)$ with the locked velocity $U = \xi + A(q)\dot q$ in place of $\xi$
(seed 004, §2): $x = [q, U, \dot q]$ when the shape moves freely, $x = U$ for a rigid body
or a prescribed shape (whose $q(t), \dot q(t)$ are given), and $x = [q, \dot q]$ for a
prescribed base (whose $g(t), \xi(t)$ are given; $g$ is carried along). `SceneTerm` owns that layout:
`encode` and `decode` convert a `State` both ways, `unpack` and `pack` give and take the
parts, and every other module goes through them.

The pose is the first leaf of $y$ in `jax.tree_util` order; the Lie-group solvers rely on
that (`split`), and also step the augmented states of diffrax's adjoints, whose first leaf
is the pose too.
"""

import abc

import diffrax
import equinox as eqx
import jax.numpy as jnp
import jax.tree_util as jtu

from . import lie
from ._dynamics import (
    bundle_geometry,
    driven_shape_acceleration,
    locked_acceleration,
    shape_acceleration,
)
from ._effects import Kinematics
from ._frames import AbstractFrame
from ._geometry import connection, locked_velocity
from ._linalg import dot, matmul
from ._scene import Prescribed, PrescribedBase, Scene
from ._state import State
from ._systems._ball_chart import ball_columns, recharted_shape

__all__ = [
    "KEPT_FIELD_OUTPUTS",
    "AbstractBodyTerm",
    "AbstractSceneTerm",
    "SceneTerm",
    "scene_field",
    "split",
    "tangent_of_twist",
    "twist_of_tangent",
]


def split(y):
    """`(g, rest, treedef)`: the pose leaf of `y`, the list of its other leaves, its structure."""
    leaves, treedef = jtu.tree_flatten(y)
    if len(leaves) == 0 or jnp.shape(leaves[0]) != (4, 4):
        shape = None if len(leaves) == 0 else jnp.shape(leaves[0])
        raise ValueError(
            "The Lie-group solvers expect a state whose first leaf is a 4x4 SE(3) pose, "
            f"e.g. y = (g, x); got a first leaf of shape {shape}."
        )
    return leaves[0], leaves[1:], treedef


def twist_of_tangent(g, gdot):
    r"""Body twist $\xi = (g^{-1}\dot g)^\vee$ of a tangent vector given in $\mathbb R^{4\times4}$.

    Reads only the entries of $g^{-1}\dot g$ that `vee` reads (the skew part of the
    rotation block is not symmetrized: for $\dot g = g\hat\xi$ with $g$ on the group the
    result is exact to rounding).
    """
    return lie.vee(dot(lie.se3_inv(g), gdot))


def tangent_of_twist(g, xi):
    r"""$\dot g = g\hat\xi$: the tangent vector in $\mathbb R^{4\times4}$ of the body twist $\xi$ at $g$."""
    return dot(g, lie.hat(xi))


KEPT_FIELD_OUTPUTS = "bundledyn_kept_field_outputs"
"""The `jax.ad_checkpoint.checkpoint_name` under which a field's outputs are kept, not
recomputed, where the Lie-group solvers rematerialize a stage for reverse mode. A field
whose reverse pass needs only its inputs and outputs (a `jax.custom_vjp`, as
`ReverseModeSceneTerm`'s) names them so, and its stage is then evaluated once, not twice."""


class AbstractBodyTerm(diffrax.AbstractTerm):
    r"""A diffrax term whose vector field is also given left-trivialized: the pose's rate
    as its body twist $\xi$, $\dot g = g\hat\xi$.

    The Lie-group solvers step in the twist. Read off $\dot g$ as $(g^{-1}\dot g)^\vee$, it
    would make every stage form $g\hat\xi$ and $g^{-1}$ even for a field that never reads
    $g$, and reverse mode would send cotangents through both that cancel in the end.

    Subclass it to give a Lie-group solver your own equations: implement `body_vf`, `contr`
    and `prod`. `vf`, the field on the $4\times4$ embedding, follows from `body_vf`, so
    stock diffrax solvers integrate the same term.
    """

    @abc.abstractmethod
    def body_vf(self, t, y, args):
        r"""The vector field at `y`, shaped as `y` but with the body twist $\xi$, `(6,)`, as
        its first leaf in place of $\dot g$."""

    def vf(self, t, y, args):
        g, _, treedef = split(y)
        xi, *rest = jtu.tree_leaves(self.body_vf(t, y, args))
        return jtu.tree_unflatten(treedef, [tangent_of_twist(g, xi), *rest])


def _frame_shift(frame: AbstractFrame, t, g):
    r"""$\operatorname{Ad}_{g^{-1}}\vartheta$, $\operatorname{Ad}_{g^{-1}}\dot\vartheta$ and $M$:
    what the scene's frame (moving by $M(t)$ with body velocity $\vartheta$) adds to the
    velocities of (2.9)–(2.10)."""
    M, theta, theta_dot = frame.motion_and_velocity(t)
    Ad_inv = lie.Ad(lie.se3_inv(g))
    return matmul(Ad_inv, theta), matmul(Ad_inv, theta_dot), M


def scene_field(scene: Scene, t, g, q, U, qdot):
    r"""The body twist $\xi$ of the pose and the rates $\dot U$, $\ddot q$ of (2.6)–(2.7).

    In a moving frame the locked velocity is relative to it: the true one is $U +
    \operatorname{Ad}_{g^{-1}}\vartheta$, and $\dot U$ gains $[\xi, \operatorname{Ad}_{g^{-1}}\vartheta]
    - \operatorname{Ad}_{g^{-1}}\dot\vartheta$ (seed 004, (2.9)–(2.10)).
    """
    if scene.frame is not None:
        shift, shift_dot, M = _frame_shift(scene.frame, t, g)
        U, g = U + shift, matmul(M, g)
    geo = bundle_geometry(scene.system, q, U, qdot)
    xi = U - matmul(geo.A, qdot)
    F, Q = scene.forces(Kinematics(t, g, q, xi, qdot))
    Udot = locked_acceleration(geo, F)
    if scene.frame is not None:
        xi = xi - shift
        Udot = Udot + lie.bracket(xi, shift) - shift_dot
    qddot = shape_acceleration(geo, F, Q) if scene.free_shape else None
    return xi, Udot, qddot


def _driven_field(scene: Scene, base: PrescribedBase, t, x):
    r"""The body twist $\xi(t)$ of the given base and $(\dot q, \ddot q)$ of the shape
    equation it drives (`driven_shape_acceleration`)."""
    d = scene.system.shape_dim
    q, qdot = x[:d], x[d:]
    g, xi, xi_dot = base.at(t)
    _, Q = scene.forces(Kinematics(t, g, q, xi, qdot))
    qddot = driven_shape_acceleration(scene.system, q, xi, xi_dot, qdot, Q)
    return xi, jnp.concatenate([qdot, qddot])


@eqx.filter_jit
def _scene_body_vf(term, t, y, args):
    # A jitted call: diffrax traces a solver's step up to three times (shapes, loop body,
    # starting step), and JAX then reuses the field's jaxpr, and under `jax.grad` its
    # derivative, instead of tracing and differentiating the field each time.
    base = term.scene.base
    if isinstance(base, PrescribedBase):
        return _driven_field(term.scene, base, t, y[1])
    g, q, U, qdot = term.unpack(t, y)
    xi, Udot, qddot = scene_field(term.scene, t, g, q, U, qdot)
    if qddot is None:
        return xi, Udot
    return xi, jnp.concatenate([qdot, Udot, qddot])


class AbstractSceneTerm(AbstractBodyTerm):
    r"""A scene's term: the state codec and everything but the field, shared by `SceneTerm`
    and the variant whose field has a hand-derived reverse pass (`ReverseModeSceneTerm`)."""

    scene: eqx.AbstractVar[Scene]

    def contr(self, t0, t1, **kwargs):
        return t1 - t0

    def recharted(self, t, y):
        r"""`y` with every ball joint's rotation vector in $|\varphi| \le \pi$: the same state
        in the coordinates where the Lie-group solvers step best (`recharted_shape`; the
        chart degenerates at $|\varphi| = 2\pi$). `y` itself when nothing is recharted.

        **Arguments:**

        - `t`: the time of `y`.
        - `y`: the integration state $(g, x)$.

        **Returns:**

        The integration state in the recharted coordinates.
        """
        scene = self.scene
        if ball_columns(scene.system).size == 0 or isinstance(scene.shape, Prescribed):
            return y
        _, q, U, qdot = self.unpack(t, y)
        q, qdot = recharted_shape(scene.system, q, qdot)
        return self.pack(y[0], q, U, qdot)

    def prod(self, vf, control):
        return jtu.tree_map(lambda v: control * v, vf)

    # The codec.
    def unpack(self, t, y):
        r"""$(g, q, U, \dot q)$ from the integration state `y` at time `t`.

        **Arguments:**

        - `t`: the time (a prescribed shape is read off its motion at `t`).
        - `y`: `(g, x)`.

        **Returns:**

        The pose `(4, 4)`, the shape `(d,)`, the locked velocity $U$ `(6,)` and the shape
        velocity `(d,)`.
        """
        g, x = y
        scene = self.scene
        if isinstance(scene.shape, Prescribed):
            q, qdot = scene.shape.at(t)
            return g, q, x, qdot
        d = scene.system.shape_dim
        if isinstance(scene.base, PrescribedBase):
            g, xi, _ = scene.base.at(t)
            q, qdot = x[:d], x[d:]
            return g, q, locked_velocity(scene.system, q, xi, qdot), qdot
        return g, x[:d], x[d : d + 6], x[d + 6 :]

    def pack(self, g, q, U, qdot):
        r"""The integration state $y = (g, x)$ of the pose, shape, locked velocity and shape
        velocity: $x = [q, U, \dot q]$, $x = U$ for a rigid body or a prescribed shape, and
        $x = [q, \dot q]$ for a prescribed base."""
        if isinstance(self.scene.base, PrescribedBase):
            return g, jnp.concatenate([q, qdot])
        if self.scene.free_shape:
            return g, jnp.concatenate([q, U, qdot])
        return g, U

    def encode(self, t, state: State):
        r"""The integration state $y$ of `state` at time `t`, with $U = \xi + A(q)\dot q$.

        For a prescribed shape, $q$ and $\dot q$ come from its motion at `t`, not from `state`;
        for a prescribed base, $g$ and $\xi$ come from the base's motion.

        **Arguments:**

        - `t`: the time of the state.
        - `state`: a `State` in the scene's frame.

        **Returns:**

        `y = (g, x)`.
        """
        system = self.scene.system
        if isinstance(self.scene.shape, Prescribed):
            q, qdot = self.scene.shape.at(jnp.asarray(t, dtype=state.g.dtype))
        elif state.q.shape != (system.shape_dim,):
            raise ValueError(
                f"`state.q` and `state.qdot` must have shape ({system.shape_dim},) for this "
                f"system, got {state.q.shape}."
            )
        else:
            q, qdot = state.q, state.qdot
        if isinstance(self.scene.base, PrescribedBase):
            g = self.scene.base.at(jnp.asarray(t, dtype=state.g.dtype))[0]
            return self.pack(g, q, None, qdot)
        U = locked_velocity(system, q, state.xi, qdot) if system.shape_dim else state.xi
        return self.pack(state.g, q, U, qdot)

    def decode(self, t, y) -> State:
        r"""The `State` $(g, q, \xi, \dot q)$ of the integration state `y` at time `t`, $\xi = U - A(q)\dot q$."""
        g, q, U, qdot = self.unpack(t, y)
        return State(g, q, self._xi(q, U, qdot), qdot)

    def _xi(self, q, U, qdot):
        system = self.scene.system
        return U - connection(system, q) @ qdot if system.shape_dim else U

    def kinematics(self, t, y) -> Kinematics:
        """The state at `y` as `Kinematics` in the Galilean frame (the true pose and velocities).

        **Arguments:**

        - `t`: the time; `y`: the integration state.
        """
        g, q, U, qdot = self.unpack(t, y)
        xi = self._xi(q, U, qdot)
        if self.scene.frame is None:
            return Kinematics(t, g, q, xi, qdot)
        shift, _, M = _frame_shift(self.scene.frame, t, g)
        return Kinematics(t, M @ g, q, xi + shift, qdot)


class SceneTerm(AbstractSceneTerm):
    r"""The diffrax term of a scene: Chevallier's equations (2.6)–(2.7), and the state codec.

    As a term it behaves as `diffrax.ODETerm` of the field on $y = (g, x)$ (`vf` gives
    $(\dot g, \dot x)$ with $\dot g = g\hat\xi$), and gives the Lie-group solvers the field
    left-trivialized (`body_vf`). Any diffrax solver integrates it:

    ```python
    term = bd.SceneTerm(scene)
    sol = diffrax.diffeqsolve(term, bd.RKMK87(), 0.0, 1.0, None, term.encode(0.0, state),
                              stepsize_controller=diffrax.PIDController(rtol=1e-8, atol=1e-8))
    ```

    **Arguments:**

    - `scene`: the `Scene`.
    """

    scene: Scene

    def body_vf(self, t, y, args):
        r"""$(\xi, \dot x)$: the body twist of the pose and $\dot x = (\dot q, \dot U, \ddot q)$,
        or $\dot U$ when $x = U$."""
        return _scene_body_vf(self, t, y, args)
