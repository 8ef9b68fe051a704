r"""Rolling contacts of a rigid body's convex surface on a plane (seed 001, §54; architecture §5).

A body rolls without slipping when the material point at the contact has zero velocity. In
the body frame, with the plane's upward normal $n$ seen from the body and $c(n)$ the point
of the surface that touches the plane (the surface's lowest point along $n$), that is
$v + \omega\times c(n) = 0$ for the body twist $\xi = (\omega, v)$: three rows of Pfaffian
constraints (76), linear in $\xi$, whose coefficients depend on the configuration through
$n = R^T n_{\rm world}$. Their parametric form (77) takes the angular velocity as the
kinematic characteristics: $\xi = H(n)\,\omega$, $H = (I;\ \tilde c)$, since
$v = c\times\omega$. The normal row is the derivative of a holonomic constraint (the
surface touches the plane) which the rolling mode keeps exactly by placing the body on the
plane; the two tangential rows are not integrable.
"""

import abc

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._validation import check_shape, concrete

__all__ = [
    "AbstractContactSurface",
    "DiscContact",
    "EllipsoidContact",
    "PointContact",
    "SphereContact",
    "TorusContact",
    "contact_twist",
]


def _positive(owner: str, name: str, value) -> None:
    check_shape(f"{owner}.{name}", value, ())
    v = concrete(value)
    if v is not None and not (np.isfinite(v) and v > 0):
        raise ValueError(f"`{owner}.{name}` must be finite and positive, got {v}.")


def unit_axis(owner: str, axis, name: str = "axis") -> Float[Array, "3"]:
    """`axis` as a unit 3-vector, refused with a `ValueError` if it is not a nonzero one."""
    axis = jnp.asarray(axis, dtype=float)
    check_shape(f"{owner}.{name}", axis, (3,))
    norm = concrete(jnp.linalg.norm(axis))
    if norm is not None and not (np.isfinite(norm) and norm > 0):
        raise ValueError(f"`{owner}.{name}` must be a nonzero finite vector, e.g. (0, 1, 0).")
    return axis / jnp.linalg.norm(axis)


def _as_centre(owner: str, centre) -> Float[Array, "3"]:
    centre = jnp.asarray(centre, dtype=float)
    check_shape(f"{owner}.centre", centre, (3,))
    return centre


class AbstractContactSurface(eqx.Module):
    r"""A convex surface fixed in a body, which rolls on a plane.

    Subclasses give `contact_point`: the point $c(n)$ of the surface, in the body frame,
    that touches a plane whose upward unit normal seen from the body is $n$. It must be a
    smooth function of $n$ where the contact is a single point.
    """

    @abc.abstractmethod
    def contact_point(self, n: Float[Array, "3"]) -> Float[Array, "3"]:
        r"""The point $c(n)$ of the surface (body frame) lowest along the unit vector $n$.

        **Arguments:**

        - `n`: the plane's upward unit normal in the body frame, shape `(3,)`.

        **Returns:**

        $c(n)$, shape `(3,)`.
        """


class PointContact(AbstractContactSurface):
    r"""A sharp point fixed in the body, such as a knife edge's or a skate blade's tip:
    $c(n) = c_0$ whatever the plane's normal.

    **Arguments:**

    - `point`: $c_0$ in the body frame.
    """

    point: Float[Array, "3"]

    def __init__(self, point):
        self.point = jnp.asarray(point, dtype=float)

    def __check_init__(self):
        check_shape("PointContact.point", self.point, (3,))

    def contact_point(self, n):
        return self.point


class SphereContact(AbstractContactSurface):
    r"""A sphere of radius $r$ centred at `centre` (body frame): $c(n) = c_0 - r n$.

    With `centre` away from the centre of mass this is a Chaplygin-type ball with an offset
    centre; at the centre of mass with unequal moments, the Chaplygin sphere.

    **Arguments:**

    - `radius`: $r > 0$.
    - `centre`: the sphere's centre in the body frame; default the body frame's origin.
    """

    radius: Float[Array, ""]
    centre: Float[Array, "3"]

    def __init__(self, radius, centre=(0.0, 0.0, 0.0)):
        self.radius = jnp.asarray(radius, dtype=float)
        self.centre = _as_centre("SphereContact", centre)

    def __check_init__(self):
        _positive("SphereContact", "radius", self.radius)

    def contact_point(self, n):
        return self.centre - self.radius * n


