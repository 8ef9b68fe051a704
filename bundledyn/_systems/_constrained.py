r"""Holonomic constraints among shape coordinates, solved for the dependent ones (seed 001, §54).

Constraints $f(q) = 0$ that give some shape coordinates as functions of the others,
$q = \Phi(p)$, explicitly (`JointCoupling`) or by Newton's method (`ImplicitConstraints`:
coordinate partitioning), are eliminated by taking the others, $p$, as the shape
coordinates: the configurations that satisfy them are exactly the $\Phi(p)$. The system on $p$ has the
metric pulled back by $T = \operatorname{diag}(I_6, \partial\Phi/\partial p)$,
$G_p(p) = T^T G(\Phi(p))\,T$, since $[\xi; \dot q] = T\,[\xi; \dot p]$; the constraints
are ideal (their reactions do no work on motions that keep them), so (2.6)–(2.7) for $G_p$
are the constrained motion, and every mode, solver and adjoint integrates it as any system.
"""

import abc
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._implicit import implicit_root
from ._base import AbstractSystem, autodiff_metric_jet

__all__ = [
    "AbstractHolonomicConstraints",
    "ConstrainedSystem",
    "ImplicitConstraints",
    "JointCoupling",
]

# The dependent coordinates are continued from the reference's along the straight line to
# the free coordinates asked for, in stages that move no free coordinate by more than
# `_STAGE_LENGTH`, each of `_NEWTON_STEPS` Newton iterations (a stage starts within the
# basin of the last one's root, so quadratic convergence needs few), then polished by as
# many more. Near the reference that is one stage: the cost grows with the distance only.
_STAGE_LENGTH = 0.5
_NEWTON_STEPS = 4


def _reference_or_zeros(shape_dim, reference):
    return jnp.zeros(shape_dim) if reference is None else jnp.asarray(reference, float)


def _check_reference(owner, reference, shape_dim):
    if reference.shape != (shape_dim,):
        raise ValueError(
            f"`{owner}.reference` must have shape ({shape_dim},), got {reference.shape}."
        )


class AbstractHolonomicConstraints(eqx.Module):
    r"""Holonomic constraints $f(q) = 0$ among $d$ shape coordinates, solved as $q = \Phi(p)$
    for the free coordinates $p$ (seed 001, §54).

    Subclasses give `shape_dim`, `dependent` (the indices of the coordinates $\Phi$ sets),
    $\Phi$ (`__call__`) and $f$ (`residual`); $\Phi$ must be differentiable to second order
    (the metric's jet differentiates it twice).
    """

    shape_dim: eqx.AbstractVar[int]
    dependent: eqx.AbstractVar[tuple[int, ...]]

    @abc.abstractmethod
    def __call__(self, p: Float[Array, " m"]) -> Float[Array, " d"]:
        r"""$q = \Phi(p)$: the free coordinates `p` and the dependent ones they set."""

    @abc.abstractmethod
    def residual(self, q: Float[Array, " d"]) -> Float[Array, " r"]:
        r"""$f(q)$, zero on the constraints."""

    @property
    def free(self) -> tuple[int, ...]:
        """The indices of the coordinates the constraints leave free: those of $p$, in order
        (static)."""
        return tuple(k for k in range(self.shape_dim) if k not in self.dependent)

    def free_coordinates(self, q: Float[Array, " d"]) -> Float[Array, " m"]:
        """$p$: the free coordinates of a full shape `q`."""
        return q[np.asarray(self.free, dtype=int)]

    def _assembled(self, p, dependent_values):
        """The full shape with `p` at the free indices and `dependent_values` at the others."""
        q = jnp.zeros(self.shape_dim, p.dtype).at[np.asarray(self.free, dtype=int)].set(p)
        if not self.dependent:
            return q
        return q.at[np.asarray(self.dependent, dtype=int)].set(dependent_values)


