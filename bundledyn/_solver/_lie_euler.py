r"""The Lie–Euler method: the one-stage Runge–Kutta–Munthe-Kaas method."""

from typing import ClassVar

import equinox as eqx

from ._rkmk import INIT_DOC, AbstractRKMK
from ._tableau import LieButcherTableau, euler_tableau

__all__ = ["LieEuler"]


class LieEuler(AbstractRKMK):
    r"""Lie–Euler method: $g_1 = g_0\exp(h\hat\xi_0)$, $x_1 = x_0 + h\dot x_0$.

    First order, one vector-field evaluation per step, no error estimate (use
    `diffrax.ConstantStepSize`). The pose is updated by the group exponential, so $R$
    stays orthogonal to rounding error for any step size. Dense output: the geodesic
    $g_0\exp(s\,h\hat\xi_0)$ and linear interpolation of $x$. It is the explicit RKMK
    method of the one-stage (Euler) tableau; see `AbstractRKMK` for the state layout
    `y = (g, x)` and the vector field.

    ??? cite "Reference"

        ```bibtex
        @article{iserles2000lie,
            author={Iserles, Arieh and Munthe-Kaas, Hans Z. and N{\o}rsett, Syvert P.
                    and Zanna, Antonella},
            title={Lie-group methods},
            journal={Acta Numerica},
            volume={9},
            pages={215--365},
            year={2000}
        }
        ```
    """

    tableau: ClassVar[LieButcherTableau] = euler_tableau
    dense_output: bool = eqx.field(default=True, static=True)

    def order(self, terms):
        del terms
        return 1


LieEuler.__init__.__doc__ = INIT_DOC
