"""The moving start the cases give a model: the same for any model, from its size."""

import jax.numpy as jnp
import numpy as np

from .._state import State
from ._models import chain

XI0 = (0.3, -0.2, 0.4, 0.1, 0.0, -0.2)


def start_of(system=None, *, spin: float | None = None):
    """`(system, state)`: the model (default a free three-link chain of masses 1, 1.5, 2 kg)
    and a moving start: shape coordinates alternating ±0.3, rates ±1, the twist `XI0`, its
    angular part scaled to `spin` rad/s when given."""
    system = chain((1.0, 1.5, 2.0)) if system is None else system
    d = system.shape_dim
    signs = np.where(np.arange(d) % 2 == 0, 1.0, -1.0)
    xi = np.asarray(XI0)
    if spin is not None:
        xi = np.concatenate([spin * xi[:3] / np.linalg.norm(xi[:3]), xi[3:]])
    state = State(jnp.eye(4), jnp.asarray(0.3 * signs), jnp.asarray(xi), jnp.asarray(signs))
    return system, state
