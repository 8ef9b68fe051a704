r"""The reverse pass of the articulated-body field (`_recursive_dynamics`), by the implicit
function theorem: $O(n)$ work, as the field's.

The shape accelerations solve the bodies' Newton–Euler equations in the section frame
(`_recursive_dynamics`' docstring), $R(x, a) = 0$ with $a = [\mathcal A_0; \ddot q]$ and

$$R = \Big[\textstyle\sum_a f_a - F_b;\ \ Z_j\cdot\sum_{a\succeq j} f_a + a_j\ddot q_j - Q_{H,j}\Big],
\qquad f_a = \tilde M_a\mathcal A_a + \operatorname{ad}^*_{V_a}\tilde M_aV_a,$$

linear in $a$ with the metric $G$ as its matrix (the reference form, architecture §3). A
cotangent $[0; \bar{\ddot q}]$ on the solution becomes $\lambda = G^{-1}[0; \bar{\ddot q}]$
(`metric_solve`: the passes at rest) and $\bar x = -\nabla_x(\lambda\cdot R)$ at fixed $a$
on the inputs $x$. Every row of $R$ is a sum of body wrenches seen through joint columns,
so $\lambda\cdot R = \sum_a\Lambda_a\cdot f_a - \lambda_0\cdot F_b - \lambda_q\cdot Q_H$ up to
terms constant in $x$, with $\Lambda_a = \lambda_0 + \sum_{j\preceq a} Z_j\lambda_j$ the twist
that $\lambda$ gives body $a$: nothing of the pass from the leaves is differentiated, only
the bodies' kinematics and wrenches, whose transpose autodiff takes once, together with the
field's other outputs ($\xi$, $\dot U$, the forces). Autodiff's VJP of the field instead
transposes the $6\times6$ articulated inertias of the pass from the leaves, level by level.
"""

from collections.abc import Callable

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .. import lie
from .._linalg import einsum, spd_solve, take
from ._recursive_dynamics import (
    NodeMotion,
    at_bodies,
    body_twist,
    locked_rate,
    metric_solve,
    node_motion,
    node_path_sums,
    node_twists,
)

__all__ = ["driven_field_vjp", "floating_field_vjp"]


def _at_bodies(system, x):
    r"""Node path sums `x` `(m, 6)` read at each body's last node, `(n, 6)`."""
    return take(node_path_sums(system, x), system.tables.body_last)


def _wrenches(system, motion: NodeMotion, xi, base_acceleration, qddot):
    r"""$f_a = \tilde M_a\mathcal A_a + \operatorname{ad}^*_{V_a}\tilde M_aV_a$ of every body,
    `(n, 6)`, with $V_a = \xi + W_a$ and
    $\mathcal A_a = \mathcal A_0 + \sum_{k\preceq a}(Z_k\ddot q_k + c_k) + [\xi, W_a]$
    (`_recursive_dynamics._from_the_root`, its drifts $c$ summed along the path)."""
    W = take(motion.relative, system.tables.body_last)
    along = _at_bodies(system, node_twists(system, motion.columns, qddot) + motion.drift)
    A = base_acceleration[None] + along + lie.bracket(xi[None], W)
    V = xi[None] + W
    M = motion.inertias
    return einsum("aij,aj->ai", M, A) + lie.coad_action(V, einsum("aij,aj->ai", M, V))


def _implicit_cotangents(system, columns, wrenches, base, shape):
    r"""The cotangents of $-\lambda\cdot R$ on the wrenches $f$ and the joint columns $Z$:
    $-\Lambda$ and $-\partial_Z\sum_a\Lambda_a\cdot f_a$, for $\lambda = (\lambda_0, \lambda_q)$
    = `(base, shape)`."""

    def virtual_twists(Z):
        return base[None] + _at_bodies(system, node_twists(system, Z, shape))

    twists, pullback = jax.vjp(virtual_twists, columns)
    return -twists, -pullback(wrenches)[0]


