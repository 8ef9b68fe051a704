r"""Theorem 2.2's conditions and Theorem 2.3's rigid structure, computed from the metric alone.

Everything is evaluated on the section, $s = r(q)$ ($g = e$), where the spatial and the
section-frame descriptions coincide. Derivatives along horizontal directions are taken by
forward-mode autodiff along the horizontal lift $\varepsilon \mapsto
\exp(-\varepsilon A(q)\,\delta q)\cdot r(q + \varepsilon\,\delta q)$ (seed 004, §2), on which
the spatial locked inertia is $\operatorname{Ad}_{g^{-1}}^T I_r(q) \operatorname{Ad}_{g^{-1}}$.

Residuals are made unit-free by rewriting the metric in the system's own units: mass
$m_0 = \operatorname{tr} I_{vv}/3$, length $L = (\operatorname{tr} I_{\omega\omega} /
\operatorname{tr} I_{vv})^{1/2}$ and, for each shape coordinate, the step $h_k$ whose kinetic
energy scale is $m_0 L^2$. Scaling lengths is an automorphism of $\mathfrak{se}(3)$, so every
condition keeps its form and one tolerance serves any units.
"""

from collections.abc import Callable
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .. import lie
from .._effects import mass_and_centre
from .._geometry import curvature_from_connection
from .._systems._base import AbstractSystem
from .._systems._rigid_body import spatial_inertia

MetricChart = Callable[[Float[Array, " d"]], Float[Array, "6+d 6+d"]]


def _physical_chart(system: AbstractSystem, q) -> MetricChart:
    r"""$\delta \mapsto G(q + \delta)$: the metric around $q$ in the system's own units."""
    return lambda delta: system.metric(q + delta)


def _unit_free_chart(system: AbstractSystem, q) -> MetricChart:
    r"""$\delta \mapsto \tilde G(\delta)$: the metric around $q$ in units of its own mass, length and shape steps."""
    G = system.metric(q)
    trace_v, trace_w = jnp.trace(G[3:6, 3:6]), jnp.trace(G[:3, :3])
    mass, length = trace_v / 3.0, jnp.sqrt(trace_w / trace_v)
    energy = mass * length**2
    step = jnp.sqrt(energy / jnp.diagonal(G)[6:])
    one = jnp.ones(3, G.dtype)
    scale = jnp.concatenate([one, length * one, step])
    return lambda delta: jnp.outer(scale, scale) * system.metric(q + step * delta) / energy


def _locked(chart: MetricChart, delta):
    G = chart(delta)
    I_r = G[:6, :6]
    return I_r, jnp.linalg.solve(I_r, G[:6, 6:])


class _FirstOrder(NamedTuple):
    r"""The locked inertia and connection at the shape, and their derivatives along horizontal lifts.

    `dI[k]` is the derivative of the spatial locked inertia $\operatorname{Ad}_{g^{-1}}^T I_r
    \operatorname{Ad}_{g^{-1}}$ along the horizontal lift of $e_k$; `dA[k]` $= \partial_k A$.
    """

    I_r: Float[Array, "6 6"]
    A: Float[Array, "6 d"]
    dI: Float[Array, "d 6 6"]
    dA: Float[Array, "d 6 d"]


def _first_order(chart: MetricChart, d: int, dtype) -> _FirstOrder:
    zero = jnp.zeros(d, dtype)
    A0 = _locked(chart, zero)[1]

    def along_lift(delta):
        # To first order the horizontal lift of δ starts with g = exp(-A(q) δ).
        I_r, A = _locked(chart, delta)
        coAd = lie.coAd(lie.se3_exp(-A0 @ delta))  # Ad_{g^{-1}}^T
        spatial = coAd @ I_r @ coAd.T
        return (spatial, A), (I_r, A)

    (dI, dA), (I_r, A) = jax.jacfwd(along_lift, has_aux=True)(zero)
    return _FirstOrder(I_r, A, jnp.moveaxis(dI, -1, 0), jnp.moveaxis(dA, -1, 0))


def inertial_coupling(I_r: Float[Array, "6 6"], X: Float[Array, "6"], Y: Float[Array, "6"]):
    r"""The seed's $\mathbf C(s)(X, Y) = \operatorname{ad}^*_X\mathbf I(Y) + \operatorname{ad}^*_Y\mathbf I(X) + \mathbf I([X, Y])$.

    With $\operatorname{ad}^* = -\operatorname{ad}^T$ (the library's `coad`), the form that
    appears in (2.10) and in Theorem 2.2 (a).

    **Returns:**

    The covector $\mathbf C(X, Y)$, shape `(6,)`.
    """
    return lie.coad(X) @ (I_r @ Y) + lie.coad(Y) @ (I_r @ X) + I_r @ lie.bracket(X, Y)


def _translations(dtype):
    return jnp.eye(6, dtype=dtype)[3:]


def _worst_of_each(*groups):
    """The largest absolute entry of each group of arrays, stacked."""
    largest = [jnp.stack([jnp.max(jnp.abs(x), initial=0.0) for x in group]) for group in groups]
    return jnp.stack([jnp.max(x) for x in largest])


