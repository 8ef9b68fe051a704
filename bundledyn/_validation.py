"""Construction checks shared by every layer: a value when it is concrete, and its shape.

The lowest layer: it imports no module of the package, so any module may use it (the
systems' parameter checks, `_systems/_validation.py`, build on it; so do `State`, the
solids and the tolerances' checks).
"""

import numpy as np


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
