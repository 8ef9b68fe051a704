r"""The base parameters: the combinations of inertial parameters that the data determine.

A tree's dynamics is linear in each body's ten standard inertial parameters, in Khalil and
Dombre's notation `M` (mass), `MX`, `MY`, `MZ` (first moments $mc$) and `XX`, `XY`, `XZ`,
`YY`, `YZ`, `ZZ` (inertia about the body frame's origin, in body axes), all linear in the
pseudo-inertia $P = [\Sigma, mc; mc^T, m]$ ($XX = \Sigma_{yy} + \Sigma_{zz}$,
$XY = -\Sigma_{xy}$, …), and in the joint constants. Where the data cannot see a direction
(a regrouping, or one too weakly excited: the blind directions of `analyse`), no single
parameter along it is determined; the linear combinations that no blind direction moves
are (the base parameters of Gautier & Khalil 1990; Gautier 1991). Here they are the
reduced row echelon form of that space, the parameters ordered root to leaf, so that a
child's parameter is regrouped into its parent's: `arm.M + hand.M` is the mass the arm and
the hand carry together. Each has its estimate and standard error by the delta method.
"""

import functools
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._parameters import Parameters

__all__ = [
    "BaseParameter",
    "base_parameters",
    "parameter_names",
    "standard_parameter_names",
    "standard_parameters",
    "value_and_jacobian",
]

_STANDARD = ("XX", "XY", "XZ", "YY", "YZ", "ZZ", "MX", "MY", "MZ", "M")
_PIVOT = 1e-6  # a column with less left than this (of the largest) depends on earlier ones
_TERM = 1e-6  # coefficients below this, relative to their parameters' sizes, are rounding


class BaseParameter(NamedTuple):
    """A combination of standard parameters that the data determine.

    **Fields:** `name` (the combination, e.g. `arm.ZZ + 0.09 hand.M`), `value`, `std`
    (its standard error), `coefficients` (over `standard_parameter_names`).
    """

    name: str
    value: float
    std: float
    coefficients: np.ndarray


def standard_parameters(parameters: Parameters, theta):
    """The free bodies' standard parameters (module docstring), body after body, then the
    free joint constants, as one vector."""
    P = parameters.pseudo_inertias(theta)
    sigma, first, mass = P[:, :3, :3], P[:, :3, 3], P[:, 3, 3]
    trace = jnp.trace(sigma, axis1=1, axis2=2)[:, None, None]
    inertia = trace * jnp.eye(3, dtype=P.dtype)[None] - sigma
    rows, columns = (0, 0, 0, 1, 1, 2), (0, 1, 2, 1, 2, 2)
    per_body = jnp.concatenate([inertia[:, rows, columns], first, mass[:, None]], axis=1)
    constants = [jnp.ravel(v) for v in parameters.joint_constant_values(theta).values()]
    return jnp.concatenate([per_body.reshape(-1), *constants])


def parameter_names(parameters: Parameters, quantities) -> list[str]:
    """`body.quantity` for each free body and each of `quantities`, then the free joint
    constants' names."""
    names = parameters.body_names
    labels = [f"{names[b]}.{q}" for b in parameters.bodies for q in quantities]
    for name, value in parameters.joint_constant_values(parameters.initial()).items():
        size = int(np.size(value))
        labels += [name] if size == 1 else [f"{name}[{k}]" for k in range(size)]
    return labels


def standard_parameter_names(parameters: Parameters) -> list[str]:
    """The names of `standard_parameters`' entries: `body.XX`, …, `body.M`, then the joint
    constants'."""
    return parameter_names(parameters, _STANDARD)


@eqx.filter_jit
def value_and_jacobian(function, parameters: Parameters, theta):
    r"""`function(parameters, theta)` and its Jacobian in $\theta$."""
    at = functools.partial(function, parameters)
    return at(theta), jax.jacfwd(at)(theta)