class GalileanConditions(eqx.Module):
    r"""The three residual tensors of Theorem 2.2 at one shape (seed 004, §2).

    Indices: $U_i$ ($i < 3$) runs over the translations $\mathfrak t$, $X_j$ over the twists
    (angular first), $\delta q_k$ over the shape coordinates; all three sets are bases, so a
    zero tensor is the condition for every $U$, $X$, $\delta q$.

    - `objectivity[i, j]` $= \mathbf C(s)(U_i, X_j)$: (a), the objectivity of the inertial
      forces of the frozen system.
    - `horizontal_derivative[k, i, j]` $= \nabla\mathbf J(s)(\Gamma(s, e_k))(U_i, X_j)$: (b), the
      derivative along the horizontal lift of $e_k$, by autodiff.
    - `curvature_coupling[i, j, k]` $= \mathbf J(s)(U_i, \Omega(e_j, e_k))$: (c), the
      translations against the curvature values $\mathfrak K(s)$.
    """

    objectivity: Float[Array, "3 6 6"]
    horizontal_derivative: Float[Array, "d 3 6"]
    curvature_coupling: Float[Array, "3 d d"]

    @property
    def residuals(self) -> Float[Array, "3"]:
        """The largest entry of (a), (b), (c), in that order."""
        return _worst_of_each(
            (self.objectivity,), (self.horizontal_derivative,), (self.curvature_coupling,)
        )


def _conditions(first: _FirstOrder) -> GalileanConditions:
    I_r = first.I_r
    U = _translations(I_r.dtype)
    X = jnp.eye(6, dtype=I_r.dtype)
    C = jax.vmap(jax.vmap(lambda u, x: inertial_coupling(I_r, u, x), (None, 0)), (0, None))(U, X)
    Omega = curvature_from_connection(first.A, first.dA)
    return GalileanConditions(
        objectivity=C,
        horizontal_derivative=jnp.swapaxes(first.dI[:, :, 3:], 1, 2),
        curvature_coupling=jnp.tensordot(I_r[3:], Omega, 1),
    )


def galilean_conditions(system: AbstractSystem, q: Float[Array, " d"]) -> GalileanConditions:
    r"""The residuals of Theorem 2.2 (seed 004) at the shape $q$, relative to the metric's size.

    For all translations $U\in\mathfrak t$: (a) $\mathbf C(s)(U, X) = 0$ for all $X$;
    (b) $\nabla\mathbf J(s)(U, X) = 0$ along horizontal directions; (c) $\mathbf J(s)(U, X) = 0$
    for $X$ in the span $\mathfrak K(s)$ of the curvature values. Together they are necessary
    and sufficient for (2.6) to be the same in every Galilean frame. The residuals are
    computed in the metric's own units (module docstring), so entries of order one mean a
    violation as large as the metric itself.

    **Arguments:**

    - `system`: any system.
    - `q`: shape, `(d,)`. jit and vmap over `q` freely.

    **Returns:**

    A `GalileanConditions`; `.residuals` gives the worst entry of (a), (b), (c).
    """
    return _conditions(_first_order(_unit_free_chart(system, q), system.shape_dim, q.dtype))


class RigidStructure(eqx.Module):
    r"""Theorem 2.3's data at one shape: the frozen system is a rigid body of mass `mass`.

    **Fields:**

    - `mass`, `centre`, `rotational_inertia`: $m$, $c_s$ (section frame) and $l_s$ (about
      $c_s$), read off the locked inertia, in the system's units.
    - `form_residual`: $I_r$ minus the rigid form $J(X,Y) = m\,X(c)\cdot Y(c) + l(\omega_X)\cdot
      \omega_Y$ (property 1, equivalent to (a) by Lemma 1), unit-free, `(6, 6)`.
    - `mass_variation[k]`: $\partial m / \partial q_k$, relative (Lemma 2: $m$ is constant).
    - `centre_motion[k]`: the velocity of $c_s$ along the horizontal lift of $e_k$ (property
      2), in units of the system's length, `(d, 3)`.
    - `curvature_at_centre[:, j, k]`: $\Omega(e_j, e_k)(c_s) = v + \omega\times c_s$, the part of
      a curvature value outside $\mathfrak c_s$ (property 3), unit-free, `(3, d, d)`.
    """

    mass: Float[Array, ""]
    centre: Float[Array, "3"]
    rotational_inertia: Float[Array, "3 3"]
    form_residual: Float[Array, "6 6"]
    mass_variation: Float[Array, " d"]
    centre_motion: Float[Array, "d 3"]
    curvature_at_centre: Float[Array, "3 d d"]

    @property
    def residuals(self) -> Float[Array, "3"]:
        """The worst entry of properties 1, 2 (mass variation and centre motion) and 3."""
        return _worst_of_each(
            (self.form_residual,),
            (self.mass_variation, self.centre_motion),
            (self.curvature_at_centre,),
        )