class JointCoupling(AbstractHolonomicConstraints):
    r"""Shape coordinates coupled by polynomials of others, as MuJoCo's joint equalities:
    $q_j - \bar q_j = \sum_{k=0}^{4} a_{jk}\,(q_i - \bar q_i)^k$ (seed 001, §54: holonomic
    constraints solved for the dependent coordinates).

    **Arguments:**

    - `shape_dim`: $d$, the number of shape coordinates $q$ (static).
    - `couplings`: a sequence of `(dependent, independent, coefficients)`: the index $j$ of
      the coordinate it sets, the index $i$ of the coordinate it follows (`None`: $q_j$ is
      held at $\bar q_j + a_{j0}$), and $(a_0, \dots, a_4)$ (fewer are padded with zeros).
      An independent coordinate must not itself be set by a coupling.
    - `reference`: $\bar q$, shape `(d,)`; default zeros (MuJoCo's `qpos0`).
    """

    shape_dim: int = eqx.field(static=True)
    dependent: tuple[int, ...] = eqx.field(static=True)
    independent: tuple[int | None, ...] = eqx.field(static=True)
    coefficients: Float[Array, "r 5"]
    reference: Float[Array, " d"]

    def __init__(self, shape_dim, couplings, reference=None):
        self.shape_dim = int(shape_dim)
        couplings = tuple(couplings)
        self.dependent = tuple(int(j) for j, _, _ in couplings)
        self.independent = tuple(None if i is None else int(i) for _, i, _ in couplings)
        rows = []
        for _, _, a in couplings:
            a = np.asarray(a, dtype=float).reshape(-1)
            if a.size > 5:
                raise ValueError(
                    f"`JointCoupling` takes at most 5 coefficients (degree 4), got {a.size}."
                )
            rows.append(np.pad(a, (0, 5 - a.size)))
        self.coefficients = jnp.asarray(np.reshape(rows, (len(rows), 5)), dtype=float)
        self.reference = _reference_or_zeros(self.shape_dim, reference)

    def __check_init__(self):
        d = self.shape_dim
        _check_reference("JointCoupling", self.reference, d)
        named = [j for j in self.dependent] + [i for i in self.independent if i is not None]
        if any(not 0 <= k < d for k in named):
            raise ValueError(f"`JointCoupling` indices must lie in [0, {d}), got {named}.")
        if len(set(self.dependent)) != len(self.dependent):
            raise ValueError("`JointCoupling` sets each dependent coordinate once.")
        followed = set(self.dependent) & {i for i in self.independent if i is not None}
        if followed:
            raise ValueError(
                f"`JointCoupling`: coordinates {sorted(followed)} are both set by a coupling "
                "and followed by one; couple each to a free coordinate instead."
            )

    def _set_values(self, q):
        """$\\bar q_j + \\sum_k a_{jk}(q_i - \\bar q_i)^k$ for every coupling, shape `(r,)`."""
        values = []
        for row, i in enumerate(self.independent):
            x = jnp.zeros((), q.dtype) if i is None else q[i] - self.reference[i]
            values.append(jnp.polyval(self.coefficients[row, ::-1], x))
        ref = self.reference[np.asarray(self.dependent, dtype=int)]
        return ref + jnp.stack(values) if values else ref

    def __call__(self, p: Float[Array, " m"]) -> Float[Array, " d"]:
        r"""$q = \Phi(p)$: the free coordinates `p` and the coupled ones they set."""
        followed = self._assembled(p, jnp.zeros(len(self.dependent), p.dtype))
        return self._assembled(p, self._set_values(followed))

    def residual(self, q: Float[Array, " d"]) -> Float[Array, " r"]:
        r"""$f(q)$: each coupled coordinate minus the value its coupling sets; zero on the
        constraints."""
        return q[np.asarray(self.dependent, dtype=int)] - self._set_values(q)


