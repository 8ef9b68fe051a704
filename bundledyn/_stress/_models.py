"""The small models the cases build: boxes and chains of them."""

import jax.numpy as jnp
import numpy as np

from .._systems._joints import Revolute, Spherical
from .._systems._link import Link
from .._systems._multibody import Multibody
from .._systems._rigid_body import RigidBody


def box(mass: float, size) -> RigidBody:
    """A solid box of `mass` and edge lengths `size`, its centre at its frame's origin."""
    a, b, c = size
    return RigidBody(mass, jnp.zeros(3), mass / 12.0 * jnp.diag(jnp.array([b*b + c*c, a*a + c*c, a*a + b*b])))  # fmt: skip


def chain(masses, *, ball: bool = False) -> Multibody:
    """A free-floating chain of 0.5 m boxes, one per mass, joined end to end by hinges
    about axes that turn from link to link (or by ball joints)."""
    bodies = [box(m, (0.5, 0.1, 0.08)) for m in masses]
    placement = np.eye(4)
    placement[0, 3] = 0.5
    anchor = (-0.25, 0.0, 0.0)

    def joint(i):
        return Spherical(anchor) if ball else Revolute((0.0, np.cos(i), np.sin(i)), anchor)

    links = [Link(bodies[i], joint(i), i - 1, placement) for i in range(1, len(bodies))]
    return Multibody(bodies[0], links)
