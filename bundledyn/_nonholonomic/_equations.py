r"""Which of seed 001's equations give the characteristics' rates: Maggi's or Appell's."""

import abc

import equinox as eqx
from jaxtyping import Array, Float

from ._appell import appell_accelerations, appell_body_rates
from ._body_motion import BodyMotion
from ._maggi import maggi_accelerations, maggi_body_rates
from ._system import AbstractNonholonomicSystem


class AbstractNonholonomicEquations(eqx.Module):
    r"""Equations of motion that give the rates $\dot e$ of the characteristics.

    Two settings: a system in Lagrangian coordinates at $(q, e, t)$ (`accelerations`;
    `NonholonomicTerm` takes the equations), and a rigid body on the bundle whose body twist
    is $\xi = He$ (`body_rates`; `RollingMode` and `SkatingMode` take them).
    `MaggiEquations()` (the default) or `AppellEquations()`; subclass it to give your own (a
    closed form, a faster assembly) and check it against them.
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

    @abc.abstractmethod
    def body_rates(self, body: BodyMotion) -> Float[Array, " nu"]:
        r"""The rates $\dot e$ of a rigid body whose body twist is $\xi = He$.

        **Arguments:**

        - `body`: a `BodyMotion` ($H$, $\dot He$, $\xi$, the spatial inertia, the wrench).

        **Returns:**

        $\dot e$, shape `(nu,)`.
        """


class MaggiEquations(AbstractNonholonomicEquations):
    r"""Maggi's equations (82), $\sum_h \eta_{h\alpha}\big(\frac{d}{dt}\frac{\partial T}{\partial\dot q_h} - \frac{\partial T}{\partial q_h}\big) = \Phi_\alpha$ (`maggi_accelerations`; on the bundle `maggi_body_rates`)."""

    def accelerations(self, system, q, e, t):
        return maggi_accelerations(system, q, e, t)

    def body_rates(self, body):
        return maggi_body_rates(body)


class AppellEquations(AbstractNonholonomicEquations):
    r"""Appell's equations (§60), $\partial S/\partial\dot e_\alpha = \Phi_\alpha$ with the energy of accelerations $S$ (`appell_accelerations`; on the bundle `appell_body_rates`)."""

    def accelerations(self, system, q, e, t):
        return appell_accelerations(system, q, e, t)

    def body_rates(self, body):
        return appell_body_rates(body)
