r"""What the data determines: the information on the parameters, and its blind directions.

At the solution, the weighted data residuals have Jacobian $J$ in the decision vector
$z = (\theta, s)$ and the continuity constraints $C$. Feasible changes are $\delta z = Ny$
($N$ a basis of the null space of $C$), with $A = JN$. The information on $\theta$ after the
window states are eliminated is the Schur complement

$$F_\theta = B^T(1 - QQ^T)B,\qquad B = AT^+,$$

with $T = N_{\theta\cdot}$ the map from $y$ to $\delta\theta$ and $Q$ an orthonormal basis
of the range of $A$ on the null space of $T$ (the state directions). In coordinates
scaled to each body's size, the eigenvectors of $F_\theta$ with small eigenvalues are the
combinations the data cannot determine: their standard deviation $\hat\sigma/\sqrt\lambda$
exceeds 1 (the size of the parameter itself), or $\lambda$ vanishes to rounding. Standard
errors of physical quantities (mass, centre of mass, inertia entries) follow by the delta
method on the determined subspace only; a quantity with a component along an undetermined
direction gets none. $\hat\sigma^2 = \chi^2/(R - \mathrm{rank})$ scales them, so misstated
noise levels do not make the intervals lie.
"""

import functools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._systems._pseudo_inertia import inertial_from_pseudo_inertia
from ._base_parameters import (
    BaseParameter,
    base_parameters,
    parameter_names,
    value_and_jacobian,
)
from ._parameters import Parameters
from ._regrouping import named_directions

__all__ = ["Estimate", "Identifiability", "analyse", "physical_quantities"]

_QUANTITIES = ("mass", "com_x", "com_y", "com_z", "I_xx", "I_yy", "I_zz", "I_xy", "I_xz", "I_yz")
_NUMERICAL_NULL = 1e-12  # eigenvalues below this fraction of the largest are zero
_ORTHOGONAL = 1e-6  # a quantity with less than this share along a blind direction is determined
_INSIDE = 1e-3  # a named direction this close to the blind subspace lies in it


class Estimate(NamedTuple):
    """A physical parameter with its standard error (`nan` when the data cannot determine it).

    **Fields:** `name` (body and quantity), `value`, `std`, `determined`.
    """

    name: str
    value: float
    std: float
    determined: bool


class Identifiability(NamedTuple):
    r"""What the data determines, from the information matrix at the solution.

    **Fields:** `singular_values` (of the scaled, state-eliminated weighted Jacobian,
    descending), `condition_number` (of the determined part), `undetermined` (a sentence
    per blind direction, in physical terms), `noise_scale` ($\hat\sigma$, 1 when the noise
    levels were right), `covariance` (of $\theta$ on the determined subspace),
    `estimates` (a tuple of `Estimate`: each body's physical parameters, most of them not
    determined alone), `base_parameters` (a tuple of `BaseParameter`: the combinations
    the data determine, with standard errors).
    """

    singular_values: np.ndarray
    condition_number: float
    undetermined: tuple[str, ...]
    noise_scale: float
    covariance: np.ndarray
    estimates: tuple[Estimate, ...]
    base_parameters: tuple[BaseParameter, ...]


def null_space(C):
    r"""An orthonormal basis of the null space of $C$ (from a QR factorization of $C^T$)."""
    Q, _ = jnp.linalg.qr(C.T, mode="complete")
    return Q[:, C.shape[0] :]


@functools.partial(jax.jit, static_argnames="num_parameters")
def theta_information(J, C, num_parameters: int):
    r"""$F_\theta$: the information on the first `num_parameters` entries of $z$ once the
    others (window states) are eliminated under the constraints $C\delta z = 0$."""
    n = J.shape[1]
    N = null_space(C) if C.shape[0] else jnp.eye(n, dtype=J.dtype)
    A, T = J @ N, N[:num_parameters]
    B = A @ jnp.linalg.pinv(T)
    if n == num_parameters:
        return B.T @ B
    T_null = null_space(T)
    Q, R = jnp.linalg.qr(A @ T_null)
    rank = jnp.abs(jnp.diagonal(R)) > 1e-12 * jnp.max(jnp.abs(jnp.diagonal(R)))
    Q = Q * rank.astype(Q.dtype)[None, :]
    projected = B - Q @ (Q.T @ B)
    return projected.T @ projected


def physical_quantities(parameters: Parameters, theta):
    """The free bodies' mass, centre of mass and inertia entries (about the centre of mass,
    in body axes), then the free joint constants, as one vector, and their names."""
    m, c, J = inertial_from_pseudo_inertia(parameters.pseudo_inertias(theta))
    per_body = jnp.concatenate(
        [m[:, None], c, J[:, (0, 1, 2, 0, 0, 1), (0, 1, 2, 1, 2, 2)]], axis=1
    ).reshape(-1)
    constants = [jnp.ravel(v) for v in parameters.joint_constant_values(theta).values()]
    return jnp.concatenate([per_body, *constants])


