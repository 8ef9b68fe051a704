r"""The scene's field as a `jax.custom_vjp` for reverse mode (`ReverseModeSceneTerm`,
`ReplayedSceneTerm`): its VJP needs only the field's inputs and outputs, so the adjoint's
reverse sweep can replay the field's values instead of evaluating the field again.

A `jax.custom_vjp` cannot be differentiated in forward mode, which the library needs
(identification pushes directions through rollouts; the geometry uses `jacfwd`), and one
nested in a `custom_jvp` rule cannot be transposed. So the custom reverse pass is not put on
`SceneTerm`'s field: `StoredStepsAdjoint`, which differentiates each step itself in its
reverse sweep, steps the terms' reverse-mode variants there (`for_reverse_mode`), and the
forward solve, forward mode and every other adjoint keep the plain field.

The VJP is written out on `FreeShapeMode`'s layout $x = [q, U, \dot q]$ in the Galilean
frame and on `PrescribedBaseMode`'s $x = [q, \dot q]$ (`_state_pass`): through the dense
metric (`_dynamics_vjp`) for a dense field or a small tree, where its few large kernels
cost least; by the articulated-body recursions (`_recursive_dynamics_vjp`) on a large tree
whose field is theirs, where the dense metric's work grows with the square of the bodies.
Elsewhere (a rigid body, a moving frame) it is autodiff's VJP of the field, evaluated again
at the state.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.tree_util as jtu
from jax.ad_checkpoint import checkpoint_name

from ._dynamics_vjp import body_field_vjp, driven_field_vjp
from ._effects import Kinematics, total_force, uniform_fields
from ._linalg import matmul
from ._modes import ArticulatedBodyField, FreeShapeMode, PrescribedBaseMode
from ._scene import Scene

__all__ = ["KEPT_FIELD_OUTPUTS", "replayed_field", "reverse_mode_field", "written_out"]

KEPT_FIELD_OUTPUTS = "bundledyn_kept_field_outputs"
"""The `jax.ad_checkpoint.checkpoint_name` under which a field's outputs are kept, not
recomputed, where the Lie-group solvers rematerialize a stage for reverse mode. A field
whose reverse pass needs only its inputs and outputs (a `jax.custom_vjp`, as
`ReverseModeSceneTerm`'s) names them so, and its stage is then evaluated once, not twice."""


# Where the pass through the dense metric stops costing less than the recursions': measured
# on dm_control's models and on chains, the recursions' worst case (benchmarks/README.md). A
# floating base's VJPs cost about the same on the 56-coordinate CMU humanoid, and the
# recursions' less on the 73-coordinate dog_v2; a held base's cost less through the metric
# on the 85-coordinate dog and on chains up to 127 coordinates.
_DENSE_MOST_COORDINATES = 56
_DENSE_MOST_DRIVEN_COORDINATES = 127


def _state_pass(scene: Scene):
    """The written-out VJP on the state of `scene`'s field, or None where autodiff's VJP
    of the field is taken: through the dense metric (`body_field_vjp`, `driven_field_vjp`)
    for a floating base and a free shape (`FreeShapeMode`) in the Galilean frame or a
    prescribed base (`PrescribedBaseMode`), by the articulated-body recursions where the
    scene's field is theirs and the shape has more than `_DENSE_MOST_COORDINATES`
    (`_DENSE_MOST_DRIVEN_COORDINATES`) coordinates."""
    if isinstance(scene.mode, PrescribedBaseMode):
        dense, articulated = _driven_state_vjp, _articulated_driven_state_vjp
        most = _DENSE_MOST_DRIVEN_COORDINATES
    elif isinstance(scene.mode, FreeShapeMode) and scene.frame is None:
        dense, articulated, most = _state_vjp, _articulated_state_vjp, _DENSE_MOST_COORDINATES
    else:
        return None
    if isinstance(scene.algorithm, ArticulatedBodyField) and scene.system.shape_dim > most:
        return articulated
    return dense


def written_out(scene: Scene) -> bool:
    """Whether the field's VJP on the state is written out (`_state_pass`)."""
    return _state_pass(scene) is not None


def _field(scene: Scene, t, y):
    return scene.mode.body_field(scene, t, y)


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


def _field_twist(gamma, pose, dtype):
    r"""$(0, R^T\gamma)$: a uniform field's acceleration as a twist in the section's axes."""
    gamma_b = matmul(pose[:3, :3].T, gamma.astype(dtype))
    return jnp.concatenate([jnp.zeros(3, dtype), gamma_b])


def _state_vjp(scene, y, t, out, cotangents):
    r"""The cotangent on the state `y = (g, x)` of the field's outputs `out`, by
    `body_field_vjp`.

    A uniform field adds $(0, R^T\gamma)$ to $\dot U$ and nothing else (seed 004, Theorem
    3.4), so the pass takes the field without it and adds its cotangent on $R$: through
    the forces it would differentiate the metric's rows along $q$ (`Gravity`'s).
    """
    g, x = y
    d = scene.system.shape_dim
    q, U, qdot = x[:d], x[d : d + 6], x[d + 6 :]
    xi_bar, xdot_bar = cotangents
    Udot, qddot = out[1][d : d + 6], out[1][d + 6 :]
    gamma, others = uniform_fields(scene.effects)
    if gamma is not None:
        Udot = Udot - _field_twist(gamma, g, q.dtype)

    def forces_vjp(mu_xi, mu_q):
        def forces(g, q, xi, qdot):
            return total_force(others, scene.system, Kinematics(t, g, q, xi, qdot))

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
    if gamma is not None:  # ∂/∂R of Ū̇_v·Rᵀγ = γ Ū̇_vᵀ
        g_bar = g_bar.at[:3, :3].add(jnp.outer(gamma.astype(q.dtype), xdot_bar[d + 3 : d + 6]))
    return g_bar, jnp.concatenate([q_bar, U_bar, qdot_bar + xdot_bar[:d]])


def _driven_state_vjp(scene, y, t, out, cotangents):
    r"""The cotangent on the state `y = (g, [q, \dot q])` of a prescribed base's field
    outputs `out`, by `driven_field_vjp`. The base's motion depends on $t$ alone, so the
    carried pose and the output twist pass nothing back; a uniform field is taken off the
    base's acceleration (Theorem 3.4) instead of entering as forces, as in `_state_vjp`."""
    g, x = y
    d = scene.system.shape_dim
    q, qdot = x[:d], x[d:]
    xdot_bar = cotangents[1]
    pose, xi, xi_dot = scene.mode.motion.at(t)
    gamma, others = uniform_fields(scene.effects)
    if gamma is not None:
        xi_dot = xi_dot - _field_twist(gamma, pose, q.dtype)

    def forces_vjp(mu):
        def shape_force(q, qdot):
            return total_force(others, scene.system, Kinematics(t, pose, q, xi, qdot))[1]

        return jax.vjp(shape_force, q, qdot)[1](mu)

    q_bar, qdot_bar = driven_field_vjp(
        scene.system, q, xi, xi_dot, qdot, out[1][d:], xdot_bar[d:], forces_vjp
    )
    return jnp.zeros_like(g), jnp.concatenate([q_bar, qdot_bar + xdot_bar[:d]])


def _articulated_state_vjp(scene, y, t, out, cotangents):
    r"""The cotangent on the state `y = (g, [q, U, \dot q])` of a floating base's
    articulated-body field outputs `out` (`ArticulatedBodyField.floating_vjp`)."""
    g, x = y
    d = scene.system.shape_dim
    xi_bar, xdot_bar = cotangents
    g_bar, q_bar, U_bar, qdot_bar = scene.algorithm.floating_vjp(
        scene, t, g, x[:d], x[d : d + 6], x[d + 6 :], out[1][d + 6 :],
        (xi_bar, xdot_bar[d : d + 6], xdot_bar[d + 6 :]),
    )  # fmt: skip
    return g_bar, jnp.concatenate([q_bar, U_bar, qdot_bar + xdot_bar[:d]])


def _articulated_driven_state_vjp(scene, y, t, out, cotangents):
    r"""The cotangent on the state `y = (g, [q, \dot q])` of a prescribed base's
    articulated-body field outputs `out` (`ArticulatedBodyField.driven_vjp`); the carried
    pose and the output twist pass nothing back, as in `_driven_state_vjp`."""
    g, x = y
    d = scene.system.shape_dim
    xdot_bar = cotangents[1]
    pose, xi, xi_dot = scene.mode.motion.at(t)
    q_bar, qdot_bar = scene.algorithm.driven_vjp(
        scene, t, pose, x[:d], xi, xi_dot, x[d:], out[1][d:], xdot_bar[d:]
    )
    return jnp.zeros_like(g), jnp.concatenate([q_bar, qdot_bar + xdot_bar[:d]])


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
    unperturbed = eqx.filter(scene, lambda _: False)
    state_pass = _state_pass(scene)
    if state_pass is not None:
        return unperturbed, state_pass(scene, y, t, out, cotangents)
    _, vjp = jax.vjp(lambda y: _field(scene, t, y), y)
    return unperturbed, vjp(cotangents)[0]


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
def reverse_mode_field(scene: Scene, t, y):
    r"""The field $(\xi, \dot x)$ of `scene` at `y`, with the reverse pass of the module
    docstring."""
    return _reverse_mode_field((scene, y), t)


def replayed_field(scene: Scene, t, y, values):
    """The field's known `values` at `y`, with the reverse pass at `(scene, y)` of the module
    docstring."""
    return _replayed_field((scene, y), t, jax.lax.stop_gradient(values))
