r"""A nonholonomic system's equations (77) with (82) or §60 as a diffrax term on $(q, e)$."""

import diffrax
import equinox as eqx
import jax.tree_util as jtu
from jaxtyping import Array, Float

from ._constraints import as_time, constrained_velocities
from ._equations import AbstractNonholonomicEquations, MaggiEquations
from ._system import AbstractNonholonomicSystem


@eqx.filter_jit
def _field(system, equations, t, y):
    # A jitted call: diffrax traces a solver's step several times (shapes, loop body,
    # starting step), and JAX then reuses the field's jaxpr, and under `jax.grad` its
    # derivative, instead of tracing and differentiating the autodiff assembly each time.
    q, e = y
    t = as_time(t, q)
    q = system.constraints.on_the_constraints(q, t)
    return constrained_velocities(system.constraints, q, e, t), equations.accelerations(
        system, q, e, t
    )


class NonholonomicTerm(diffrax.AbstractTerm):
    r"""The equations of a nonholonomic system as a diffrax term on the state $y = (q, e)$.

    The field is $\dot q = \eta(q, t)\,e + \eta_0(q, t)$ (77) and $\dot e$ from `equations`
    (Maggi's (82) by default, or Appell's, §60), the normal form of §55 in $n + \nu$
    unknowns, evaluated with $q$ on the holonomic constraints the system's kinematic ones
    include (`on_the_constraints`). It behaves as `diffrax.ODETerm`, so any diffrax solver, step-size controller,
    `SaveAt` and adjoint work with it, inside `jax.jit`, `jax.vmap` and `jax.grad`:

    ```python
    bd.enable_x64()  # the tolerances below need float64
    sleigh = bd.ChaplyginSleigh(mass=1.0, inertia=0.5, distance=0.3)
    term = bd.NonholonomicTerm(sleigh)                        # Maggi's equations
    # term = bd.NonholonomicTerm(sleigh, bd.AppellEquations())  # the same motion
    y0 = (jnp.zeros(3), jnp.array([0.0, 2.0]))                # (q, e) = ((x, y, θ), (v, ω))
    sol = diffrax.diffeqsolve(term, diffrax.Tsit5(), 0.0, 5.0, None, y0,
                              stepsize_controller=diffrax.PIDController(rtol=1e-10, atol=1e-10))
    ```

    **Arguments:**

    - `system`: an `AbstractNonholonomicSystem`.
    - `equations`: an `AbstractNonholonomicEquations`, `MaggiEquations()` by default.
    """

    system: AbstractNonholonomicSystem
    equations: AbstractNonholonomicEquations = eqx.field(default_factory=MaggiEquations)

    def __check_init__(self):
        if not isinstance(self.system, AbstractNonholonomicSystem):
            raise ValueError(
                "`NonholonomicTerm.system` must be an AbstractNonholonomicSystem (e.g. "
                f"`NonholonomicSystem`, `ChaplyginSleigh`); got {type(self.system).__name__}."
            )
        if not isinstance(self.equations, AbstractNonholonomicEquations):
            raise ValueError(
                "`NonholonomicTerm.equations` must be an AbstractNonholonomicEquations, "
                f"`MaggiEquations()` or `AppellEquations()`; got {type(self.equations).__name__}."
            )

    def vf(self, t, y, args):
        r"""$(\dot q, \dot e)$ at the state `y = (q, e)` and time `t`."""
        return _field(self.system, self.equations, t, y)

    def constraint_residual(self, t, y) -> Float[Array, " h"]:
        r"""$f(q, t)$ of the system's holonomic constraints at the integrated configuration.

        The field is evaluated on the constraints (`on_the_constraints`), so this is the
        integrator's error in the dependent coordinates; `jax.vmap` it over a solution's
        `ts` and `ys`.

        **Arguments:**

        - `t`: the time; `y`: the state $(q, e)$.

        **Returns:**

        The residual, shape `(h,)`; empty for a system without holonomic constraints.
        """
        q, _ = y
        return self.system.constraints.holonomic_residual(q, as_time(t, q))

    def contr(self, t0, t1, **kwargs):
        return t1 - t0

    def prod(self, vf, control):
        return jtu.tree_map(lambda v: control * v, vf)