def _describe(direction, parameters: Parameters, value, gradients, names):
    r"""A blind direction of $\theta$ as the physical quantities that move most along it
    (relative to their size: a centre by the body's radius of gyration, an inertia entry
    by the trace), from the quantities' `value` and `gradients` in $\theta$."""
    change = gradients @ direction
    size = np.abs(value).copy()
    for b in range(len(parameters.bodies)):
        block = value[10 * b : 10 * b + 10]
        trace = np.sum(block[4:7])
        size[10 * b + 1 : 10 * b + 4] = np.sqrt(trace / (2 * block[0]))
        size[10 * b + 4 : 10 * b + 10] = trace
    relative = change / np.maximum(size, np.finfo(float).tiny)
    relative = relative / np.max(np.abs(relative))
    order = np.argsort(-np.abs(relative))
    terms = [f"{relative[i]:+.2f} {names[i]}" for i in order[:4] if abs(relative[i]) > 0.2]
    return "the combination " + " ".join(terms)


def _blind_directions(blind, scales, parameters: Parameters, theta, quantities, names):
    r"""The blind subspace (orthonormal columns, scaled coordinates) in words: the named
    directions it contains (`named_directions`), then what remains, by its largest
    physical components (`quantities`: their values and Jacobian at $\theta$). Also a basis
    of it made of those directions: the named ones exactly as built from the geometry
    (the eigenvectors hold them only to the information's rounding), then the rest."""
    found, inside = [], []
    for label, u in named_directions(parameters, theta).items():
        u = u / scales
        norm = np.linalg.norm(u)
        if norm > 0 and np.linalg.norm(u - blind @ (blind.T @ u)) < _INSIDE * norm:
            found.append(label)
            inside.append(u / norm)
    rest = blind
    if inside:
        U = np.stack(inside, axis=1)
        rest = blind - U @ np.linalg.lstsq(U, blind, rcond=None)[0]
    left, singular, _ = np.linalg.svd(rest, full_matrices=False)
    remainder = left[:, singular > _INSIDE] if rest.size else rest
    value, gradients = quantities
    found += [_describe(scales * v, parameters, value, gradients, names) for v in remainder.T]
    basis = np.concatenate([np.stack(inside, axis=1), remainder], axis=1) if inside else remainder
    return tuple(found), basis


def analyse(parameters: Parameters, theta, information, chi2: float, dof: int) -> Identifiability:
    r"""The identifiability report at $\theta$ from the information $F_\theta$ (see module).

    **Arguments:**

    - `parameters`: the `Parameters`; `theta`: the solution.
    - `information`: $F_\theta$, `(P, P)`.
    - `chi2`: the weighted residuals' sum of squares; `dof`: residuals minus parameters.

    **Returns:**

    An `Identifiability`.
    """
    S = parameters.scales(theta)
    F = np.asarray(information) * S[:, None] * S[None, :]
    eigenvalues, vectors = np.linalg.eigh(0.5 * (F + F.T))
    eigenvalues, vectors = eigenvalues[::-1], vectors[:, ::-1]
    largest = max(eigenvalues[0], np.finfo(float).tiny)
    sigma2 = chi2 / max(dof, 1)
    null = eigenvalues <= _NUMERICAL_NULL * largest
    blind = null | (sigma2 / np.where(null, 1.0, eigenvalues) > 1.0)
    determined = ~blind
    inverse = np.where(determined, 1.0 / np.where(determined, eigenvalues, 1.0), 0.0)
    covariance = S[:, None] * ((vectors * inverse) @ vectors.T) * sigma2 * S[None, :]
    names = parameter_names(parameters, _QUANTITIES)
    theta = jnp.asarray(theta)
    values, gradients = (
        np.asarray(x) for x in value_and_jacobian(physical_quantities, parameters, theta)
    )
    scaled = gradients * S[None, :]
    blind_vectors = vectors[:, blind]
    share = np.linalg.norm(scaled @ blind_vectors, axis=1) / np.maximum(
        np.linalg.norm(scaled, axis=1), np.finfo(float).tiny
    )
    stds = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", gradients, covariance, gradients), 0.0))
    estimates = tuple(
        Estimate(name, float(v), float(s) if ok else float("nan"), bool(ok))
        for name, v, s, ok in zip(names, values, stds, share <= _ORTHOGONAL, strict=True)
    )
    undetermined, blind_basis = _blind_directions(
        blind_vectors, S, parameters, theta, (values, gradients), names
    )
    kept = eigenvalues[determined]
    condition = float(np.sqrt(kept[0] / kept[-1])) if kept.size else float("inf")
    return Identifiability(
        np.sqrt(np.maximum(eigenvalues, 0.0)),
        condition,
        undetermined,
        float(np.sqrt(sigma2)),
        covariance,
        estimates,
        base_parameters(parameters, theta, S[:, None] * blind_basis, covariance),
    )
