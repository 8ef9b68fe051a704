r"""The tensorial Lagrange equations (44) as a diffrax term on $(X, V)$."""

import diffrax
import equinox as eqx
import jax.tree_util as jtu

from ._coordinates import checked_state, rates_of
from ._equations import tensorial_accelerations
from ._system import AbstractTensorialSystem

__all__ = ["TensorialTerm"]


@eqx.filter_jit
def _field(system, t, y):
    # A jitted call: diffrax traces a solver's step several times, and JAX then reuses the
    # field's jaxpr instead of tracing the autodiff assembly of (44) each time.
    X, V = checked_state(y)
    return rates_of(X, V), tensorial_accelerations(system, X, V, t)


class TensorialTerm(diffrax.AbstractTerm):
    r"""A system in tensor coordinates as a diffrax term on the state $y = (X, V)$.

    The field is $(\dot X, \dot V)$: the rates (55) of the coordinates, $(\dot q,\
    \Omega\times e,\ \tilde\omega Z)$, and the velocities' rates that solve the tensorial
    Lagrange equations (44) (`tensorial_accelerations`). Integrate it with
    `TensorialRKMK87` (or `TensorialRKMK54`, `TensorialRKMK4`), which move each unit vector
    and rotation by rotations only, so they stay on the sphere and on SO(3) to rounding
    error; any diffrax solver also integrates it, in the embedding, where they drift.

    **Arguments:**

    - `system`: an `AbstractTensorialSystem`.
    """

    system: AbstractTensorialSystem

    def __check_init__(self):
        if not isinstance(self.system, AbstractTensorialSystem):
            raise ValueError(
                "`TensorialTerm.system` must be an AbstractTensorialSystem (e.g. "
                f"`TensorialSystem`); got {type(self.system).__name__}."
            )

    def vf(self, t, y, args):
        r"""$(\dot X, \dot V)$ at the state `y = (X, V)` and time `t`."""
        return _field(self.system, t, y)

    def contr(self, t0, t1, **kwargs):
        return t1 - t0

    def prod(self, vf, control):
        return jtu.tree_map(lambda v: control * v, vf)
