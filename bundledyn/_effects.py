r"""Effects a scene can name: gravity, gravity gradient, shape springs and dampers, forces.

An effect turns the current kinematics into generalized forces in the variables
$(\xi, \dot q)$: a wrench $F_b$ on the section frame (section axes, angular first) and a
shape force $Q_H$. Conservative effects (`AbstractPotential`) are given by their potential
$\Pi(t, g, q)$, which the energy adds; their forces are
$F_b = -\partial_\eta \Pi(g\exp\hat\eta, q)|_0$ (the seed's $\mathcal L\Pi$ with a sign)
and $Q_H = -\partial_q\Pi$, by autodiff, except where an effect writes them out (`Gravity`:
differentiating its potential would differentiate the metric).
Only the effects a scene names enter its compiled vector field.
Their `potential` and `generalized_force` are compiled (`equinox.filter_jit`): called on
concrete values, each runs as one program, not primitive by primitive.
"""

import abc
from collections.abc import Callable
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
from jax.typing import ArrayLike
from jaxtyping import Array, Float

from . import lie
from ._systems._base import AbstractSystem
from ._systems._multibody import AbstractMultibody


class Kinematics(NamedTuple):
    """The motion at one instant, in the Galilean frame: time, pose, shape and velocities."""

    t: Float[ArrayLike, ""]
    g: Float[Array, "4 4"]
    q: Float[Array, " d"]
    xi: Float[Array, "6"]
    qdot: Float[Array, " d"]


def mass_and_centre(I_r: Float[Array, "6 6"]):
    r"""Total mass $m$ and centre of mass $c$ (section frame) read off the locked inertia.

    By Lemma 1 / Theorem 2.3 (seed 004), $I_r = \begin{bmatrix} l - m\tilde c\tilde c & m\tilde c\\
    m\tilde c^T & m 1\end{bmatrix}$ for a Galilean-invariant system.

    **Returns:**

    `(m, c, l)`: mass, centre of mass `(3,)` and rotational inertia about it `(3, 3)`.
    """
    m = jnp.trace(I_r[3:, 3:]) / 3.0
    c_hat = I_r[:3, 3:] / m
    c = lie.vee(0.5 * (c_hat - c_hat.T))
    return m, c, I_r[:3, :3] + m * c_hat @ c_hat


class AbstractEffect(eqx.Module):
    """Something that acts on the system: it supplies generalized forces $(F_b, Q_H)$.

    A conservative effect is an `AbstractPotential`: it has a potential, which
    `Trajectory.energy` adds to the kinetic energy; other effects have none.
    """

    @abc.abstractmethod
    def generalized_force(
        self, system: AbstractSystem, kin: Kinematics
    ) -> tuple[Float[Array, "6"], Float[Array, " d"]]:
        """The generalized force `(F_b (6,), Q_H (d,))` at the kinematics `kin`."""


def total_force(effects, system: AbstractSystem, kin: Kinematics):
    """The sum of `effects`' generalized forces `(F_b, Q_H)` on `system` at `kin`."""
    F = jnp.zeros(6, kin.q.dtype)
    Q = jnp.zeros_like(kin.q)
    for effect in effects:
        dF, dQ = effect.generalized_force(system, kin)
        F, Q = F + dF, Q + dQ
    return F, Q


class AbstractPotential(AbstractEffect):
    r"""A conservative effect given by its potential $\Pi(t, g, q)$; forces by autodiff.

    The energy (`Trajectory.energy`) is the kinetic energy plus the potentials of the
    scene's effects that are `AbstractPotential`s.
    """

    @abc.abstractmethod
    def potential(self, system: AbstractSystem, t, g, q) -> Float[Array, ""]:
        r"""$\Pi(t, g, q)$, a scalar."""

    @eqx.filter_jit
    def generalized_force(self, system, kin):
        def Pi(eta, q):
            return self.potential(system, kin.t, kin.g @ lie.se3_exp(eta), q)

        dPi_deta, dPi_dq = jax.grad(Pi, argnums=(0, 1))(jnp.zeros(6, kin.q.dtype), kin.q)
        return -dPi_deta, -dPi_dq


