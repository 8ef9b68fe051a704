"""Construction checks shared by every layer: a value when it is concrete, and its shape.

The lowest layer: it imports no module of the package, so any module may use it (the
systems' parameter checks, `_systems/_validation.py`, build on it; so do `State`, the
solids and the tolerances' checks).
"""

import numpy as np


def precision_floor(dtype, floor: float, rounding_errors: float) -> float:
    """`floor`, or `rounding_errors` rounding errors of `dtype` where that is larger (no
    rounding error for a dtype that is not floating): a tolerance set for float64's
    arithmetic, widened where a narrower precision cannot meet it."""
    dtype = np.dtype(dtype)
    eps = float(np.finfo(dtype).eps) if np.issubdtype(dtype, np.floating) else 0.0
    return max(floor, rounding_errors * eps)


def rounding_tolerance(value, floor: float) -> float:
    """`floor`, or 64 rounding errors of `value`'s dtype where that is larger: a construction
    check's tolerance, widened so float32's arithmetic passes it too (float32 builds a
    rotation orthogonal only to about 1e-7)."""
    return precision_floor(np.asarray(value).dtype, floor, 64.0)


def concrete(x):
    """The value of `x` as a NumPy array, or `None` when `x` is a tracer (inside jit/vmap/grad).

    Validation runs on concrete inputs only: a module rebuilt from tracers by a JAX
    transformation was validated when it was first built.
    """
    try:
        return np.asarray(x)
    except Exception:
        return None


def check_shape(name: str, value, shape: tuple[int, ...]) -> None:
    """Raise `ValueError` naming `name` unless `value` has exactly `shape`."""
    if tuple(np.shape(value)) != shape:
        raise ValueError(
            f"`{name}` must have shape {shape}, got {tuple(np.shape(value))}; pass a "
            f"{'scalar' if shape == () else 'array of that shape'}."
        )
