r"""A scene's term whose field has the hand-derived reverse pass (`body_field_vjp`).

A `jax.custom_vjp` cannot be differentiated in forward mode, which the library needs
(identification pushes directions through rollouts; the geometry uses `jacfwd`), and one
nested in a `custom_jvp` rule cannot be transposed. So the custom reverse pass is not put on
`SceneTerm`'s field: `StoredStepsAdjoint`, which differentiates each step itself in its
reverse sweep, steps `for_reverse_mode(terms)` there, and the forward solve, forward mode and
every other adjoint keep the plain field.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.tree_util as jtu
from jax.ad_checkpoint import checkpoint_name

from ._dynamics_vjp import body_field_vjp
from ._effects import Kinematics
from ._scene import FloatingBase, Scene
from ._term import KEPT_FIELD_OUTPUTS, AbstractSceneTerm, SceneTerm, scene_field

__all__ = [
    "ReplayedSceneTerm",
    "ReverseModeSceneTerm",
    "for_replay",
    "for_reverse_mode",
]


def _covered(scene: Scene) -> bool:
    """Whether the hand-derived reverse pass covers `scene`: a floating base and a free
    shape in the Galilean frame (any system with $d > 0$, any effects)."""
    return scene.free_shape and scene.frame is None and isinstance(scene.base, FloatingBase)


def _check_covered(scene, name):
    if not _covered(scene):
        raise ValueError(
            f"`{name}` needs a scene with a floating base and a free shape (d > 0) in the "
            "Galilean frame; use `SceneTerm` for any other scene."
        )


def _field(scene, t, y):
    g, x = y
    d = scene.system.shape_dim
    q, U, qdot = x[:d], x[d : d + 6], x[d + 6 :]
    xi, Udot, qddot = scene_field(scene, t, g, q, U, qdot)
    assert qddot is not None  # a free shape (`_covered`)
    return xi, jnp.concatenate([qdot, Udot, qddot])


@eqx.filter_custom_vjp
def _reverse_mode_field(scene__y, t):
    return _field(scene__y[0], t, scene__y[1])


@_reverse_mode_field.def_fwd
def _reverse_mode_field_fwd(perturbed, scene__y, t):
    out = _field(scene__y[0], t, scene__y[1])
    out = checkpoint_name(out, KEPT_FIELD_OUTPUTS)  # the residuals: no stage rematerialized
    return out, out


def _materialized(ct, like):
    return jnp.zeros_like(like) if ct is None else ct


def _state_vjp(scene, y, t, out, cotangents):
    """The cotangent on the state `y = (g, x)` of the field's outputs `out`, by
    `body_field_vjp`."""
    g, x = y
    d = scene.system.shape_dim
    q, U, qdot = x[:d], x[d : d + 6], x[d + 6 :]
    xi_bar, xdot_bar = cotangents
    Udot, qddot = out[1][d : d + 6], out[1][d + 6 :]

    def forces_vjp(mu_xi, mu_q):
        def forces(g, q, xi, qdot):
            return scene.forces(Kinematics(t, g, q, xi, qdot))

        _, vjp = jax.vjp(forces, g, q, out[0], qdot)  # the field's first output is ξ
        g_bar, q_bar, xi_bar_f, qdot_bar = vjp((mu_xi, mu_q))
        return q_bar, xi_bar_f, qdot_bar, g_bar

    q_bar, U_bar, qdot_bar, g_bar = body_field_vjp(
        scene.system,
        q,
        U,
        qdot,
        Udot,
        qddot,
        (xi_bar, xdot_bar[d : d + 6], xdot_bar[d + 6 :]),
        forces_vjp,
    )
    return g_bar, jnp.concatenate([q_bar, U_bar, qdot_bar + xdot_bar[:d]])


def _field_vjp(out, grad_out, perturbed, scene__y, t):
    """The cotangents on `(scene, y)` of the field's outputs `out` at `(scene, y)`."""
    scene, y = scene__y
    cotangents = tuple(_materialized(c, o) for c, o in zip(grad_out, out, strict=True))
    if any(jtu.tree_leaves(perturbed[0])):
        # The scene's numbers too (inertias, effect constants): they reach every kernel of
        # the field, so one transpose of it by autodiff for the scene and the state
        # together costs less than the written-out pass plus a transpose for the scene.
        _, vjp = jax.vjp(lambda scene, y: _field(scene, t, y), scene, y)
        return vjp(cotangents)
    return eqx.filter(scene, lambda _: False), _state_vjp(scene, y, t, out, cotangents)


_reverse_mode_field.def_bwd(_field_vjp)


@eqx.filter_custom_vjp
def _replayed_field(scene__y, t, out):
    del scene__y, t
    return out


@_replayed_field.def_fwd
def _replayed_field_fwd(perturbed, scene__y, t, out):
    del perturbed, scene__y, t
    return out, out


@_replayed_field.def_bwd
def _replayed_field_bwd(out, grad_out, perturbed, scene__y, t, _):
    return _field_vjp(out, grad_out, perturbed, scene__y, t)


@eqx.filter_jit
def _reverse_mode_body_vf(term, t, y, args):
    return _reverse_mode_field((term.scene, y), t)


class ReverseModeSceneTerm(AbstractSceneTerm):
    r"""`SceneTerm` with the field's hand-derived reverse pass (`body_field_vjp`): the same
    field and codec, for reverse mode only (it has no forward-mode derivative).

    **Arguments:**

    - `scene`: a `Scene` with a floating base and a free shape in the Galilean frame.
    """

    scene: Scene

    def __check_init__(self):
        _check_covered(self.scene, type(self).__name__)

    def body_vf(self, t, y, args):
        r"""$(\xi, \dot x)$, $\dot x = (\dot q, \dot U, \ddot q)$, as `SceneTerm.body_vf`."""
        return _reverse_mode_body_vf(self, t, y, args)


class ReplayedSceneTerm(AbstractSceneTerm):
    r"""`ReverseModeSceneTerm` whose field's values at the state it will be evaluated at
    are known: it gives them back (`values`), and its reverse pass is the written-out one.

    `StoredStepsAdjoint` keeps the field's values at a step's stages in its forward solve
    and steps again with these terms in its reverse sweep (`AbstractRKMK.stage_step`), so
    the field is not evaluated there. Only correct at that state: the values do not depend
    on the state the term is given.

    **Arguments:**

    - `scene`: a `Scene` that `ReverseModeSceneTerm` takes.
    - `values`: the field's values $(\xi, \dot x)$ there, as `SceneTerm.body_vf` gives them.
    """

    scene: Scene
    values: tuple

    def __check_init__(self):
        _check_covered(self.scene, type(self).__name__)

    def body_vf(self, t, y, args):
        """The stored `values`, with the written-out reverse pass at `(scene, y)`."""
        return _replayed_field((self.scene, y), t, jax.lax.stop_gradient(self.values))


def _swapped(terms, swap):
    def maybe(x):
        return swap(x.scene) if isinstance(x, SceneTerm) and _covered(x.scene) else x

    return jtu.tree_map(maybe, terms, is_leaf=lambda x: isinstance(x, SceneTerm))


def for_reverse_mode(terms):
    """`terms` with every `SceneTerm` that `ReverseModeSceneTerm` covers replaced by it."""
    return _swapped(terms, ReverseModeSceneTerm)


def for_replay(terms, values):
    """`terms` with its one covered `SceneTerm` replaced by a `ReplayedSceneTerm` giving
    `values`."""
    return _swapped(terms, lambda scene: ReplayedSceneTerm(scene, values))