class Gravity(AbstractPotential):
    r"""Uniform gravity $\gamma = g\,\chi$: $\Pi = -m_g\,\gamma\cdot(p + R(c + \delta))$ (seed 004, (3.1)).

    The centre of mass $c(q)$ and mass $m$ come from the locked inertia
    (`mass_and_centre`), so gravity needs nothing but the metric.

    **Arguments:**

    - `g`: magnitude of the acceleration of gravity (default 9.81).
    - `direction`: unit vector $\chi$ of gravity in the Galilean frame (default $-e_z$).
    - `gravitational_mass`: $m_g$; default: the inertial mass (the equivalence principle).
    - `centre_offset`: $\delta$, the centre of gravity minus the centre of mass in the section
      frame; default 0. Setting it apart breaks Theorem 3.4 (the seed's remark).
    """

    g: Float[Array, ""]
    direction: Float[Array, "3"]
    gravitational_mass: Float[Array, ""] | None
    centre_offset: Float[Array, "3"] | None

    def __init__(
        self, g=9.81, direction=(0.0, 0.0, -1.0), *, gravitational_mass=None, centre_offset=None
    ):
        self.g = jnp.asarray(g, dtype=float)
        direction = jnp.asarray(direction, dtype=float)
        if direction.shape != (3,):
            raise ValueError(
                f"`Gravity.direction` must be a 3-vector, got shape {direction.shape}."
            )
        self.direction = direction / jnp.linalg.norm(direction)
        self.gravitational_mass = (
            None if gravitational_mass is None else jnp.asarray(gravitational_mass, dtype=float)
        )
        self.centre_offset = (
            None if centre_offset is None else jnp.asarray(centre_offset, dtype=float)
        )

    def _weight(self, m):
        r"""$m_g\,\gamma$ over $m$: the weight per unit of inertial mass."""
        m_g = m if self.gravitational_mass is None else self.gravitational_mass
        return m_g / m * self.g * self.direction

    def _centre(self, c):
        r"""The centre of gravity $c + \delta$ in the section frame."""
        return c if self.centre_offset is None else c + self.centre_offset

    @eqx.filter_jit
    def potential(self, system, t, g, q):
        m, c, _ = mass_and_centre(system.metric(q)[:6, :6])
        return -m * self._weight(m) @ (g[:3, 3] + g[:3, :3] @ self._centre(c))

    @eqx.filter_jit
    def generalized_force(self, system, kin):
        r"""$F_b = (m_g (c + \delta)\times\gamma_b,\; m_g\gamma_b)$ and $Q_H = \tfrac{m_g}{m}
        B_v^T\gamma_b$, with $\gamma_b = R^T\gamma$ and $B_v$ the linear rows of the metric's
        coupling block $B = I_r A$ (seed 004, (3.1)).

        For a system that satisfies Theorem 2.2, $B_v = m\,\partial c/\partial q$ (Theorem
        2.3, property 2: the centre of mass does not move at zero momentum), so these are
        $-\partial\Pi$ without differentiating the metric. They are read off the metric jet
        the field computes, so inside the field XLA computes that metric once.

        **Arguments:**

        - `system`: the system; `kin`: the `Kinematics`.

        **Returns:**

        `(F_b, Q_H)`, shapes `(6,)` and `(d,)`.
        """
        rows = system.metric_jet(kin.q).metric[:6]
        m, c, _ = mass_and_centre(rows[:, :6])
        weight = m * (kin.g[:3, :3].T @ self._weight(m))
        F_b = jnp.concatenate([jnp.cross(self._centre(c), weight), weight])
        return F_b, rows[3:6, 6:].T @ weight / m


def uniform_fields(effects) -> tuple[Float[Array, "3"] | None, tuple]:
    r"""The uniform fields among `effects`: `Gravity`s acting on every body as on its inertial
    mass (no gravitational mass of their own, no centre offset), which are the acceleration
    $\gamma$ of a frame falling with them (seed 004, Theorem 3.4), not forces.

    **Arguments:**

    - `effects`: a scene's effects.

    **Returns:**

    `(gamma, others)`: their summed acceleration $\gamma$ in the Galilean frame, `(3,)`
    (`None` without one), and the other effects in their order.
    """
    fields = [e for e in effects if _is_uniform_field(e)]
    others = tuple(e for e in effects if not _is_uniform_field(e))
    if not fields:
        return None, others
    return jnp.sum(jnp.stack([e.g * e.direction for e in fields]), axis=0), others


def _is_uniform_field(effect) -> bool:
    return (
        type(effect) is Gravity
        and effect.gravitational_mass is None
        and effect.centre_offset is None
    )


class AbstractCentralGravity(AbstractPotential):
    r"""A central Newtonian field $-\mu/|x - x_0|$ with its gravity gradient (seed 004, §3).

    Each mass element's potential is expanded to second order about its centre of mass
    (MacCullagh's formula): $\Pi = -\tfrac{\mu m}{\rho} - \tfrac{\mu}{2\rho^3}
    (\operatorname{tr} l - 3\hat\rho^T l\hat\rho)$ with $\rho = c - x_0$ and $l$ the rotational
    inertia about $c$, summed over the elements that `mass_elements` gives.
    """

    mu: eqx.AbstractVar[Float[Array, ""]]
    centre: eqx.AbstractVar[Float[Array, "3"]]

    @abc.abstractmethod
    def mass_elements(
        self, system: AbstractSystem, g, q
    ) -> tuple[Float[Array, " k"], Float[Array, "k 3"], Float[Array, "k 3 3"]]:
        """The masses `(k,)`, centres of mass `(k, 3)` and rotational inertias about them
        `(k, 3, 3)` of the elements the expansion is applied to, in the Galilean frame."""

    def _maccullagh(self, m, c_world, l_world):
        rho = c_world - self.centre
        r2 = rho @ rho
        r = jnp.sqrt(r2)
        quad = jnp.trace(l_world) - 3.0 * rho @ l_world @ rho / r2
        return -self.mu * m / r - 0.5 * self.mu * quad / (r2 * r)

    @eqx.filter_jit
    def potential(self, system, t, g, q):
        return jnp.sum(jax.vmap(self._maccullagh)(*self.mass_elements(system, g, q)))


