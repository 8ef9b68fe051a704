r"""Springs and dampers along tendons that run straight between points fixed in a tree's bodies.

A tendon through sites $p_1, \dots, p_n$ (each fixed in a body of the tree) has the length
$L(q) = \sum_i |p_{i+1}(q) - p_i(q)|$, the positions taken in the section frame: a tendon
is internal to the system, so its length depends on the shape alone and its forces have
no net wrench. MuJoCo's passive force of a spatial tendon, $-k\,(L - L_s) - b\,\dot L$
along it, is the potential $\tfrac12 k\,(L - L_s)^2$ (`TendonSpring`) and the shape force
$-b\,\dot L\,\partial L/\partial q$ (`TendonDamper`).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.typing import ArrayLike
from jaxtyping import Array, Float

from ._effects import AbstractEffect, AbstractPotential, require_tree

__all__ = ["SitePath", "TendonDamper", "TendonSpring"]


def _segment_length(d: Float[Array, "... 3"]) -> Float[Array, "..."]:
    """$|d|$ with a zero derivative where $d = 0$ (two sites at one point), not NaN."""
    squared = jnp.sum(d**2, axis=-1)
    apart = squared > 0
    return jnp.where(apart, jnp.sqrt(jnp.where(apart, squared, 1.0)), 0.0)


class SitePath(eqx.Module):
    r"""A tendon's path: straight segments between points fixed in bodies of a tree.

    **Arguments:**

    - `bodies`: the body of each point, in order along the tendon (static).
    - `points`: each point in its body's frame, `(n, 3)`.
    """

    bodies: tuple[int, ...] = eqx.field(static=True)
    points: Array

    def __init__(self, bodies, points: ArrayLike):
        self.bodies = tuple(int(b) for b in bodies)
        self.points = jnp.asarray(points, dtype=float)

    def __check_init__(self):
        if len(self.bodies) < 2 or self.points.shape != (len(self.bodies), 3):
            raise ValueError(
                "a `SitePath` needs two points or more, one body each: `points` of shape "
                f"({len(self.bodies)}, 3) for {len(self.bodies)} bodies, got "
                f"{self.points.shape}."
            )

    def length(self, system, q: Float[Array, " d"]) -> Float[Array, ""]:
        r"""$L(q)$, the sum of the segments' lengths (module docstring).

        **Arguments:**

        - `system`: the tree (an `AbstractMultibody`); `q`: its shape.

        **Returns:**

        The length.
        """
        poses = require_tree(system, "SitePath").body_poses(q)[jnp.asarray(self.bodies)]
        p = jnp.einsum("nij,nj->ni", poses[:, :3, :3], self.points) + poses[:, :3, 3]
        return jnp.sum(_segment_length(p[1:] - p[:-1]))


class TendonSpring(AbstractPotential):
    r"""A linear spring along a tendon, $\Pi = \tfrac12 k\,(L(q) - L_s)^2$ (MuJoCo's
    spatial tendon `stiffness` about its `springlength`).

    **Arguments:**

    - `path`: the tendon's `SitePath`.
    - `stiffness`: $k$; `spring_length`: $L_s$.
    """

    path: SitePath
    stiffness: Array
    spring_length: Array

    def __init__(self, path: SitePath, stiffness: ArrayLike, spring_length: ArrayLike):
        self.path = path
        self.stiffness = jnp.asarray(stiffness, dtype=float)
        self.spring_length = jnp.asarray(spring_length, dtype=float)

    @eqx.filter_jit
    def potential(self, system, t, g, q):
        stretch = self.path.length(system, q) - self.spring_length
        return 0.5 * self.stiffness * stretch**2


class TendonDamper(AbstractEffect):
    r"""Linear damping along a tendon, $Q_H = -b\,\dot L\,\partial L/\partial q$ with
    $\dot L = \partial L/\partial q\,\dot q$ (MuJoCo's spatial tendon `damping`).

    **Arguments:**

    - `path`: the tendon's `SitePath`.
    - `damping`: $b$.
    """

    path: SitePath
    damping: Array

    def __init__(self, path: SitePath, damping: ArrayLike):
        self.path = path
        self.damping = jnp.asarray(damping, dtype=float)

    @eqx.filter_jit
    def generalized_force(self, system, kin):
        direction = jax.grad(lambda q: self.path.length(system, q))(kin.q)
        return jnp.zeros(6, kin.q.dtype), -self.damping * (direction @ kin.qdot) * direction