def _sizes(standard, num_bodies: int):
    """Each standard parameter's natural size: a body's mass $m$, $m r$ for its first
    moments and $m r^2$ for its inertia, $r^2 = \\operatorname{tr}\\Sigma / m$ (its radius
    of gyration about its frame's origin); a joint constant's own magnitude."""
    sizes = np.abs(standard).copy()
    for b in range(num_bodies):
        block = standard[10 * b : 10 * b + 10]
        mass = abs(block[9])
        radius2 = (block[0] + block[3] + block[5]) / (2 * mass)
        sizes[10 * b : 10 * b + 6] = mass * radius2
        sizes[10 * b + 6 : 10 * b + 9] = mass * np.sqrt(radius2)
        sizes[10 * b + 9] = mass
    return np.maximum(sizes, np.finfo(float).tiny)


def _reduced_row_echelon(rows):
    """The reduced row echelon form of `rows` (full row rank, entries of order one), taking
    pivots column by column: each row's first nonzero entry is 1 and its column is zero in
    the other rows. Only row operations: the rows span the same space."""
    rows = np.array(rows, dtype=float)
    pivots, done = [], 0
    for j in range(rows.shape[1]):
        if done == rows.shape[0]:
            break
        r = done + int(np.argmax(np.abs(rows[done:, j])))
        if abs(rows[r, j]) <= _PIVOT:
            continue
        rows[[done, r]] = rows[[r, done]]
        rows[done] /= rows[done, j]
        others = np.arange(rows.shape[0]) != done
        rows[others] -= np.outer(rows[others, j], rows[done])
        pivots.append(j)
        done += 1
    return rows, pivots


def _name(coefficients, pivot: int, names, sizes) -> str:
    terms = [names[pivot]]
    for j in np.flatnonzero(np.abs(coefficients) * sizes / sizes[pivot] > _TERM):
        if j != pivot:
            c = coefficients[j]
            terms.append(f"{'-' if c < 0 else '+'} {abs(c):.4g} {names[j]}")
    return " ".join(terms)


def base_parameters(parameters: Parameters, theta, blind, covariance) -> tuple[BaseParameter, ...]:
    r"""The base parameters at $\theta$ with their standard errors.

    **Arguments:**

    - `parameters`: the `Parameters`; `theta`: the solution.
    - `blind`: the blind directions of $\theta$, `(P, b)` (columns; any basis).
    - `covariance`: of $\theta$ on the determined subspace, `(P, P)`.

    **Returns:**

    A tuple of `BaseParameter`, one per dimension of the standard parameters' space that
    $\theta$ reaches and no blind direction moves.
    """
    standard, jacobian = (
        np.asarray(x) for x in value_and_jacobian(standard_parameters, parameters, theta)
    )
    sizes = _sizes(standard, len(parameters.bodies))
    # In scaled standard parameters: the directions θ moves them along, and the blind ones.
    reached = jacobian / sizes[:, None]
    left, singular, _ = np.linalg.svd(reached, full_matrices=False)
    left = left[:, singular > 1e-12 * singular[0]]
    moved = left.T @ (reached @ np.asarray(blind))
    if moved.size:
        u, s, _ = np.linalg.svd(moved, full_matrices=True)
        determined = left @ u[:, int(np.sum(s > 1e-9 * max(s[0], 1.0))) :]
    else:
        determined = left
    if determined.shape[1] == 0:
        return ()
    rows, pivots = _reduced_row_echelon(determined.T)
    names = standard_parameter_names(parameters)
    result = []
    for row, pivot in zip(rows, pivots, strict=True):
        coefficients = row * sizes[pivot] / sizes
        gradient = coefficients @ jacobian
        variance = max(float(gradient @ np.asarray(covariance) @ gradient), 0.0)
        result.append(
            BaseParameter(
                _name(coefficients, pivot, names, sizes),
                float(coefficients @ standard),
                float(np.sqrt(variance)),
                coefficients,
            )
        )
    return tuple(result)