class GravityGradient(AbstractCentralGravity):
    r"""A central field's gravity gradient on the whole system, expanded about its centre of mass.

    $m, c, l$ come from the locked inertia (`mass_and_centre`), so it applies to any
    system (see `AbstractCentralGravity` for the potential).

    **Arguments:**

    - `mu`: gravitational parameter $\mu = G M$.
    - `centre`: $x_0$, the attracting centre in the Galilean frame (default origin).
    """

    mu: Float[Array, ""]
    centre: Float[Array, "3"]

    def __init__(self, mu, centre=(0.0, 0.0, 0.0)):
        self.mu = jnp.asarray(mu, dtype=float)
        self.centre = jnp.asarray(centre, dtype=float)

    def mass_elements(self, system, g, q):
        R, p = g[:3, :3], g[:3, 3]
        m, c, l = mass_and_centre(system.metric(q)[:6, :6])
        return m[None], (p + R @ c)[None], (R @ l @ R.T)[None]

    @eqx.filter_jit
    def generalized_force(self, system, kin):
        r"""$F_b = -\partial_\eta\Pi$ and $Q_H = -\partial_q\Pi$ through the locked inertia:
        $\partial_q\Pi = \partial_c\Pi\,B_v/m + \sum_i e_i^T(\partial_q G)(P e_i)$, with
        $P = \partial\Pi/\partial I_\omega$ the potential's derivative in the locked inertia's
        rotational block (at fixed centre of mass) and $B_v = m\,\partial c/\partial q$
        (Theorem 2.3, seed 004).

        The metric's derivative enters through the jet's forms (`AbstractMetricJet.forms`)
        of the three pairs $(e_i, P e_i)$, not by differentiating the metric; the jet is the
        one the field computes, so inside the field XLA computes it once.

        **Arguments:**

        - `system`: the system; `kin`: the `Kinematics`.

        **Returns:**

        `(F_b, Q_H)`, shapes `(6,)` and `(d,)`.
        """
        jet = system.metric_jet(kin.q)
        rows = jet.metric[:6]
        m, c, _ = mass_and_centre(rows[:, :6])

        def potential(eta, c, rotational):
            g = kin.g @ lie.se3_exp(eta)
            R, c_hat = g[:3, :3], lie.so3_hat(c)
            l = rotational + m * c_hat @ c_hat  # about the centre of mass (`mass_and_centre`)
            return self._maccullagh(m, g[:3, 3] + R @ c, R @ l @ R.T)

        zero = jnp.zeros(6, kin.q.dtype)
        dPi_deta, dPi_dc, dPi_drot = jax.grad(potential, argnums=(0, 1, 2))(zero, c, rows[:3, :3])
        P = 0.5 * (dPi_drot + dPi_drot.T)
        d = kin.q.shape[0]
        angular = jnp.concatenate([jnp.eye(3, dtype=P.dtype), jnp.zeros((3, 3 + d), P.dtype)], 1)
        forms = jet.forms(jnp.concatenate([angular, P @ angular]))
        rotational = sum(forms[i, 3 + i] for i in range(3))
        return -dPi_deta, -(rotational + dPi_dc @ rows[3:6, 6:] / m)


class BodywiseGravityGradient(AbstractCentralGravity):
    r"""A central field's gravity gradient summed body by body over a tree of bodies.

    Exact up to each body's own third moments (see `AbstractCentralGravity`); the system
    must be a `Multibody` (an `AbstractMultibody`).

    **Arguments:**

    - `mu`: gravitational parameter $\mu = G M$.
    - `centre`: $x_0$, the attracting centre in the Galilean frame (default origin).
    """

    mu: Float[Array, ""]
    centre: Float[Array, "3"]

    def __init__(self, mu, centre=(0.0, 0.0, 0.0)):
        self.mu = jnp.asarray(mu, dtype=float)
        self.centre = jnp.asarray(centre, dtype=float)

    def mass_elements(self, system, g, q):
        tree = require_tree(system, "BodywiseGravityGradient")
        poses = g @ tree.body_poses(q)
        R = poses[:, :3, :3]
        c = poses[:, :3, 3] + jnp.einsum("nij,nj->ni", R, tree.com)
        return tree.mass, c, jnp.einsum("nij,njk,nlk->nil", R, tree.inertia, R)


