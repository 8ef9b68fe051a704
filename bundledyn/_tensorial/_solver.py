r"""Runge–Kutta–Munthe-Kaas methods for tensor coordinates: unit vectors and rotations moved
by rotations only, so they stay on the sphere and on SO(3) to rounding error.

The state is $y = (X, V)$ (`TensorCoordinates`, `TensorVelocities`). Over a step from $y_0$ it is
written in the chart
$$q = q_0 + \delta q,\quad e_k = \exp(\tilde\theta_k)\,e_{k,0},\quad
Z_k = \exp(\tilde\vartheta_k)\,Z_{k,0},\quad V = V_0 + \delta V,$$
in which the motion obeys an ODE on a vector space: $\dot{\delta q} = \dot q$,
$\dot\theta_k = J_l^{-1}(\theta_k)\,(e_k\times\dot e_k)$,
$\dot\vartheta_k = J_l^{-1}(\vartheta_k)\,(\dot Z_kZ_k^T)^\vee$, $\dot{\delta V} = \dot V$
($J_l$ the left Jacobian of $\exp$ on SO(3): $\dot RR^T = (J_l(\theta)\dot\theta)^\wedge$ for
$R = \exp\tilde\theta$, `lie.so3_left_jacobian`). A classical tableau applied to it is an
RKMK method of the tableau's order (Munthe-Kaas 1999), the same construction as
`bundledyn.RKMK87` on SE(3), here on the product of spheres and rotation groups. Its
dense output is the tableau's continuous extension in the same chart.
"""

from typing import ClassVar

import jax
import jax.numpy as jnp
import jax.tree_util as jtu
from diffrax import (
    RESULTS,
    AbstractAdaptiveSolver,
    AbstractLocalInterpolation,
    AbstractSolver,
    AbstractTerm,
)
from jax.flatten_util import ravel_pytree
from jaxtyping import Array, PyTree

from .. import lie
from .._solver._tableau import LieButcherTableau, dopri5_tableau, dopri8_tableau, rk4_tableau
from ._coordinates import TensorCoordinates, angular_velocity, checked_state

__all__ = [
    "AbstractTensorialRKMK",
    "TensorialInterpolation",
    "TensorialRKMK4",
    "TensorialRKMK54",
    "TensorialRKMK87",
]


def _split_chart(X: TensorCoordinates, u):
    m, n, p = X.counts
    return (
        u[:m],
        u[m : m + 3 * n].reshape(n, 3),
        u[m + 3 * n : m + 3 * n + 3 * p].reshape(p, 3),
        u[m + 3 * n + 3 * p :],
    )


def _from_chart(y0, u):
    """The state at the chart point `u` of the step from `y0`."""
    X0, V0 = y0
    shift, axis_turns, turns, velocity_shift = _split_chart(X0, u)
    flat, unflatten = ravel_pytree(V0)
    X = TensorCoordinates(
        X0.scalars + shift,
        jnp.einsum("nij,nj->ni", lie.so3_exp(axis_turns), X0.unit_vectors),
        lie.so3_exp(turns) @ X0.rotations,
    )
    return X, unflatten(flat + velocity_shift)


def _chart_rate(u, y, field):
    """The rate of the chart point `u`, where the state is `y` and its rate `field`."""
    X, _ = y
    Xdot, Vdot = field
    _, axis_turns, turns, _ = _split_chart(X, u)
    axis_generators = jnp.cross(X.unit_vectors, Xdot.unit_vectors)  # Ω⊥: ė = Ω⊥ × e
    generators = angular_velocity(X.rotations, Xdot.rotations)  # ω: Ż = ω̃ Z
    apply = lambda turn, w: jnp.einsum("kij,kj->ki", lie.so3_left_jacobian_inv(turn), w)
    return jnp.concatenate(
        [
            Xdot.scalars,
            apply(axis_turns, axis_generators).ravel(),
            apply(turns, generators).ravel(),
            ravel_pytree(Vdot)[0],
        ]
    )


def _as_state_error(y1, u_error):
    """A chart increment as a state-shaped error: turns applied to e and Z as $\\tilde\\theta e$
    and $\\tilde\\vartheta Z$, so that a controller scales it as it scales the state."""
    X1, V1 = y1
    shift, axis_turns, turns, velocity_shift = _split_chart(X1, u_error)
    X = TensorCoordinates(
        shift, jnp.cross(axis_turns, X1.unit_vectors), lie.so3_hat(turns) @ X1.rotations
    )
    return X, ravel_pytree(V1)[1](velocity_shift)


