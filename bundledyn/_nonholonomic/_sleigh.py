r"""The Chaplygin sleigh: a rigid body in the plane on a knife edge (seed 001's first example)."""

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._validation import check_shape, concrete
from ._constraints import AbstractKinematicConstraints, smallest_singular_value
from ._system import AbstractNonholonomicSystem


class _KnifeEdge(AbstractKinematicConstraints):
    r"""The sleigh's blade in parametric form: $e = (v, \omega)$, the blade's forward speed and
    the turning rate; $\dot x = v\cos\theta - a\omega\sin\theta$, $\dot y = v\sin\theta +
    a\omega\cos\theta$, $\dot\theta = \omega$."""

    distance: Float[Array, ""]

    def parametric_form(self, q, t):
        c, s, a = jnp.cos(q[2]), jnp.sin(q[2]), self.distance
        zero, one = jnp.zeros_like(c), jnp.ones_like(c)
        eta = jnp.stack([jnp.stack([c, -a * s]), jnp.stack([s, a * c]), jnp.stack([zero, one])])
        return eta, jnp.zeros_like(q)

    def smallest_singular_value(self, q, t):
        # eta^T eta = diag(1, 1 + a^2): the blade's parametrization never breaks down.
        return smallest_singular_value(self.parametric_form(q, t)[0])


def _check_positive(name, value):
    v = concrete(value)
    if v is not None and not (np.isfinite(v) and v > 0):
        raise ValueError(f"`{name}` must be finite and positive, got {v}.")


class ChaplyginSleigh(AbstractNonholonomicSystem):
    r"""The Chaplygin sleigh: a rigid body in the plane on a knife edge a distance $a$ behind its centre of mass.

    Coordinates $q = (x, y, \theta)$: the centre of mass $C$ and the heading of the body
    axis $u = (\cos\theta, \sin\theta)$. The blade at $P = C - a u$ cannot slide sideways:
    with $n = (-\sin\theta, \cos\theta)$, $v_P\cdot n = 0$, i.e. (76)
    $-\sin\theta\,\dot x + \cos\theta\,\dot y - a\dot\theta = 0$. The characteristics are
    $e = (v, \omega)$, the blade's forward speed $v = v_C\cdot u$ and the turning rate
    $\omega = \dot\theta$ (77):
    $\dot x = v\cos\theta - a\omega\sin\theta$, $\dot y = v\sin\theta + a\omega\cos\theta$.
    $T = \tfrac12 m(\dot x^2 + \dot y^2) + \tfrac12 I\dot\theta^2$ with $I$ about $C$; no
    active forces.

    **The motion in closed form**, from the body's rest frame (axes $u, n$ turning with it):
    $C$ moves with $v_C = v\,u + a\omega\,n$ and the blade's reaction $F n$ acts at $P$.
    Newton's law along $u$ and $n$ and the moment about $C$ give $m(\dot v - a\omega^2) = 0$,
    $m(a\dot\omega + v\omega) = F$, $I\dot\omega = -aF$, so

    $$ \dot v = a\,\omega^2, \qquad (I + ma^2)\,\dot\omega = -m a\, v\,\omega, $$

    which is what Maggi's equations (82) give. The energy $E = \tfrac12 m v^2 +
    \tfrac12 J\omega^2$, $J = I + ma^2$, is conserved, so $\dot v = (am/J)(V^2 - v^2)$ with
    $V^2 = 2E/m$: starting from $v(0) = 0$, $\omega(0) = \omega_0$,

    $$ v = V\tanh(kt), \qquad \omega = \omega_0\,\mathrm{sech}(kt), \qquad
       \theta = \theta_0 + \frac{\omega_0}{k}\arctan\sinh(kt), $$

    with $V = |\omega_0|\sqrt{J/m}$ and $k = amV/J = a|\omega_0|\sqrt{m/J}$ (the second from
    $\dot\omega/\omega = -(ma/J)v$ integrated, the third from $\int\mathrm{sech}$): the sleigh
    stops turning and glides forward at $V$ (Chaplygin 1911; Neimark & Fufaev, *Dynamics of
    Nonholonomic Systems*, ch. II; Bloch, *Nonholonomic Mechanics and Control*, §1.7).

    **Arguments:**

    - `mass`: $m > 0$.
    - `inertia`: $I > 0$, the moment of inertia about the centre of mass.
    - `distance`: $a$, how far the blade is behind the centre of mass along the body axis
      (negative: ahead of it).
    """

    mass: Float[Array, ""]
    inertia: Float[Array, ""]
    distance: Float[Array, ""]

    def __init__(self, mass, inertia, distance):
        self.mass = jnp.asarray(mass, dtype=float)
        self.inertia = jnp.asarray(inertia, dtype=float)
        self.distance = jnp.asarray(distance, dtype=float)

    def __check_init__(self):
        for name in ("mass", "inertia", "distance"):
            check_shape(f"ChaplyginSleigh.{name}", getattr(self, name), ())
        _check_positive("ChaplyginSleigh.mass", self.mass)
        _check_positive("ChaplyginSleigh.inertia", self.inertia)
        a = concrete(self.distance)
        if a is not None and not np.isfinite(a):
            raise ValueError(f"`ChaplyginSleigh.distance` must be finite, got {a}.")

    @property
    def constraints(self) -> AbstractKinematicConstraints:  # pyright: ignore[reportIncompatibleVariableOverride]
        """The blade, in parametric form with $e = (v, \\omega)$."""
        return _KnifeEdge(self.distance)

    def kinetic_energy(self, q, qdot, t):
        return 0.5 * self.mass * (qdot[0] ** 2 + qdot[1] ** 2) + 0.5 * self.inertia * qdot[2] ** 2

    def potential_energy(self, q, t):
        return jnp.zeros((), q.dtype)

    def generalized_forces(self, q, qdot, t):
        return jnp.zeros_like(q)
