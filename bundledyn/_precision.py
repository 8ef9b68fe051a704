"""Floating-point precision: float64 is opt-in, never switched on at import."""

import warnings

import jax
import jax.numpy as jnp
from jax.typing import ArrayLike

from ._systems._validation import concrete


def enable_x64(enable: bool = True) -> None:
    """Switch JAX to float64 as the default working precision.

    bundledyn never flips this global flag on import; call this once, before building
    arrays, when rounding-level accuracy is wanted (the physics tests do).

    **Arguments:**

    - `enable`: `True` for float64 (the default), `False` to go back to float32.
    """
    jax.config.update("jax_enable_x64", enable)


def warn_if_tolerance_too_tight(tolerance: ArrayLike, dtype) -> None:
    """Warn when a requested tolerance is below what `dtype` can resolve.

    **Arguments:**

    - `tolerance`: the relative tolerance the user asked for.
    - `dtype`: the floating dtype the computation will run in.
    """
    eps = float(jnp.finfo(dtype).eps)
    value = concrete(tolerance)  # None under jit: a traced tolerance is the caller's choice
    if value is not None and value < 100 * eps:
        warnings.warn(
            f"a tolerance of {tolerance:g} was asked for in {jnp.dtype(dtype).name}, whose "
            f"rounding error is {eps:.1e}; call `bundledyn.enable_x64()` before building arrays "
            "to compute in float64.",
            stacklevel=3,
        )
