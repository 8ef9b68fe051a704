r"""The chart of a ball joint's rotation vector, kept where it is regular.

A `Spherical` joint's coordinates are the rotation vector $\varphi$ of the child relative to
the parent, and its angular velocity is $\omega = \operatorname{dexp}(\varphi)\dot\varphi$
(seed 000, the vector parameterization; `lie.so3_dexp`). The chart covers every rotation
for $|\varphi| < 2\pi$ but degenerates as $|\varphi| \to 2\pi$, where $\operatorname{dexp}$
is singular: a joint that keeps turning about one axis drives $|\varphi|$ there and the
metric, hence the step size, with it. Past $|\varphi| = \pi$ the same rotation and the same
angular velocity have coordinates nearer the origin,
$\varphi' = \varphi\,(1 - 2\pi/|\varphi|)$ and
$\dot\varphi' = \operatorname{dexp}(\varphi')^{-1}\operatorname{dexp}(\varphi)\,\dot\varphi$,
which the Lie-group solvers switch to at the start of a step (`SceneTerm.recharted`).

So two states' coordinates are compared through what they describe (`shape_difference`,
`shape_velocity_difference`): a measured ball joint (its rotation vector read off MuJoCo's
quaternion, $|\varphi| \le \pi$) and a solved one in another chart are the same rotation and
angular velocity with coordinates $2\pi$ apart.
"""

import jax.numpy as jnp
import numpy as np

from .. import lie
from ._base import AbstractSystem
from ._multibody import AbstractMultibody

__all__ = ["ball_columns", "recharted_shape", "shape_difference", "shape_velocity_difference"]


def ball_columns(system: AbstractSystem) -> np.ndarray:
    """The shape coordinates of each ball joint, a static `(k, 3)` integer array (k = 0
    for a system without ball joints)."""
    if not isinstance(system, AbstractMultibody):
        return np.zeros((0, 3), dtype=int)
    tables = system.tables
    starts = [s for kind, s in zip(tables.kinds, tables.q_start, strict=True) if kind == "ball"]
    return np.asarray(starts, dtype=int).reshape(-1, 1) + np.arange(3)


def recharted_shape(system: AbstractSystem, q, qdot):
    r"""The same shape and shape velocity with every ball joint's rotation vector in the
    ball $|\varphi| \le \pi$ (see the module docstring).

    **Arguments:**

    - `system`: any system (those without ball joints are returned as they are, at no cost).
    - `q`, `qdot`: the shape and its velocity, `(d,)` each.

    **Returns:**

    `(q, qdot)` in the recharted coordinates: the same configuration and the same motion.
    """
    columns = ball_columns(system)
    if columns.size == 0:
        return q, qdot
    phi, phidot = q[columns], qdot[columns]
    theta2 = jnp.sum(phi**2, axis=-1, keepdims=True)
    outside = theta2 > jnp.pi**2
    # Double `where`: inside the ball (φ = 0 included) the flipped branch is never formed
    # from a small |φ|, so neither it nor its derivative is NaN.
    theta = jnp.sqrt(jnp.where(outside, theta2, jnp.pi**2))
    flipped = phi * (1.0 - 2.0 * jnp.pi / theta)
    omega = jnp.einsum("kij,kj->ki", lie.so3_dexp(phi), phidot)
    rates = jnp.einsum("kij,kj->ki", lie.so3_dexp_inv(flipped), omega)
    phi_new = jnp.where(outside, flipped, phi)
    phidot_new = jnp.where(outside, rates, phidot)
    return q.at[columns].set(phi_new), qdot.at[columns].set(phidot_new)


def shape_difference(columns: np.ndarray, q_a, q_b):
    r"""$q_a - q_b$, each ball joint's part the rotation vector of $R(\varphi_b)^T R(\varphi_a)$:
    the same in every chart of either (a hinge's or slide's part is the plain difference).

    **Arguments:**

    - `columns`: the ball joints' coordinates, `ball_columns(system)`.
    - `q_a`, `q_b`: two shapes, `(d,)` each.

    **Returns:**

    The difference, `(d,)`.
    """
    difference = q_a - q_b
    if columns.size == 0:
        return difference
    turn = jnp.einsum("kji,kjl->kil", lie.so3_exp(q_b[columns]), lie.so3_exp(q_a[columns]))
    return difference.at[columns].set(lie.so3_log(turn))


def shape_velocity_difference(columns: np.ndarray, q_a, qdot_a, q_b, qdot_b):
    r"""$\dot q_a - \dot q_b$, each ball joint's part the difference of its angular velocities
    $\omega = \operatorname{dexp}(\varphi)\dot\varphi$ (the same in every chart).

    **Arguments:**

    - `columns`: the ball joints' coordinates, `ball_columns(system)`.
    - `q_a`, `qdot_a`, `q_b`, `qdot_b`: two shapes and their velocities, `(d,)` each.

    **Returns:**

    The difference, `(d,)`.
    """
    difference = qdot_a - qdot_b
    if columns.size == 0:
        return difference

    def omega(q, qdot):
        return jnp.einsum("kij,kj->ki", lie.so3_dexp(q[columns]), qdot[columns])

    return difference.at[columns].set(omega(q_a, qdot_a) - omega(q_b, qdot_b))
