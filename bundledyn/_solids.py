"""Homogeneous solids: the inertia of a box, an ellipsoid or a capsule, and their surfaces.

A solid is a shape in its own frame (centred at its centre of mass, axes along its
principal axes). It gives a `RigidBody` its inertia from a mass, and `bundledyn.viz` the
surface to draw.
"""

import abc

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ._systems._rigid_body import RigidBody
from ._validation import check_shape, concrete


def _positive(name, value):
    v = concrete(value)
    if v is not None and not (np.all(np.isfinite(v)) and np.all(v > 0)):
        raise ValueError(f"`{name}` must be finite and positive, got {v}.")


class AbstractSolid(eqx.Module):
    """A homogeneous solid in its principal frame, centre of mass at the origin."""

    @abc.abstractmethod
    def principal_moments(self, mass) -> Float[Array, "3"]:
        """Its principal moments of inertia about the centre of mass, for a given mass."""

    @abc.abstractmethod
    def surface(self, resolution: int = 12) -> np.ndarray:
        """Points of its surface in its own frame, shape `(rows, columns, 3)` (a mesh grid)."""

    def rigid_body(self, mass, com=(0.0, 0.0, 0.0)) -> RigidBody:
        r"""The `RigidBody` of this solid with mass `mass`, its centre at `com` in the body frame.

        **Arguments:**

        - `mass`: $m > 0$.
        - `com`: where the solid's centre sits in the body frame (default the origin).

        **Returns:**

        A `RigidBody` with inertia $\operatorname{diag}(I_1, I_2, I_3)$ about `com`.
        """
        return RigidBody(mass, com, jnp.diag(self.principal_moments(jnp.asarray(mass, float))))


class Box(AbstractSolid):
    """A solid box with edge lengths $(a, b, c)$: $I_1 = m(b^2 + c^2)/12$ and cyclic.

    **Arguments:**

    - `size`: the three edge lengths along the box's x, y, z axes.
    """

    size: Float[Array, "3"]

    def __init__(self, size):
        self.size = jnp.asarray(size, dtype=float)

    def __check_init__(self):
        check_shape("Box.size", self.size, (3,))
        _positive("Box.size", self.size)

    def principal_moments(self, mass):
        return _moments(mass, self.size**2, 12.0)

    def surface(self, resolution=12):
        # The unit cube's surface as one grid: the sphere grid pushed out to the faces.
        u = _sphere(resolution)
        cube = u / np.max(np.abs(u), axis=-1, keepdims=True)
        return 0.5 * cube * np.asarray(self.size)

    @classmethod
    def equivalent(cls, mass, moments) -> "Box":
        """The box of mass `mass` with principal moments `moments` (its inertia box).

        Inverts $I_1 = m(b^2 + c^2)/12$: $a^2 = 6(I_2 + I_3 - I_1)/m$ and cyclic.
        """
        return cls(_lengths(mass, moments, 12.0))


class Ellipsoid(AbstractSolid):
    """A solid ellipsoid with semi-axes $(a, b, c)$: $I_1 = m(b^2 + c^2)/5$ and cyclic.

    **Arguments:**

    - `radii`: the semi-axes along x, y, z.
    """

    radii: Float[Array, "3"]

    def __init__(self, radii):
        self.radii = jnp.asarray(radii, dtype=float)

    def __check_init__(self):
        check_shape("Ellipsoid.radii", self.radii, (3,))
        _positive("Ellipsoid.radii", self.radii)

    def principal_moments(self, mass):
        return _moments(mass, self.radii**2, 5.0)

    def surface(self, resolution=12):
        return _sphere(resolution) * np.asarray(self.radii)

    @classmethod
    def equivalent(cls, mass, moments) -> "Ellipsoid":
        """The ellipsoid of mass `mass` with principal moments `moments`.

        Inverts $I_1 = m(b^2 + c^2)/5$: $a^2 = 5(I_2 + I_3 - I_1)/(2m)$ and cyclic.
        """
        return cls(_lengths(mass, moments, 5.0))


class Capsule(AbstractSolid):
    r"""A solid capsule along x: a cylinder of radius $r$ and length $l$ with hemispherical caps.

    With $m_c = m\,l/(l + 4r/3)$ in the cylinder and $m_s = m - m_c$ in the caps,
    $I_x = m_c r^2/2 + 2 m_s r^2/5$ and
    $I_y = I_z = m_c(l^2/12 + r^2/4) + m_s(2r^2/5 + l^2/4 + 3lr/8)$ (each cap's centre of mass
    lies $3r/8$ from its flat face).

    **Arguments:**

    - `radius`: $r$.
    - `length`: $l$, the cylinder's length between the caps' flat faces.
    """

    radius: Float[Array, ""]
    length: Float[Array, ""]

    def __init__(self, radius, length):
        self.radius = jnp.asarray(radius, dtype=float)
        self.length = jnp.asarray(length, dtype=float)

    def __check_init__(self):
        check_shape("Capsule.radius", self.radius, ())
        check_shape("Capsule.length", self.length, ())
        _positive("Capsule.radius", self.radius)
        _positive("Capsule.length", self.length)

    def principal_moments(self, mass):
        r, l = self.radius, self.length
        m_cylinder = mass * l / (l + 4.0 * r / 3.0)
        m_caps = mass - m_cylinder
        axial = m_cylinder * r**2 / 2 + m_caps * 2 * r**2 / 5
        transverse = m_cylinder * (l**2 / 12 + r**2 / 4) + m_caps * (
            2 * r**2 / 5 + l**2 / 4 + 3 * l * r / 8
        )
        return jnp.stack([axial, transverse, transverse])

    def surface(self, resolution=12):
        u = _sphere(resolution)
        r, half = float(self.radius), 0.5 * float(self.length)
        points = r * u
        points[..., 0] += np.sign(u[..., 0]) * half  # split the sphere and pull its halves apart
        return points


def _moments(mass, squares, divisor):
    """$I_1 = m(s_2^2 + s_3^2)/k$ and cyclic: the moments of a box ($k = 12$) or ellipsoid ($k = 5$)."""
    return mass / divisor * (jnp.sum(squares) - squares)


def _lengths(mass, moments, divisor):
    """The lengths $s_i$ that `_moments` turns into `moments`: $s_1^2 = k(I_2 + I_3 - I_1)/(2m)$."""
    moments = np.asarray(moments, dtype=float)
    squares = 0.5 * divisor * (np.sum(moments) - 2.0 * moments) / float(mass)
    return np.sqrt(np.maximum(squares, 1e-12 * np.max(squares)))


def _sphere(resolution):
    """The unit sphere as a `(resolution + 1, 2 * resolution + 1, 3)` latitude–longitude grid."""
    theta = np.linspace(0.0, np.pi, resolution + 1)[:, None]
    phi = np.linspace(0.0, 2.0 * np.pi, 2 * resolution + 1)[None, :]
    return np.stack(
        np.broadcast_arrays(
            np.cos(theta), np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi)
        ),
        axis=-1,
    )
