"""Checks of the systems' parameters: at construction on concrete values, and at run time.

The construction checks raise `ValueError` with the fix and skip traced values; their
run-time forms (`checked_*`) attach `equinox.error_if` to values that may be traced. The
checks of any value (`concrete`, `check_shape`) are the package's, in `_validation.py`.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._validation import concrete, rounding_tolerance


def check_mass(name: str, mass) -> None:
    """Raise `ValueError` unless `mass` is finite and positive."""
    m = concrete(mass)
    if m is not None and not (np.all(np.isfinite(m)) and np.all(m > 0)):
        raise ValueError(f"`{name}` must be finite and positive, got {m}.")


def check_inertia(name: str, inertia) -> None:
    r"""Raise `ValueError` unless `inertia` is a physical rotational inertia (3×3).

    Physical means symmetric, positive definite and obeying the triangle inequality
    of the principal moments, $I_1 + I_2 \ge I_3$ (any ordering): the inertia of a
    real mass distribution.
    """
    J = concrete(inertia)
    if J is None:
        return
    scale = max(float(np.max(np.abs(J))), 1e-300)
    tolerance = rounding_tolerance(J, 1e-9)
    if not np.allclose(J, J.T, rtol=0.0, atol=tolerance * scale):
        raise ValueError(f"`{name}` must be symmetric, got\n{J}.")
    moments = np.linalg.eigvalsh(0.5 * (J + J.T))
    if not moments[0] > 0:
        raise ValueError(
            f"`{name}` must be positive definite; its principal moments are {moments}."
        )
    if moments[0] + moments[1] < moments[2] * (1 - tolerance):
        raise ValueError(
            f"`{name}` breaks the triangle inequality of principal moments "
            f"({moments[0]:g} + {moments[1]:g} < {moments[2]:g}): no mass distribution has it."
        )


def check_spd(name: str, matrix) -> None:
    """Raise `ValueError` unless `matrix` is symmetric positive definite."""
    S = concrete(matrix)
    if S is None:
        return
    scale = max(float(np.max(np.abs(S))), 1e-300)
    if not np.allclose(S, S.T, rtol=0.0, atol=rounding_tolerance(S, 1e-9) * scale) or not (
        np.linalg.eigvalsh(0.5 * (S + S.T))[0] > 0
    ):
        raise ValueError(f"`{name}` must be symmetric positive definite, got\n{S}.")


# Run-time forms of the checks above: `equinox.error_if` on traced values, for `checked`.


def checked_mass(name: str, mass):
    """`mass` with a run-time check that every entry is finite and positive."""
    mass = jnp.asarray(mass)
    bad = ~jnp.all(jnp.isfinite(mass) & (mass > 0))
    return eqx.error_if(mass, bad, f"`{name}` must be finite and positive.")


def _symmetric_part_moments(matrix):
    """The eigenvalues of the symmetric part, and whether `matrix` is symmetric to 1e-9."""
    scale = jnp.maximum(jnp.max(jnp.abs(matrix)), jnp.finfo(matrix.dtype).tiny)
    asymmetry = jnp.max(jnp.abs(matrix - jnp.swapaxes(matrix, -1, -2)))
    symmetric = 0.5 * (matrix + jnp.swapaxes(matrix, -1, -2))
    return jnp.linalg.eigvalsh(symmetric), asymmetry <= 1e-9 * scale


def checked_inertia(name: str, inertia):
    """`inertia` (3×3, or stacked) with run-time checks: symmetric, positive definite,
    triangle inequality of the principal moments (see `check_inertia`)."""
    inertia = jnp.asarray(inertia)
    moments, symmetric = _symmetric_part_moments(inertia)
    inertia = eqx.error_if(inertia, ~symmetric, f"`{name}` must be symmetric.")
    inertia = eqx.error_if(
        inertia, ~jnp.all(moments[..., 0] > 0), f"`{name}` must be positive definite."
    )
    triangle = moments[..., 0] + moments[..., 1] >= moments[..., 2] * (1 - 1e-9)
    return eqx.error_if(
        inertia,
        ~jnp.all(triangle),
        f"`{name}` breaks the triangle inequality of principal moments: no mass distribution "
        "has it.",
    )


def checked_spd(name: str, matrix):
    """`matrix` with a run-time check that it is symmetric positive definite."""
    matrix = jnp.asarray(matrix)
    moments, symmetric = _symmetric_part_moments(matrix)
    bad = ~symmetric | ~jnp.all(moments[..., 0] > 0)
    return eqx.error_if(matrix, bad, f"`{name}` must be symmetric positive definite.")
