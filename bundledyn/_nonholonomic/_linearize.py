r"""The linearization of a nonholonomic system's equations about a state, by autodiff."""

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._term import NonholonomicTerm

__all__ = ["linearization"]


def linearization(
    term: NonholonomicTerm, y: tuple[Float[Array, " n"], Float[Array, " nu"]], t=0.0
) -> Float[Array, "n+nu n+nu"]:
    r"""The Jacobian of the field $(\dot q, \dot e)$ of (77) with (82) (or §60) at the state
    $y = (q, e)$: the linearized equations $\delta\dot y = J\,\delta y$ about an
    equilibrium or a steady motion.

    At a steady motion of a system with cyclic coordinates (those the field does not depend
    on: a rolling disc's position, heading and spin angle) $J$ is block-triangular: the
    rows and columns of the other variables form the reduced field's Jacobian, whose
    eigenvalues decide the stability (`jnp.linalg.eigvals(J[np.ix_(kept, kept)])`). The
    cyclic block only adds zero eigenvalues, defective ones (a heading moves the position),
    which an eigenvalue solver returns only to about $\sqrt{\varepsilon}$: take the reduced
    block. The Jacobian is differentiable in the system's parameters, so are its
    eigenvalues.

    **Arguments:**

    - `term`: a `NonholonomicTerm` (the system and Maggi's or Appell's equations).
    - `y`: the state `(q, e)`, shapes `(n,)` and `(nu,)`.
    - `t`: the time.

    **Returns:**

    $J = \partial(\dot q, \dot e)/\partial(q, e)$, shape `(n + nu, n + nu)`, rows and
    columns ordered as $(q, e)$.
    """
    q, e = y
    n = q.shape[0]

    def field(z):
        q_dot, e_dot = term.vf(t, (z[:n], z[n:]), None)
        return jnp.concatenate([q_dot, e_dot])

    return jax.jacfwd(field)(jnp.concatenate([q, e]))
