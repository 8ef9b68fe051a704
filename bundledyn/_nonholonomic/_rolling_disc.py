r"""The vertical rolling disc: a disc rolling upright without slipping on a plane."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._validation import check_shape, concrete
from ._constraints import AbstractKinematicConstraints
from ._pfaffian import PfaffianConstraints
from ._system import AbstractNonholonomicSystem


class _ContactRows(eqx.Module):
    r"""Rolling without slipping as Pfaffian rows (76): $\dot x - R\cos\varphi\,\dot\psi = 0$,
    $\dot y - R\sin\varphi\,\dot\psi = 0$."""

    radius: Float[Array, ""]

    def __call__(self, q, t):
        c, s = jnp.cos(q[2]), jnp.sin(q[2])
        zero, one = jnp.zeros_like(c), jnp.ones_like(c)
        return jnp.stack(
            [
                jnp.stack([one, zero, zero, -self.radius * c]),
                jnp.stack([zero, one, zero, -self.radius * s]),
            ]
        )


class RollingDisc(AbstractNonholonomicSystem):
    r"""A disc rolling upright without slipping on a horizontal plane.

    Coordinates $q = (x, y, \varphi, \psi)$: the contact point (below the centre), the
    heading $\varphi$ of the rolling direction $d = (\cos\varphi, \sin\varphi, 0)$ and the
    spin angle $\psi$ about the axle $(-\sin\varphi, \cos\varphi, 0)$. The angular velocity
    is $\dot\varphi\,e_z + \dot\psi\,$axle, and the contact point has zero velocity:
    $\dot x = R\cos\varphi\,\dot\psi$, $\dot y = R\sin\varphi\,\dot\psi$, two Pfaffian rows
    (76) solved for $(\dot x, \dot y)$, the characteristics being $e = (\dot\varphi,
    \dot\psi)$ (`PfaffianConstraints` with `independent=(2, 3)`, which never breaks down).
    The centre stays at height $R$, so gravity does no work, and

    $$ T = \tfrac12 m(\dot x^2 + \dot y^2) + \tfrac12 I_d\dot\varphi^2 + \tfrac12 I_a\dot\psi^2. $$

    **The motion in closed form:** $T^* = \tfrac12 I_d\dot\varphi^2 + \tfrac12(I_a + mR^2)
    \dot\psi^2$ has constant coefficients and the nonholonomic terms do not enter, so
    Maggi's equations are $I_d\ddot\varphi = 0$, $(I_a + mR^2)\ddot\psi = 0$: both rates are
    constant, and the contact point runs on a circle of radius $R\dot\psi/\dot\varphi$
    ($x = x_0 + \frac{R\dot\psi}{\dot\varphi}(\sin\varphi - \sin\varphi_0)$,
    $y = y_0 - \frac{R\dot\psi}{\dot\varphi}(\cos\varphi - \cos\varphi_0)$), or on a line if
    $\dot\varphi = 0$.

    **Arguments:**

    - `mass`: $m > 0$.
    - `radius`: $R > 0$.
    - `axial_inertia`: $I_a$ about the axle; default $mR^2/2$ (a uniform disc).
    - `diametral_inertia`: $I_d$ about a diameter; default $mR^2/4$ (a uniform disc).
    """

    mass: Float[Array, ""]
    radius: Float[Array, ""]
    axial_inertia: Float[Array, ""]
    diametral_inertia: Float[Array, ""]

    def __init__(self, mass, radius, axial_inertia=None, diametral_inertia=None):
        self.mass = jnp.asarray(mass, dtype=float)
        self.radius = jnp.asarray(radius, dtype=float)
        uniform = self.mass * self.radius**2
        self.axial_inertia = (
            uniform / 2 if axial_inertia is None else jnp.asarray(axial_inertia, dtype=float)
        )
        self.diametral_inertia = (
            uniform / 4
            if diametral_inertia is None
            else jnp.asarray(diametral_inertia, dtype=float)
        )

    def __check_init__(self):
        for name in ("mass", "radius", "axial_inertia", "diametral_inertia"):
            value = getattr(self, name)
            check_shape(f"RollingDisc.{name}", value, ())
            v = concrete(value)
            if v is not None and not (np.isfinite(v) and v > 0):
                raise ValueError(f"`RollingDisc.{name}` must be finite and positive, got {v}.")

    @property
    def constraints(self) -> AbstractKinematicConstraints:  # pyright: ignore[reportIncompatibleVariableOverride]
        r"""Rolling without slipping: `PfaffianConstraints` solved for $(\dot x, \dot y)$."""
        return PfaffianConstraints(_ContactRows(self.radius), independent=(2, 3))

    def kinetic_energy(self, q, qdot, t):
        return 0.5 * (
            self.mass * (qdot[0] ** 2 + qdot[1] ** 2)
            + self.diametral_inertia * qdot[2] ** 2
            + self.axial_inertia * qdot[3] ** 2
        )

    def potential_energy(self, q, t):
        return jnp.zeros((), q.dtype)

    def generalized_forces(self, q, qdot, t):
        return jnp.zeros_like(q)
