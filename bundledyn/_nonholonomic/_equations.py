r"""Which of seed 001's equations give the characteristics' rates: Maggi's or Appell's."""

import abc

import equinox as eqx
from jaxtyping import Array, Float

from ._appell import appell_accelerations
from ._maggi import maggi_accelerations
from ._system import AbstractNonholonomicSystem


class AbstractNonholonomicEquations(eqx.Module):
    r"""Equations of motion that give the rates $\dot e$ of the characteristics at $(q, e, t)$.

    `NonholonomicTerm` takes one: `MaggiEquations()` (the default) or `AppellEquations()`.
    Subclass it to give your own (a closed form, a faster assembly) and check it against them.
    """

    @abc.abstractmethod
    def accelerations(
        self, system: AbstractNonholonomicSystem, q: Float[Array, " n"], e: Float[Array, " nu"], t
    ) -> Float[Array, " nu"]:
        r"""The rates $\dot e$ at $(q, e, t)$.

        **Arguments:**

        - `system`: an `AbstractNonholonomicSystem`.
        - `q`: the coordinates, shape `(n,)`; `e`: the characteristics, shape `(nu,)`.
        - `t`: the time.

        **Returns:**

        $\dot e$, shape `(nu,)`.
        """


class MaggiEquations(AbstractNonholonomicEquations):
    r"""Maggi's equations (82), $\sum_h \eta_{h\alpha}\big(\frac{d}{dt}\frac{\partial T}{\partial\dot q_h} - \frac{\partial T}{\partial q_h}\big) = \Phi_\alpha$ (`maggi_accelerations`)."""

    def accelerations(self, system, q, e, t):
        return maggi_accelerations(system, q, e, t)


class AppellEquations(AbstractNonholonomicEquations):
    r"""Appell's equations (§60), $\partial S/\partial\dot e_\alpha = \Phi_\alpha$ with the energy of accelerations $S$ (`appell_accelerations`)."""

    def accelerations(self, system, q, e, t):
        return appell_accelerations(system, q, e, t)
