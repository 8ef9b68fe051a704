r"""How a scene's field solves (2.6)–(2.7) for the accelerations: from the dense metric, or
by the articulated-body recursions over a tree."""

import abc

import equinox as eqx
from jaxtyping import Array

from .._dynamics import (
    bundle_geometry,
    driven_shape_acceleration,
    locked_acceleration,
    shape_acceleration,
)
from .._effects import Kinematics, total_force, uniform_fields
from .._linalg import matmul
from .._systems._multibody import Multibody
from .._systems._recursive_dynamics import (
    body_twist,
    covers,
    driven_accelerations,
    floating_accelerations,
    tree_motion,
    uniform_field_twist,
)
from .._systems._recursive_dynamics_vjp import driven_field_vjp, floating_field_vjp

__all__ = ["AbstractFieldAlgorithm", "ArticulatedBodyField", "DenseField", "default_algorithm"]


class AbstractFieldAlgorithm(eqx.Module):
    r"""How a scene's field finds the accelerations of (2.6)–(2.7) (seed 004).

    The modes assemble their fields from its two methods, in the Galilean frame (a moving
    frame's terms are the mode's); every algorithm gives the same accelerations, to
    rounding, at a different cost.
    """

    @abc.abstractmethod
    def check(self, system) -> None:
        """Raise `ValueError`, naming the algorithm to use instead, if this one cannot
        compute the field of `system`."""

    @abc.abstractmethod
    def floating(self, scene, t, g, q, U, qdot) -> tuple[Array, Array, Array]:
        r"""$(\xi, \dot U, \ddot q)$ of a floating base and a free shape (2.6)–(2.7).

        **Arguments:**

        - `scene`: the scene (its system and effects); `t`: the time.
        - `g`, `q`, `U`, `qdot`: the pose, shape, locked velocity and shape velocity in
          the Galilean frame.

        **Returns:**

        `(xi, Udot, qddot)`, shapes `(6,)`, `(6,)`, `(d,)`.
        """

    @abc.abstractmethod
    def driven(self, scene, t, g, q, xi, xi_dot, qdot) -> Array:
        r"""$\ddot q$ of the shape equation when the section frame's motion $(g, \xi,
        \dot\xi)$ is given (a held or moving base).

        **Returns:**

        $\ddot q$, `(d,)`.
        """


class DenseField(AbstractFieldAlgorithm):
    r"""The field from the metric, the connection and their derivatives along the motion
    (`bundle_geometry`): $O(n^2)$ work in the coordinates, any system.

    The choice for systems other than a tree at its base (affine bodies, coupled
    coordinates, a section inside the tree), and for long chains where compiling the
    recursions' levels costs more than their evaluations save.
    """

    def check(self, system) -> None:
        pass

    def floating(self, scene, t, g, q, U, qdot) -> tuple[Array, Array, Array]:
        geo = bundle_geometry(scene.system, q, U, qdot)
        xi = U - matmul(geo.A, qdot)
        F, Q = scene.forces(Kinematics(t, g, q, xi, qdot))
        return xi, locked_acceleration(geo, F), shape_acceleration(geo, F, Q)

    def driven(self, scene, t, g, q, xi, xi_dot, qdot) -> Array:
        _, Q = scene.forces(Kinematics(t, g, q, xi, qdot))
        return driven_shape_acceleration(scene.system, q, xi, xi_dot, qdot, Q)


def _field_and_forces(scene, kin: Kinematics):
    r"""The uniform fields' acceleration in section axes $\gamma_b = R^T\sum\gamma$ (None
    without one) and the other effects' forces `(F_b, Q_H)` at `kin`."""
    gamma, others = uniform_fields(scene.effects)
    F, Q = total_force(others, scene.system, kin)
    if gamma is None:
        return None, F, Q
    return matmul(kin.g[:3, :3].T, gamma.astype(kin.q.dtype)), F, Q


class ArticulatedBodyField(AbstractFieldAlgorithm):
    r"""The field by the articulated-body recursions over a tree's levels
    (`floating_accelerations`, `driven_accelerations`): no metric is formed, and the work
    grows with the bodies, not their square.

    A uniform `Gravity` on the inertial mass enters as the acceleration of a frame falling
    with it (seed 004, Theorem 3.4), not as forces read off the metric; every other
    effect's forces enter as they are. Covers a `Multibody` whose section is its base, with
    hinges, slides, ball joints and welds (any imported MuJoCo tree); `check` refuses
    anything else by name.
    """

    def check(self, system) -> None:
        if not covers(system):
            raise ValueError(
                "`ArticulatedBodyField` needs a `Multibody` whose section is its base, with "
                f"hinges, slides, balls and welds; got {type(system).__name__}. Use "
                "`DenseField()`, which computes the field of any system."
            )

    def floating(self, scene, t, g, q, U, qdot) -> tuple[Array, Array, Array]:
        motion = tree_motion(scene.system, q, qdot)
        xi = body_twist(motion, U)
        gamma, F, Q = _field_and_forces(scene, Kinematics(t, g, q, xi, qdot))
        Udot, qddot = floating_accelerations(scene.system, motion, U, xi, F, Q, gamma)
        return xi, Udot, qddot

    def driven(self, scene, t, g, q, xi, xi_dot, qdot) -> Array:
        gamma, _, Q = _field_and_forces(scene, Kinematics(t, g, q, xi, qdot))
        motion = tree_motion(scene.system, q, qdot)
        return driven_accelerations(scene.system, motion, xi, xi_dot, Q, gamma)

    def floating_vjp(self, scene, t, g, q, U, qdot, qddot, cotangents):
        r"""The VJP of `floating` at its inputs, given its $\ddot q$ there
        (`floating_field_vjp`): cotangents $(\bar\xi, \bar{\dot U}, \bar{\ddot q})$ to
        $(\bar g, \bar q, \bar U, \bar{\dot q})$."""

        def forces(pose, q, xi, qdot):
            gamma, F, Q = _field_and_forces(scene, Kinematics(t, pose, q, xi, qdot))
            return F, Q, uniform_field_twist(gamma, U.dtype)

        return floating_field_vjp(scene.system, g, q, U, qdot, qddot, cotangents, forces)

    def driven_vjp(self, scene, t, g, q, xi, xi_dot, qdot, qddot, qddot_bar):
        r"""The VJP of `driven` in $(q, \dot q)$, given its $\ddot q$ there
        (`driven_field_vjp`): $\bar{\ddot q}$ to $(\bar q, \bar{\dot q})$."""

        def shape_force(q, qdot):
            return _field_and_forces(scene, Kinematics(t, g, q, xi, qdot))[2]

        gamma, _, _ = _field_and_forces(scene, Kinematics(t, g, q, xi, qdot))
        base_acceleration = xi_dot - uniform_field_twist(gamma, xi_dot.dtype)
        return driven_field_vjp(
            scene.system, q, qdot, xi, base_acceleration, qddot, qddot_bar, shape_force
        )


def default_algorithm(system) -> AbstractFieldAlgorithm:
    """`ArticulatedBodyField()` where it covers `system` (a `Multibody` at its base with
    shape coordinates), else `DenseField()`."""
    if isinstance(system, Multibody) and system.shape_dim and covers(system):
        return ArticulatedBodyField()
    return DenseField()