class ImplicitConstraints(AbstractHolonomicConstraints):
    r"""Holonomic constraints given implicitly, $f(q) = 0$, solved for the dependent shape
    coordinates by Newton's method (seed 001, §54; coordinate partitioning).

    For the free coordinates $p$, the dependent ones $s$ solve $f(p, s) = 0$, $r$ equations
    in $r$ unknowns, by Newton's method continued from `reference` $(p_0, s_0)$ along the
    straight line from $p_0$ to $p$ (in stages of at most 0.5 in each free coordinate): the
    root followed is the one on the
    reference's branch where $f = 0$ has several (a closed linkage's assembly modes), as
    long as that line crosses no point where $\partial f/\partial s$ is singular. A solve
    that does not reach $|f| \le 10^{-10}(1 + |q|)$ raises (`equinox.error_if`). The derivatives of
    every order, also in $f$'s own parameters, are the implicit function's,
    $\partial s = -(\partial f/\partial s)^{-1}(\partial f/\partial p\,\partial p + \partial_\theta f\,\partial\theta)$,
    not Newton's iterations differentiated.

    ```python
    def closure(q):  # the loop's last link ends at the base's pivot
        return (four_bar.body_poses(q)[3] @ tip)[:2] - pivot
    loop = bd.ConstrainedSystem(four_bar, bd.ImplicitConstraints(3, closure, dependent=(1, 2)))
    ```

    **Arguments:**

    - `shape_dim`: $d$, the number of shape coordinates $q$ (static).
    - `function`: $f(q)$, shape `(d,) -> (r,)` with $r$ = `len(dependent)`; an
      `equinox.Module` whose array fields are its parameters to differentiate, or any
      function.
    - `dependent`: the indices of the $r$ coordinates $s$ solved for (static).
    - `reference`: a configuration on the constraints, shape `(d,)`, from which Newton's
      method is continued; default zeros.
    """

    shape_dim: int = eqx.field(static=True)
    function: Callable[[Float[Array, " d"]], Float[Array, " r"]]
    dependent: tuple[int, ...] = eqx.field(static=True)
    reference: Float[Array, " d"]

    def __init__(self, shape_dim, function, dependent, reference=None):
        self.shape_dim = int(shape_dim)
        self.function = function
        self.dependent = tuple(int(j) for j in dependent)
        self.reference = _reference_or_zeros(self.shape_dim, reference)

    def __check_init__(self):
        d = self.shape_dim
        _check_reference("ImplicitConstraints", self.reference, d)
        if not self.dependent or any(not 0 <= j < d for j in self.dependent):
            raise ValueError(
                f"`ImplicitConstraints.dependent` must name coordinates in [0, {d}), got "
                f"{self.dependent}."
            )
        if len(set(self.dependent)) != len(self.dependent):
            raise ValueError("`ImplicitConstraints.dependent` names each coordinate once.")
        if not callable(self.function):
            raise ValueError("`ImplicitConstraints.function` must be a function f(q).")

    def residual(self, q):
        r"""$f(q)$, checked to have one equation per dependent coordinate."""
        f = jnp.asarray(self.function(q))
        if f.shape != (len(self.dependent),):
            raise ValueError(
                f"`ImplicitConstraints.function` must return {len(self.dependent)} values, one "
                f"per dependent coordinate; got shape {f.shape}."
            )
        return f

    def __call__(self, p):
        r"""$q = \Phi(p)$: `p` and the dependent coordinates Newton's method solves for."""
        # A closure over traced values (a parameter being differentiated) becomes a module
        # holding them as leaves, so that they are differentiated, not taken as static.
        example = self._assembled(p, jnp.zeros(len(self.dependent), p.dtype))
        function = eqx.filter_closure_convert(self.function, example)
        constraints = ImplicitConstraints(self.shape_dim, function, self.dependent, self.reference)
        s = implicit_root((constraints, p), residual=_on_the_constraints, solve=_continued_newton)
        return self._assembled(p, s)


def _on_the_constraints(inputs, s):
    constraints, p = inputs
    return constraints.residual(constraints._assembled(p, s))