class TensorialInterpolation(AbstractLocalInterpolation):
    r"""Dense output of a tensorial RKMK step: the chart polynomial $u(s) = \sum_m s^{m+1}C_m$
    mapped to the state, so unit vectors and rotations stay on their manifolds.

    **Arguments:**

    - `t0`, `t1`: the step's ends; `y0`: the state at `t0`; `coeffs`: $C$, shape
      `(degree, chart dimension)`.
    """

    t0: Array  # pyright: ignore[reportIncompatibleVariableOverride]
    t1: Array  # pyright: ignore[reportIncompatibleVariableOverride]
    y0: PyTree[Array]
    coeffs: Array

    def evaluate(self, t0, t1=None, left: bool = True) -> PyTree[Array]:
        """The state at `t0`, or, given `t1`, the difference of the states at `t1` and `t0`."""
        del left
        if t1 is not None:
            return jtu.tree_map(jnp.subtract, self.evaluate(t1), self.evaluate(t0))
        same = self.t0 == self.t1
        s = jnp.where(same, 0.0, t0 - self.t0) / jnp.where(same, 1.0, self.t1 - self.t0)
        powers = s ** jnp.arange(1, self.coeffs.shape[0] + 1, dtype=self.coeffs.dtype)
        return _from_chart(self.y0, powers @ self.coeffs)


class AbstractTensorialRKMK(AbstractSolver):
    r"""An explicit RKMK method for tensor coordinates, given by a Butcher tableau.

    Subclass it with a `LieButcherTableau` as the class attribute `tableau` and an `order`
    method (adding `diffrax.AbstractAdaptiveSolver` when the tableau has an error
    estimate). The state is `(X, V)`, `TensorCoordinates` and `TensorVelocities`; the term's field is
    $(\dot X, \dot V)$ (`TensorialTerm`), from which the turns of the unit vectors and
    rotations are read as $e\times\dot e$ and $(\dot ZZ^T)^\vee$.

    With an embedded pair the error estimate is the chart's, given the state's shape:
    $\tilde\theta e$ for a unit vector, $\tilde\vartheta Z$ for a rotation (angles, in
    the units of the state's entries), so `diffrax.PIDController` works with it. Valid
    while a step turns each axis and body by less than $2\pi$.
    """

    tableau: ClassVar[LieButcherTableau]
    term_structure: ClassVar = AbstractTerm
    interpolation_cls: ClassVar = TensorialInterpolation

    def init(self, terms, t0, t1, y0, args):
        checked_state(y0)
        return None

    def func(self, terms, t0, y0, args):
        return terms.vf(t0, y0, args)

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        tab = self.tableau
        X0, V0 = y0
        m, n, p = X0.counts
        dimension = m + 3 * n + 3 * p + ravel_pytree(V0)[0].shape[0]
        dtype = X0.rotations.dtype
        control = terms.contr(t0, t1)
        a = jnp.asarray(tab.a, dtype=dtype)
        times = t0 + jnp.asarray(tab.c_full, dtype=dtype) * (t1 - t0)

        def stage(increments, i):
            u = a[i] @ increments
            y = _from_chart(y0, u)
            increment = control * _chart_rate(u, y, terms.vf(times[i], y, args))
            return increments.at[i].set(increment), None

        start = jnp.zeros((tab.num_stages, dimension), dtype)
        increments, _ = jax.lax.scan(stage, start, jnp.arange(tab.num_stages))
        y1 = _from_chart(y0, jnp.asarray(tab.b_sol, dtype=dtype) @ increments)
        if tab.b_error is None:
            y_error = None
        else:
            u_error = jnp.asarray(tab.b_error, dtype=dtype) @ increments
            y_error = _as_state_error(y1, u_error)
        coeffs = jnp.asarray(tab.dense, dtype=dtype) @ increments
        dense_info = dict(y0=y0, coeffs=coeffs)
        return y1, y_error, dense_info, None, RESULTS.successful


class TensorialRKMK4(AbstractTensorialRKMK):
    """The classical fourth-order tableau, fixed steps (`diffrax.ConstantStepSize`); see
    `AbstractTensorialRKMK`."""

    tableau: ClassVar[LieButcherTableau] = rk4_tableau

    def order(self, terms):
        del terms
        return 4


class TensorialRKMK54(AbstractTensorialRKMK, AbstractAdaptiveSolver):
    """The Dormand–Prince 5(4) tableau, adaptive; for loose tolerances. See
    `AbstractTensorialRKMK`."""

    tableau: ClassVar[LieButcherTableau] = dopri5_tableau

    def order(self, terms):
        del terms
        return 5


class TensorialRKMK87(AbstractTensorialRKMK, AbstractAdaptiveSolver):
    """The Dormand–Prince 8(7) tableau, adaptive; for tight tolerances (its dense output is of
    fifth order between the steps, as `bundledyn.RKMK87`'s). See `AbstractTensorialRKMK`."""

    tableau: ClassVar[LieButcherTableau] = dopri8_tableau

    def order(self, terms):
        del terms
        return 8
