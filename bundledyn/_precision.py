"""Floating-point precision: float64 is opt-in, never switched on at import; tolerances that
the working precision cannot meet are refused or warned about, in the caller's line."""

import os
import sys
import warnings

import diffrax
import equinox
import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from ._validation import concrete, precision_floor

# Frames in these folders are the library's, not the user's: warnings skip past them.
LIBRARY_FOLDERS = tuple(
    os.path.dirname(path) + os.sep
    for path in (__file__, jax.__file__, equinox.__file__, diffrax.__file__)
    if path is not None
)


def enable_x64(enable: bool = True) -> None:
    """Switch JAX to float64 as the default working precision.

    bundledyn never flips this global flag on import; call this once, before building
    arrays, when rounding-level accuracy is wanted (the physics tests do).

    **Arguments:**

    - `enable`: `True` for float64 (the default), `False` to go back to float32.
    """
    jax.config.update("jax_enable_x64", enable)


def warn_in_callers_code(message: str, category: type[Warning] = UserWarning) -> None:
    """Warn with the location of the first caller outside bundledyn, JAX, equinox and diffrax.

    A fixed `stacklevel` would point into `equinox.filter_jit` or a JAX transformation when
    the warning is raised while tracing.
    """
    frame, level = sys._getframe(0), 1
    while frame is not None and frame.f_code.co_filename.startswith(LIBRARY_FOLDERS):
        frame, level = frame.f_back, level + 1
    warnings.warn(message, category, stacklevel=level)


def _advice(dtype) -> str:
    if jnp.finfo(dtype).bits < 64:
        return (
            "call `bundledyn.enable_x64()` before building arrays to compute in float64, "
            "or ask for a looser tolerance"
        )
    return "float64 is JAX's widest type: ask for rtol of 1e-14 or more"


def check_tolerances(rtol: ArrayLike, atol: ArrayLike, dtype) -> None:
    """Refuse tolerances no step size can meet in `dtype`; warn about ones at its rounding.

    A relative and absolute tolerance both below the rounding error $\\varepsilon$ of `dtype`
    cannot be met (an adaptive controller would shrink the step until `max_steps`), so they
    raise; both below $100\\varepsilon$ warn. Traced tolerances are the caller's choice.

    **Arguments:**

    - `rtol`, `atol`: the step-size controller's tolerances.
    - `dtype`: the floating dtype the solve runs in.

    **Raises:**

    `ValueError` for a negative tolerance, both zero, or both below $\\varepsilon$.
    """
    r, a = concrete(rtol), concrete(atol)
    if r is None or a is None:
        return
    r, a = float(np.max(r)), float(np.max(a))
    if min(r, a) < 0 or max(r, a) == 0:
        raise ValueError(
            f"tolerances must be non-negative and not both zero, got rtol={r:g}, atol={a:g}."
        )
    eps = float(jnp.finfo(dtype).eps)
    name = jnp.dtype(dtype).name
    if max(r, a) < eps:
        raise ValueError(
            f"rtol={r:g} and atol={a:g} are below {name}'s rounding error {eps:.1e}: no step "
            f"size can meet them; {_advice(dtype)}."
        )
    if max(r, a) < 100 * eps:
        warn_in_callers_code(
            f"rtol={r:g} and atol={a:g} are within 100 times {name}'s rounding error "
            f"{eps:.1e}: steps may be rejected for rounding and the solution is no more "
            f"accurate than about {100 * eps:.0e}; {_advice(dtype)}."
        )


def tolerance_refusals(dtype) -> tuple[str, str]:
    """The messages of `tolerance_refusal`'s codes 1 and 2, for `equinox.branched_error_if`.

    **Arguments:**

    - `dtype`: the floating dtype the solve runs in.
    """
    eps = float(jnp.finfo(dtype).eps)
    return (
        "simulate: tolerances must be non-negative.",
        f"simulate: rtol and atol are both below {jnp.dtype(dtype).name}'s rounding error "
        f"{eps:.1e}: no step size can meet them; {_advice(dtype)}.",
    )


def tolerance_refusal(rtol: ArrayLike, atol: ArrayLike, dtype) -> jax.Array:
    """`check_tolerances`'s refusals for traced tolerances (inside `jax.jit` or `jax.vmap`),
    where no Python value is there to check, as a code for `equinox.branched_error_if`: 0
    for tolerances a step size can meet, 1 for a negative one, 2 for both below the rounding
    error (`tolerance_refusals` has the messages).

    **Arguments:**

    - `rtol`, `atol`: the step-size controller's tolerances, traced or not.
    - `dtype`: the floating dtype the solve runs in.

    **Returns:**

    The code, an integer array of shape `()`.
    """
    r, a = jnp.asarray(rtol), jnp.asarray(atol)
    eps = float(jnp.finfo(dtype).eps)
    negative = jnp.any(r < 0) | jnp.any(a < 0)
    below = jnp.all(r < eps) & jnp.all(a < eps)
    return jnp.where(negative, 1, jnp.where(below, 2, 0))


def default_tolerance(dtype) -> float:
    """`simulate`'s default `rtol` and `atol` in `dtype`: 1e-8, or 1000 rounding errors where
    that is larger (1.2e-4 in float32, which cannot meet 1e-8).

    **Arguments:**

    - `dtype`: the floating dtype the solve runs in.
    """
    return precision_floor(dtype, 1e-8, 1000.0)


def default_residual_tolerance(dtype) -> float:
    """The relative residual below which a computed invariance condition counts as zero.

    1e-10 in float64 (about $5\\cdot10^5\\varepsilon$: the checks chain a few hundred
    operations, each rounding); 1e-4 in float32 (about $840\\varepsilon$), where residuals of
    valid models are measured at 1e-7 to 1e-5.

    **Arguments:**

    - `dtype`: the floating dtype of the computation.
    """
    return 1e-10 if jnp.finfo(dtype).bits >= 64 else 1e-4