def _rim_direction(axis, n):
    r"""$u = (n - (n\cdot a)a)/|n - (n\cdot a)a|$: the direction in the wheel's plane towards
    the plane's normal. Where the wheel lies flat ($n = \pm a$) the contact is a whole
    circle; there $u$ is taken as zero (the centre's point), with finite derivatives
    (double `where`)."""
    in_plane = n - jnp.dot(n, axis) * axis
    squared = jnp.dot(in_plane, in_plane)
    flat = squared < jnp.finfo(n.dtype).eps ** 2
    safe = jnp.where(flat, jnp.ones_like(squared), squared)
    return jnp.where(flat, jnp.zeros_like(in_plane), in_plane / jnp.sqrt(safe))


class DiscContact(AbstractContactSurface):
    r"""A thin disc (a wheel's sharp rim) of radius $r$ about `axis` through `centre`:
    $c(n) = c_0 - r u$ with $u$ the unit vector of $n - (n\cdot a)a$, the rim's lowest point.

    **Arguments:**

    - `radius`: $r > 0$.
    - `axis`: the wheel's axle in the body frame (normalized); default $(0, 1, 0)$.
    - `centre`: the wheel's centre in the body frame; default the origin.
    """

    radius: Float[Array, ""]
    axis: Float[Array, "3"]
    centre: Float[Array, "3"]

    def __init__(self, radius, axis=(0.0, 1.0, 0.0), centre=(0.0, 0.0, 0.0)):
        self.radius = jnp.asarray(radius, dtype=float)
        self.axis = unit_axis("DiscContact", axis)
        self.centre = _as_centre("DiscContact", centre)

    def __check_init__(self):
        _positive("DiscContact", "radius", self.radius)

    def contact_point(self, n):
        return self.centre - self.radius * _rim_direction(self.axis, n)


class TorusContact(AbstractContactSurface):
    r"""A torus-shaped wheel (a tyre): centre circle of radius $r$ about `axis`, tube of
    radius $\rho$: $c(n) = c_0 - r u - \rho n$, $u$ as for `DiscContact`.

    **Arguments:**

    - `radius`: $r > 0$, the centre circle's radius.
    - `tube_radius`: $\rho > 0$.
    - `axis`, `centre`: as for `DiscContact`.
    """

    radius: Float[Array, ""]
    tube_radius: Float[Array, ""]
    axis: Float[Array, "3"]
    centre: Float[Array, "3"]

    def __init__(self, radius, tube_radius, axis=(0.0, 1.0, 0.0), centre=(0.0, 0.0, 0.0)):
        self.radius = jnp.asarray(radius, dtype=float)
        self.tube_radius = jnp.asarray(tube_radius, dtype=float)
        self.axis = unit_axis("TorusContact", axis)
        self.centre = _as_centre("TorusContact", centre)

    def __check_init__(self):
        _positive("TorusContact", "radius", self.radius)
        _positive("TorusContact", "tube_radius", self.tube_radius)

    def contact_point(self, n):
        return self.centre - self.radius * _rim_direction(self.axis, n) - self.tube_radius * n


class EllipsoidContact(AbstractContactSurface):
    r"""An ellipsoid with semi-axes $(a_1, a_2, a_3)$ along the body axes, centred at
    `centre`: $c(n) = c_0 - A^2 n/\sqrt{n^T A^2 n}$, $A = \operatorname{diag}(a)$ (the
    point where the outward normal is $-n$).

    **Arguments:**

    - `semi_axes`: $(a_1, a_2, a_3)$, each positive.
    - `centre`: the centre in the body frame; default the origin.
    """

    semi_axes: Float[Array, "3"]
    centre: Float[Array, "3"]

    def __init__(self, semi_axes, centre=(0.0, 0.0, 0.0)):
        self.semi_axes = jnp.asarray(semi_axes, dtype=float)
        self.centre = _as_centre("EllipsoidContact", centre)

    def __check_init__(self):
        check_shape("EllipsoidContact.semi_axes", self.semi_axes, (3,))
        v = concrete(self.semi_axes)
        if v is not None and not (np.all(np.isfinite(v)) and np.all(v > 0)):
            raise ValueError(f"`EllipsoidContact.semi_axes` must be finite and positive, got {v}.")

    def contact_point(self, n):
        stretched = self.semi_axes**2 * n
        return self.centre - stretched / jnp.sqrt(jnp.dot(n, stretched))


def contact_twist(c: Float[Array, "3"], omega: Float[Array, "3"]) -> Float[Array, "6"]:
    r"""The body twist $\xi = H\omega = (\omega,\ c\times\omega)$ of a body rolling about the
    contact point $c$ (body frame): the material point at $c$ is at rest (the parametric
    form (77) of the rolling constraints, the angular velocity as characteristics).

    **Arguments:**

    - `c`: the contact point in the body frame, shape `(3,)`.
    - `omega`: the body angular velocity, shape `(3,)`.

    **Returns:**

    $\xi$, shape `(6,)`, angular part first.
    """
    return jnp.concatenate([omega, jnp.cross(c, omega)])
