r"""The bilinear covariants (84) of the constraints' Pfaffians (seed 001, §57)."""

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._constraints import AbstractKinematicConstraints, as_time


def bilinear_covariants(
    constraints: AbstractKinematicConstraints, q: Float[Array, " n"], t
) -> Float[Array, "n nu+1 nu+1"]:
    r"""The coefficients $\eta_{h|\alpha\beta}$ (84) of the bilinear covariants of the Pfaffians (77'').

    With the time as coordinate $q_0 = t$ and $\eta_{0\alpha} = \delta_{\alpha 0}$ (77''),

    $$ \eta_{h|\alpha\beta} = \sum_{\gamma=0}^{n}\Big(\eta_{\gamma\beta}\frac{\partial\eta_{h\alpha}}{\partial q_\gamma}
       - \eta_{\gamma\alpha}\frac{\partial\eta_{h\beta}}{\partial q_\gamma}\Big)
       \qquad (h = 1..n;\ \alpha, \beta = 0..\nu), $$

    so that $d''d'q_h - d'd''q_h = \sum_{\alpha,\beta}\eta_{h|\alpha\beta}\,d'\varepsilon_\alpha
    d''\varepsilon_\beta$: the Lie bracket of the constraints' vector fields in $(t, q)$. They
    are skew in $\alpha, \beta$ (85) and vanish identically for holonomic characteristics
    (§57). The derivatives of $\eta$ are one forward-mode Jacobian.

    **Arguments:**

    - `constraints`: an `AbstractKinematicConstraints`.
    - `q`: the coordinates, shape `(n,)`; `t`: the time.

    **Returns:**

    $\eta_{h|\alpha\beta}$, shape `(n, nu + 1, nu + 1)`; index 0 of the last two axes is the
    time's ($\alpha = 0$), so for constraints that do not depend on time only `[:, 1:, 1:]`
    can be nonzero.
    """
    t = as_time(t, q)

    def columns(q, t):  # eta_{h alpha}, alpha = 0..nu, column 0 the time's (eta_{h0})
        eta, eta0 = constraints.parametric_form(q, t)
        return jnp.concatenate([eta0[:, None], eta], axis=1)

    eta = columns(q, t)
    along_q, along_t = jax.jacfwd(columns, argnums=(0, 1))(q, t)
    # derivative[h, a, b] = sum_gamma eta_{gamma b} d eta_{h a} / d q_gamma, gamma = 0..n
    derivative = jnp.einsum("hag,gb->hab", along_q, eta)
    derivative = derivative.at[:, :, 0].add(along_t)
    return derivative - jnp.swapaxes(derivative, 1, 2)