def rigid_structure(system: AbstractSystem, q: Float[Array, " d"]) -> RigidStructure:
    r"""Theorem 2.3's data and residuals at the shape $q$ (seed 004, Lemmas 1–2, Theorem 2.3).

    The conditions of Theorem 2.2 hold iff 1. $\mathbf J(s)(X, Y) = m\,X(c_s)\cdot Y(c_s) +
    l_s(\omega_X)\cdot\omega_Y$ with a constant $m > 0$; 2. $dc(\mathbf v) = 0$ for horizontal
    $\mathbf v$ (the centre of mass does not move when the shape changes at zero momentum);
    3. $\mathfrak K(s)\subset\mathfrak c_s$ (curvature values are rotations about $c_s$).

    **Arguments:**

    - `system`: any system; `q`: shape, `(d,)`.

    **Returns:**

    A `RigidStructure`; `.residuals` gives the worst entry of properties 1, 2, 3.
    """
    m, c, l = mass_and_centre(system.metric(q)[:6, :6])
    return _rigid_structure(
        m, c, l, _first_order(_unit_free_chart(system, q), system.shape_dim, q.dtype)
    )


def _rigid_structure(m, c, l, first: _FirstOrder) -> RigidStructure:
    m_, c_, l_ = mass_and_centre(first.I_r)
    dm, dc, _ = jax.vmap(lambda dI: jax.jvp(mass_and_centre, (first.I_r,), (dI,))[1])(first.dI)
    Omega = curvature_from_connection(first.A, first.dA)
    angular, linear = Omega[:3], Omega[3:]
    return RigidStructure(
        mass=m,
        centre=c,
        rotational_inertia=l,
        form_residual=first.I_r - spatial_inertia(m_, c_, l_),
        mass_variation=dm / m_,
        centre_motion=dc,
        curvature_at_centre=linear + jnp.cross(angular, c_[:, None, None], axis=0),
    )


def boost_terms(system: AbstractSystem, g, q, U, qdot, velocity):
    r"""The frame terms that a Galilean boost adds to (2.9)–(2.10), as accelerations.

    In a frame $\mathcal R'$ translating with constant velocity $u$ ($\mathbf U' = (0, u)$), the
    true equations differ from (2.6) written in $\mathcal R'$ by
    $\mathbf C(\mathbf U', \mathbf W) + \operatorname{ad}^*_{\mathbf U'}\mathbf I(\mathbf U') +
    \nabla_x\mathbf I(\dot x)(\mathbf U')$ in (2.10) and by $-\nabla_x\mathbf K(\cdot)(\mathbf U')
    - \nabla_x\mathbf J(\cdot)(\mathbf U', \mathbf W) + \mathbf J(\mathbf U', \Omega(\dot x, \cdot))$
    in (2.9) (seed 004). With the block-diagonal mass matrix $\operatorname{diag}(I_r,
    \mathcal J_{\text{def}})$ they change the accelerations by the amounts returned here; all
    vanish for every state iff Theorem 2.2's conditions hold. They are linear plus
    quadratic in $u$.

    **Arguments:**

    - `system`: any system; `g`: the section pose in $\mathcal R'$; `q`, `qdot`: shape and
      its velocity; `U`: the locked velocity in $\mathcal R'$ (section axes).
    - `velocity`: $u$, the boost velocity in the Galilean frame, `(3,)`.

    **Returns:**

    `(dU, dqddot)`: the change of $\dot U$ (section axes, `(6,)`) and of $\ddot q$ (`(d,)`) that the
    boost causes, in the system's units.
    """
    d = system.shape_dim
    chart = _physical_chart(system, q)
    first = _first_order(chart, d, q.dtype)
    I_r, A = first.I_r, first.A
    conditions = _conditions(first)
    u = g[:3, :3].T @ velocity
    U_boost = jnp.concatenate([jnp.zeros(3, u.dtype), u])
    inertia_derivative = jnp.tensordot(conditions.horizontal_derivative, u, ((1,), (0,)))  # (d, 6)
    group = inertial_coupling(I_r, U_boost, U + 0.5 * U_boost) + qdot @ inertia_derivative
    dU = -jnp.linalg.solve(I_r, group)
    if not d:
        return dU, jnp.zeros(0, q.dtype)
    G = chart(jnp.zeros(d, q.dtype))
    J_def = G[6:, 6:] - G[:6, 6:].T @ A
    curvature = jnp.tensordot(u, conditions.curvature_coupling, 1)  # J(U', Ω(e_j, e_k))
    shape = inertia_derivative @ (U + 0.5 * U_boost) - qdot @ curvature
    return dU, jnp.linalg.solve(J_def, shape)


def invariance_residuals(system: AbstractSystem, q):
    """The residuals of Theorem 2.2 and of Theorem 2.3's properties, from one expansion of the metric."""
    first = _first_order(_unit_free_chart(system, q), system.shape_dim, q.dtype)
    m, c, l = mass_and_centre(first.I_r)
    return _conditions(first).residuals, _rigid_structure(m, c, l, first).residuals
