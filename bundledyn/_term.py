r"""The term layer: a scene's equations as a diffrax term, the interface solvers and
adjoints use.

The user's state of a system is $(g, q, \xi, \dot q)$ (`State`). The integration variables
are $y = (g, x)$, with the locked velocity $U = \xi + A(q)\dot q$ in place of $\xi$
(seed 004, §2), laid out by the scene's mode (`AbstractMode`: which parts are integrated
and how they are packed). `AbstractSceneTerm` is what solvers and adjoints may use of a
scene: the codec (`encode`, `decode`, `pack`, `unpack`), the metric and the forces, the
recharting of ball joints, and the variants whose field has its own reverse pass
(`reverse_mode`, `replayed`); they reach nothing else of it.

The pose is the first leaf of $y$ in `jax.tree_util` order; the Lie-group solvers rely on
that (`split`), and also step the augmented states of diffrax's adjoints, whose first leaf
is the pose too.
"""

import abc

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.tree_util as jtu

from . import lie
from ._effects import Kinematics
from ._linalg import dot
from ._reverse_term import (
    KEPT_FIELD_OUTPUTS,
    replayed_field,
    reverse_mode_field,
)
from ._scene import Scene
from ._state import State

__all__ = [
    "KEPT_FIELD_OUTPUTS",
    "AbstractBodyTerm",
    "AbstractSceneTerm",
    "ReplayedSceneTerm",
    "ReverseModeSceneTerm",
    "SceneTerm",
    "for_replay",
    "for_reverse_mode",
    "has_reverse_mode",
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


@eqx.filter_jit
def _scene_body_vf(scene: Scene, t, y):
    # A jitted call: diffrax traces a solver's step up to three times (shapes, loop body,
    # starting step), and JAX then reuses the field's jaxpr, and under `jax.grad` its
    # derivative, instead of tracing and differentiating the field each time.
    return scene.mode.body_field(scene, t, y)


class AbstractSceneTerm(AbstractBodyTerm):
    r"""A scene's term: what solvers and adjoints use of a scene.

    The codec and the scene's quantities are delegated to the scene's mode; the field
    (`body_vf`) and the variants whose field has its own reverse pass (`reverse_mode`,
    `replayed`) are each final term's own.
    """

    scene: eqx.AbstractVar[Scene]

    def contr(self, t0, t1, **kwargs):
        return t1 - t0

    def prod(self, vf, control):
        return jtu.tree_map(lambda v: control * v, vf)

    @abc.abstractmethod
    def reverse_mode(self) -> "AbstractSceneTerm | None":
        """This term with the field's own reverse pass, a VJP that needs only the field's
        inputs and outputs (for reverse mode only), or None where the term has none."""

    @abc.abstractmethod
    def replayed(self, values) -> "AbstractSceneTerm | None":
        r"""A term that gives back the field's known `values` $(\xi, \dot x)$ at the state
        it will be evaluated at, with the field's own reverse pass there; None where the
        term has none."""

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
        return self.scene.mode.recharted(self.scene, t, y)

    def unpack(self, t, y):
        r"""$(g, q, U, \dot q)$ from the integration state `y` at time `t`.

        **Arguments:**

        - `t`: the time (a prescribed shape or base is read off its motion at `t`).
        - `y`: `(g, x)`.

        **Returns:**

        The pose `(4, 4)`, the shape `(d,)`, the locked velocity $U$ `(6,)` and the shape
        velocity `(d,)`.
        """
        return self.scene.mode.unpack(self.scene, t, y)

    def pack(self, t, g, q, U, qdot):
        r"""The integration state $y = (g, x)$ at time `t` of the pose, shape, locked velocity
        and shape velocity, in the scene mode's layout."""
        return self.scene.mode.pack(self.scene, t, g, q, U, qdot)

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
        return self.scene.mode.encode(self.scene, t, state)

    def decode(self, t, y) -> State:
        r"""The `State` $(g, q, \xi, \dot q)$ of the integration state `y` at time `t`, $\xi = U - A(q)\dot q$."""
        return self.scene.mode.decode(self.scene, t, y)[0]

    def decode_with_locked_velocity(self, t, y) -> tuple[State, jax.Array]:
        """The `State` at `y` and the locked velocity $U$ there, decoded once."""
        return self.scene.mode.decode(self.scene, t, y)

    def kinematics(self, t, y) -> Kinematics:
        """The state at `y` as `Kinematics` in the Galilean frame (the true pose and velocities).

        **Arguments:**

        - `t`: the time; `y`: the integration state.
        """
        return self.scene.mode.kinematics(self.scene, t, y)

    def metric(self, q):
        """The system's metric $G(q)$ (`AbstractSystem.metric`)."""
        return self.scene.system.metric(q)

    def metric_and_derivative(self, q):
        r"""$G(q)$ and $\partial G/\partial q$ (`AbstractSystem.metric_and_derivative`)."""
        return self.scene.system.metric_and_derivative(q)

    def forces(self, t, g, q, xi, qdot):
        """The scene's generalized force `(F_b, Q_H)` at that state (`Scene.forces`)."""
        return self.scene.forces(Kinematics(t, g, q, xi, qdot))


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
        r"""$(\xi, \dot x)$: the body twist of the pose and the rate of $x$ in the mode's
        layout ($\dot x = (\dot q, \dot U, \ddot q)$ for a free shape)."""
        return _scene_body_vf(self.scene, t, y)

    def reverse_mode(self):
        return ReverseModeSceneTerm(self.scene)

    def replayed(self, values):
        return ReplayedSceneTerm(self.scene, values)


class ReverseModeSceneTerm(AbstractSceneTerm):
    r"""`SceneTerm` with the field's reverse pass as a custom VJP (`_reverse_term.py`): the
    same field and codec, for reverse mode only (it has no forward-mode derivative).

    The VJP is written out for a floating base and a free shape in the Galilean frame and
    for a prescribed base: through the dense metric (`body_field_vjp`, `driven_field_vjp`)
    with the dense field or on a small tree, by the articulated-body recursions
    (`_recursive_dynamics_vjp`) on a large one; elsewhere it is autodiff's VJP of the field
    evaluated again. Either way it needs only
    the field's inputs and outputs, so the adjoint can replay the values
    (`ReplayedSceneTerm`).

    **Arguments:**

    - `scene`: the `Scene`.
    """

    scene: Scene

    def body_vf(self, t, y, args):
        r"""$(\xi, \dot x)$ in the mode's layout, as `SceneTerm.body_vf`."""
        return reverse_mode_field(self.scene, t, y)

    def reverse_mode(self):
        return self

    def replayed(self, values):
        return ReplayedSceneTerm(self.scene, values)


class ReplayedSceneTerm(AbstractSceneTerm):
    r"""`ReverseModeSceneTerm` whose field's values at the state it will be evaluated at
    are known: it gives them back (`values`), with `ReverseModeSceneTerm`'s reverse pass.

    `StoredStepsAdjoint` keeps the field's values at a step's stages in its forward solve
    and steps again with these terms in its reverse sweep (`AbstractRKMK.stage_step`), so
    the field is not evaluated there. Only correct at that state: the values do not depend
    on the state the term is given.

    **Arguments:**

    - `scene`: the `Scene`.
    - `values`: the field's values $(\xi, \dot x)$ there, as `SceneTerm.body_vf` gives them.
    """

    scene: Scene
    values: tuple

    def body_vf(self, t, y, args):
        """The stored `values`, with `ReverseModeSceneTerm`'s reverse pass at `(scene, y)`."""
        return replayed_field(self.scene, t, y, self.values)

    def reverse_mode(self):
        return ReverseModeSceneTerm(self.scene)

    def replayed(self, values):
        return ReplayedSceneTerm(self.scene, values)


def _swapped(terms, swap):
    def maybe(x):
        if not isinstance(x, AbstractSceneTerm):
            return x
        swapped = swap(x)
        return x if swapped is None else swapped

    return jtu.tree_map(maybe, terms, is_leaf=lambda x: isinstance(x, AbstractSceneTerm))


def for_reverse_mode(terms):
    """`terms` with every scene term replaced by its `reverse_mode()` variant, where it has one."""
    return _swapped(terms, lambda term: term.reverse_mode())


def for_replay(terms, values):
    """`terms` with its one scene term replaced by its `replayed(values)` variant, where it
    has one."""
    return _swapped(terms, lambda term: term.replayed(values))


def has_reverse_mode(terms) -> bool:
    """Whether a scene term in `terms` has a variant whose field has its own reverse pass."""
    leaves = jtu.tree_leaves(terms, is_leaf=lambda x: isinstance(x, AbstractSceneTerm))
    return any(isinstance(x, AbstractSceneTerm) and x.reverse_mode() is not None for x in leaves)
