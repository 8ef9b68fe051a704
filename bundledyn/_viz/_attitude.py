"""The attitude of a motion as pictures need it: continuous quaternions, the axis it turns
about, and the angle turned about that axis."""

import jax
import numpy as np

from .. import lie

# Below this net turn (radians) a motion has no axis worth looking along.
_NO_TURN = 1e-3
# A net rotation smaller than this share of the largest one on the way is taken for a
# return near the start, whose axis says little about the motion.
_NET_SHARE = 0.25

# Compiled once per number of poses: op by op, the batched conversion compiles every
# operation as a program of its own.
_quaternions = jax.jit(jax.vmap(lie.quaternion_from_rotation))
_logs = jax.jit(jax.vmap(lie.so3_log))


def attitude_quaternions(g) -> np.ndarray:
    """Unit quaternions $(w, x, y, z)$ of the poses `g` `(n, 4, 4)`, signs made continuous.

    $q$ and $-q$ are the same rotation; flipping each sign to stay close to the previous
    sample turns the attitude into a continuous curve (seed 000, Euler parameters).

    **Arguments:**

    - `g`: poses `(n, 4, 4)` (or rotations `(n, 3, 3)`).

    **Returns:**

    The quaternions, `(n, 4)`.
    """
    quats = np.array(_quaternions(np.asarray(g)[:, :3, :3]))
    turns = np.where(np.sum(quats[1:] * quats[:-1], axis=-1) < 0, -1.0, 1.0)
    quats[1:] *= np.cumprod(turns)[:, None]
    return quats


def _turns_from_start(g) -> np.ndarray:
    """The rotations $R_k R_0^T$ that carry the first attitude to each one, `(n, 3, 3)`."""
    R = np.asarray(g)[:, :3, :3]
    return R @ R[0].T


def _rotation_vectors(g) -> np.ndarray:
    r"""The rotation vectors $\log(R_k R_0^T)$, `(n, 3)` (angles up to $\pi$)."""
    return np.asarray(_logs(_turns_from_start(g)))


def turn_axis(g) -> np.ndarray | None:
    r"""The axis a motion turns about, from its rotation vectors $r_k = \log(R_k R_0^T)$.

    The axis of the net rotation $r_{n-1}$ says where the motion ends up (a falling cat's
    axis of reorientation, however it wobbles on the way). When it ends close to where it
    began (near a whole number of turns, so that axis is ill-defined), it is the principal
    direction of the way there: the eigenvector of $\sum_k r_k r_k^T$ with the largest
    eigenvalue. Either way it is oriented so that the net turn about it is positive.

    **Arguments:**

    - `g`: poses `(n, 4, 4)`.

    **Returns:**

    A unit vector `(3,)` in the frame the poses are in, or `None` when the attitude stays
    within a milliradian of the first.
    """
    vectors = _rotation_vectors(g)
    angles = np.linalg.norm(vectors, axis=-1)
    if angles.max() < _NO_TURN:
        return None
    if angles[-1] >= _NET_SHARE * angles.max():
        return vectors[-1] / angles[-1]
    _, axes = np.linalg.eigh(vectors.T @ vectors)
    axis = axes[:, -1]
    return axis if turn_angles(g, axis)[-1] >= 0 else -axis


def turn_angles(g, axis) -> np.ndarray:
    r"""The angle turned about `axis` since the first pose, at every pose (radians, unwrapped).

    The twist of $R_k R_0^T$ about the unit axis $n$: with its quaternion $(w, v)$,
    $2\operatorname{atan2}(v\cdot n, w)$. It is the rotation angle for a turn about $n$
    itself and ignores the swing off it; quaternions with continuous signs make it a
    continuous curve, so whole turns add up.

    **Arguments:**

    - `g`: poses `(n, 4, 4)`.
    - `axis`: a unit vector `(3,)` in the frame the poses are in.

    **Returns:**

    The angles, `(n,)`, the first one 0.
    """
    quats = attitude_quaternions(_turns_from_start(g))
    return 2.0 * np.unwrap(np.arctan2(quats[:, 1:] @ np.asarray(axis), quats[:, 0]))