def require_tree(system, what) -> AbstractMultibody:
    """`system` itself, once it is known to be a tree of bodies.

    **Arguments:**

    - `system`: the system an effect acts on; `what`: the effect, for the message.

    **Returns:**

    `system`, typed as the `AbstractMultibody` it must be.
    """
    if not isinstance(system, AbstractMultibody):
        raise ValueError(
            f"`{what}` acts on the bodies of a tree and needs a Multibody, got "
            f"{type(system).__name__}."
        )
    return system


def _shape_matrix(value, d, name):
    K = jnp.asarray(value, dtype=float)
    if K.ndim == 0:
        return K * jnp.eye(d)
    if K.shape == (d,):
        return jnp.diag(K)
    if K.shape == (d, d):
        return K
    raise ValueError(
        f"`{name}` must be a scalar, a ({d},) vector or a ({d}, {d}) matrix, got {K.shape}."
    )


class ShapePotential(AbstractPotential):
    r"""A potential of the shape alone, $\Pi = V(q)$ (internal elastic energy, say).

    **Arguments:**

    - `fn`: `V(q) -> scalar`, a JAX function (an `equinox.Module` to carry parameters).
    """

    fn: Callable

    @eqx.filter_jit
    def potential(self, system, t, g, q):
        return self.fn(q)


class ShapeSpring(AbstractPotential):
    r"""A linear spring on the shape, $\Pi = \tfrac12 (q - q_0)^T K (q - q_0)$.

    **Arguments:**

    - `stiffness`: $K$, a scalar, a `(d,)` vector (diagonal) or a `(d, d)` matrix.
    - `rest`: $q_0$, the rest shape (default 0).
    """

    stiffness: Array
    rest: Array | float

    def __init__(self, stiffness, rest: ArrayLike = 0.0):
        self.stiffness = jnp.asarray(stiffness, dtype=float)
        self.rest = jnp.asarray(rest, dtype=float)

    @eqx.filter_jit
    def potential(self, system, t, g, q):
        K = _shape_matrix(self.stiffness, q.shape[0], "ShapeSpring.stiffness")
        dq = q - self.rest
        return 0.5 * dq @ K @ dq


class ShapeDamper(AbstractEffect):
    r"""Linear damping of the shape velocity, $Q_H = -C\dot q$.

    **Arguments:**

    - `c`: $C$, a scalar, a `(d,)` vector (diagonal) or a `(d, d)` matrix.
    """

    c: Array

    def __init__(self, c):
        self.c = jnp.asarray(c, dtype=float)

    @eqx.filter_jit
    def generalized_force(self, system, kin):
        C = _shape_matrix(self.c, kin.q.shape[0], "ShapeDamper.c")
        return jnp.zeros(6, kin.q.dtype), -C @ kin.qdot


class ShapeForce(AbstractEffect):
    r"""A shape force given by the user, $Q_H = f(t, q, \dot q)$ (actuators, control laws).

    **Arguments:**

    - `fn`: `f(t, q, qdot) -> (d,)`, a JAX function.
    """

    fn: Callable

    @eqx.filter_jit
    def generalized_force(self, system, kin):
        return jnp.zeros(6, kin.q.dtype), self.fn(kin.t, kin.q, kin.qdot)


class ExternalWrench(AbstractEffect):
    r"""An external wrench on one body, given in that body's own frame.

    **Arguments:**

    - `fn`: `f(t, g, q, xi, qdot) -> (6,)`, the wrench $(\tau, f)$ on the body: torque about
      the body's origin and force, both in the body's axes (angular first); `g` is the
      section frame's pose in the Galilean frame.
    - `body`: index of the body of a `Multibody` (static), or `None` for the section frame.
    """

    fn: Callable
    body: int | None = eqx.field(static=True, default=None)

    @eqx.filter_jit
    def generalized_force(self, system, kin):
        w = self.fn(kin.t, kin.g, kin.q, kin.xi, kin.qdot)
        if self.body is None:
            return w, jnp.zeros_like(kin.q)
        tree = require_tree(system, f"ExternalWrench(body={self.body})")
        r, Jhat = tree.velocity_jacobians(kin.q)
        # The body twist is Ad_{r⁻¹} Ĵ [ξ; q̇], so the wrench's virtual power gives Ĵᵀ Ad_{r⁻¹}ᵀ w.
        generalized = Jhat[self.body].T @ lie.Ad(lie.se3_inv(r[self.body])).T @ w
        return generalized[:6], generalized[6:]