def floating_field_vjp(
    system,
    pose: Float[Array, "4 4"],
    q: Float[Array, " d"],
    U: Float[Array, "6"],
    qdot: Float[Array, " d"],
    qddot: Float[Array, " d"],
    cotangents,
    forces: Callable,
):
    r"""The VJP of the articulated-body field $(g, q, U, \dot q)\mapsto(\xi, \dot U, \ddot q)$
    of a floating base (seed 004, (2.6)–(2.7)), given its $\ddot q$ (module docstring).

    **Arguments:**

    - `system`: a `Multibody` the recursions cover; `pose`: $g$; `q`, `U`, `qdot`: the state.
    - `qddot`: the field's $\ddot q$ there.
    - `cotangents`: $(\bar\xi, \bar{\dot U}, \bar{\ddot q})$.
    - `forces`: `(pose, q, xi, qdot) -> (F_b, Q_H, a)`, the other effects' wrench and shape
      forces and a uniform field's acceleration as a twist $a$, added to $\dot U$ (seed
      004, Theorem 3.4).

    **Returns:**

    $(\bar g, \bar q, \bar U, \bar{\dot q})$.
    """
    xi_bar, Udot_bar, qddot_bar = cotangents

    def parts(pose, q, U, qdot):
        nodes = node_motion(system, q, qdot)
        motion = at_bodies(system, nodes)
        xi = body_twist(motion, U)
        wrench, shape_force, frame_acceleration = forces(pose, q, xi, qdot)
        Udot = locked_rate(motion, U, xi, wrench) + frame_acceleration
        # The base's acceleration from the group rows, R_0 = 0, held fixed: ∇_x at fixed a.
        at_rest_base = _wrenches(system, nodes, xi, jnp.zeros_like(xi), qddot)
        I_r = jnp.sum(nodes.inertias, axis=0)
        A0 = jax.lax.stop_gradient(spd_solve(I_r, wrench - jnp.sum(at_rest_base, axis=0)))
        f = at_rest_base + einsum("aij,j->ai", nodes.inertias, A0)
        return (xi, Udot, f, nodes.columns, wrench, shape_force), nodes.inertias

    outputs, pullback, inertias = jax.vjp(parts, pose, q, U, qdot, has_aux=True)
    _, _, f, columns, _, _ = outputs
    base, shape = metric_solve(system, inertias, columns, qddot_bar, floating=True)
    f_bar, columns_bar = _implicit_cotangents(system, columns, f, base, shape)
    return pullback((xi_bar, Udot_bar, f_bar, columns_bar, base, shape))


def driven_field_vjp(
    system,
    q: Float[Array, " d"],
    qdot: Float[Array, " d"],
    xi: Float[Array, "6"],
    base_acceleration: Float[Array, "6"],
    qddot: Float[Array, " d"],
    qddot_bar: Float[Array, " d"],
    shape_force: Callable,
):
    r"""The VJP of the articulated-body shape equation $(q, \dot q)\mapsto\ddot q$ when the
    section frame's motion is given (a held or moving base; seed 004, (2.6)), given its
    $\ddot q$ (module docstring, with $\lambda_0 = 0$).

    **Arguments:**

    - `system`: a `Multibody` the recursions cover; `q`, `qdot`: the shape and its velocity.
    - `xi`: the frame's twist; `base_acceleration`: $\mathcal A_0 = \dot\xi - (0, \gamma_b)$,
      a uniform field's acceleration taken off (Theorem 3.4).
    - `qddot`: the equation's solution there; `qddot_bar`: its cotangent.
    - `shape_force`: `(q, qdot) -> Q_H`, the other effects' shape forces.

    **Returns:**

    $(\bar q, \bar{\dot q})$.
    """

    def parts(q, qdot):
        nodes = node_motion(system, q, qdot)
        f = _wrenches(system, nodes, xi, base_acceleration, qddot)
        return (f, nodes.columns, shape_force(q, qdot)), nodes.inertias

    (f, columns, _), pullback, inertias = jax.vjp(parts, q, qdot, has_aux=True)
    base, shape = metric_solve(system, inertias, columns, qddot_bar, floating=False)
    f_bar, columns_bar = _implicit_cotangents(system, columns, f, base, shape)
    return pullback((f_bar, columns_bar, shape))
