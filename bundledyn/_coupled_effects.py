r"""Effects written for a system's full shape, acting on its `ConstrainedSystem`.

An effect on the full shape $q$ of a system whose coordinates are coupled, $q = \Phi(p)$,
acts on the free coordinates by the virtual work it does on motions that keep the
constraints: its wrench is unchanged and its shape force is $Q_p = J^TQ_q$,
$J = \partial\Phi/\partial p$ (seed 001, §55). A potential $\Pi(t, g, q)$ is the potential
$\Pi(t, g, \Phi(p))$, whose forces are those.
"""

import jax

from ._effects import AbstractEffect, AbstractPotential, Kinematics
from ._systems._constrained import ConstrainedSystem

__all__ = ["OnFullShape", "OnFullShapePotential", "on_full_shape"]


def _constrained(system, owner: str) -> ConstrainedSystem:
    if not isinstance(system, ConstrainedSystem):
        raise ValueError(
            f"`{owner}` acts on a `ConstrainedSystem`'s full shape; the scene's system is a "
            f"{type(system).__name__}: give it the effect itself."
        )
    return system


class OnFullShapePotential(AbstractPotential):
    r"""A potential written for the full shape $q$, on a `ConstrainedSystem`: $\Pi(t, g, \Phi(p))$.

    **Arguments:**

    - `potential`: an `AbstractPotential` of the unconstrained system.
    """

    potential_of_full_shape: AbstractPotential

    def potential(self, system, t, g, q):
        system = _constrained(system, type(self).__name__)
        return self.potential_of_full_shape.potential(system.system, t, g, system.constraints(q))


class OnFullShape(AbstractEffect):
    r"""An effect written for the full shape $q$, on a `ConstrainedSystem`: its wrench, and
    its shape force $Q_q$ as $Q_p = J^TQ_q$ at $q = \Phi(p)$, $\dot q = J\dot p$.

    **Arguments:**

    - `effect`: an `AbstractEffect` of the unconstrained system.
    """

    effect: AbstractEffect

    def generalized_force(self, system, kin):
        system = _constrained(system, type(self).__name__)
        q, along = jax.linearize(system.constraints, kin.q)  # J, once for both ways
        full = Kinematics(kin.t, kin.g, q, kin.xi, along(kin.qdot))
        F, Q = self.effect.generalized_force(system.system, full)
        (Q_p,) = jax.linear_transpose(along, kin.q)(Q)
        return F, Q_p


def on_full_shape(effect: AbstractEffect) -> AbstractEffect:
    """`effect`, written for a system's full shape, acting on its `ConstrainedSystem`: an
    `OnFullShapePotential` for a potential (so the energy keeps it), else `OnFullShape`."""
    if isinstance(effect, AbstractPotential):
        return OnFullShapePotential(effect)
    return OnFullShape(effect)