def _continued_newton(inputs):
    constraints, p = inputs
    reference = constraints.reference.astype(p.dtype)
    p0 = constraints.free_coordinates(reference)

    def solved(target, s):
        f = lambda s: _on_the_constraints((constraints, target), s)
        newton = lambda _, s: s - jnp.linalg.solve(jax.jacfwd(f)(s), f(s))
        return jax.lax.fori_loop(0, _NEWTON_STEPS, newton, s)

    # A while loop, not differentiated: the derivatives are the implicit function's.
    stages = jnp.maximum(jnp.ceil(jnp.max(jnp.abs(p - p0)) / _STAGE_LENGTH), 1.0)

    def stage(carry):
        k, s = carry
        return k + 1.0, solved(p0 + (k + 1.0) / stages * (p - p0), s)

    start = reference[np.asarray(constraints.dependent, dtype=int)]
    _, s = jax.lax.while_loop(
        lambda carry: carry[0] < stages, stage, (jnp.zeros_like(stages), start)
    )
    s = solved(p, s)
    size = 1.0 + jnp.sqrt(jnp.sum(p**2) + jnp.sum(s**2))
    return eqx.error_if(
        s,
        ~(jnp.max(jnp.abs(_on_the_constraints(inputs, s))) <= 1e-10 * size),
        "ImplicitConstraints: Newton's method did not solve f(q) = 0 for the dependent "
        "coordinates here: the configuration left the basin of the reference's branch, or "
        "df/ds is singular. Give a `reference` nearer this motion, or other dependent "
        "coordinates.",
    )


class ConstrainedSystem(AbstractSystem):
    r"""A system whose shape coordinates are tied by holonomic constraints solved as
    $q = \Phi(p)$: the same system on the free coordinates $p$ (seed 001, §54).

    Its metric is $G_p(p) = T^T G(\Phi(p))\,T$, $T = \operatorname{diag}(I_6,
    \partial\Phi/\partial p)$, and its jet comes by forward-mode autodiff of it; the
    locked inertia is the system's, so gravity and the section frame are unchanged. States,
    trajectories and effects on the shape are in $p$; `constraints(p)` gives the full $q$.

    ```python
    gripper = bd.ConstrainedSystem(arm, bd.JointCoupling(arm.shape_dim, [(5, 4, (0.0, -1.0))]))
    ```

    **Arguments:**

    - `system`: the unconstrained system, with $d$ shape coordinates.
    - `constraints`: an `AbstractHolonomicConstraints` of $d$ coordinates: a
      `JointCoupling` (explicit) or `ImplicitConstraints` (solved by Newton's method).
    """

    system: AbstractSystem
    constraints: AbstractHolonomicConstraints

    def __check_init__(self):
        if not isinstance(self.system, AbstractSystem):
            raise ValueError(
                "`ConstrainedSystem.system` must be an AbstractSystem, got "
                f"{type(self.system).__name__}."
            )
        if not isinstance(self.constraints, AbstractHolonomicConstraints):
            raise ValueError(
                "`ConstrainedSystem.constraints` must be a `JointCoupling` or "
                f"`ImplicitConstraints`, got {type(self.constraints).__name__}."
            )
        if self.constraints.shape_dim != self.system.shape_dim:
            raise ValueError(
                f"`ConstrainedSystem`: the coupling is of {self.constraints.shape_dim} shape "
                f"coordinates, the system has {self.system.shape_dim}."
            )

    @property
    def shape_dim(self) -> int:
        return len(self.constraints.free)

    def metric(self, q):
        full = self.constraints(q)
        d = self.system.shape_dim
        m = self.shape_dim
        J = jax.jacfwd(self.constraints)(q)
        T = jnp.block(
            [
                [jnp.eye(6, dtype=q.dtype), jnp.zeros((6, m), q.dtype)],
                [jnp.zeros((d, 6), q.dtype), J],
            ]
        )
        return T.T @ self.system.metric(full) @ T

    def metric_jet(self, q):
        return autodiff_metric_jet(self, q)

    def constraint_residual(self, q):
        r"""$f(\Phi(p))$ at the free coordinates `q` $= p$: zero to Newton's tolerance
        ($10^{-10}(1 + |q|)$, `ImplicitConstraints`) or to rounding (`JointCoupling`)."""
        return self.constraints.residual(self.constraints(q))

    def checked(self) -> "ConstrainedSystem":
        """The system with its unconstrained system's run-time checks."""
        return ConstrainedSystem(self.system.checked(), self.constraints)
