r"""Explicit Runge–Kutta–Munthe-Kaas methods on SE(3) × Euclidean space, as diffrax solvers.

One generic implementation, `AbstractRKMK`, parametrized by a Butcher tableau; `RKMK4`,
`RKMK54`, `RKMK87` (and `LieEuler`, in `_lie_euler.py`) are instances.

The method (Munthe-Kaas 1998, 1999; Iserles, Munthe-Kaas, Nørsett & Zanna 2000, §5). The
vector field is an ordinary diffrax term on the embedding $\mathbb R^{4\times4}\times
\mathbb R^n$, $\dot g = g\hat\xi(t, g, x)$, $\dot x = F(t, g, x)$. Over a step
$[t_0, t_0 + h]$, writing $g = g_0\exp\hat\Omega$, the increment obeys the ODE
$\dot\Omega = \mathrm{dexp}^{-1}_\Omega\,\xi$ on the vector space $\mathbb R^6$, to which
the classical tableau is applied:

$$\Omega_i = \sum_j a_{ij}K_j,\quad g_i = g_0\exp\hat\Omega_i,\quad
X_i = x_0 + \sum_j a_{ij}k_j,$$
$$K_i = h\,\mathrm{dexp}^{-1}_{\Omega_i}\xi(t_0 + c_ih, g_i, X_i),\quad
k_i = h\,F(t_0 + c_ih, g_i, X_i),$$
$$g_1 = g_0\exp\Big(\sum_i b_iK_i\Big)^\wedge,\quad x_1 = x_0 + \sum_i b_ik_i.$$

With $\mathrm{dexp}^{-1}$ evaluated exactly (`bundledyn.lie.se3_dexp_inv`) an order-$p$
tableau gives an order-$p$ method, and $g$ is only ever multiplied by exponentials, so
$R$ stays orthogonal to rounding error whatever the step size or tolerance. The twist is
taken from the term where it gives it (`AbstractBodyTerm`, as `SceneTerm` does), otherwise
read off the field as $\xi_i = (g_i^{-1}\dot g_i)^\vee$; matrices are never added to $g$.
"""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import jax.tree_util as jtu
from diffrax import RESULTS, AbstractAdaptiveSolver, AbstractTerm

from .. import lie
from .._term import split
from ._base import AbstractStageReplaySolver
from ._chart import body_field, body_term, checked_start, from_chart, recharted
from ._interpolation import LieLocalInterpolation
from ._stage_reverse import combine, stages, stages_with_reverse_pass
from ._tableau import LieButcherTableau, dopri5_tableau, dopri8_tableau, rk4_tableau

__all__ = ["AbstractRKMK", "RKMK4", "RKMK54", "RKMK87"]


class AbstractRKMK(AbstractStageReplaySolver):
    r"""Explicit Runge–Kutta–Munthe-Kaas method given by a Butcher tableau.

    Subclass it with a `LieButcherTableau` as the class attribute `tableau`, an `order`
    method and a `dense_output` field to get a Lie-group solver of your own tableau (add
    `diffrax.AbstractAdaptiveSolver` as a base when the tableau has an error estimate).
    States are pytrees whose first leaf is a $4\times4$ SE(3) pose and whose other leaves
    are Euclidean, e.g. `y = (g, x)`; the term is an `AbstractBodyTerm`, which gives the
    pose's rate as its body twist $\xi$, or any diffrax term whose vector field returns
    $(\dot g, \dot x)$ with $\dot g = g\hat\xi$ (the twist is then read off $\dot g$).

    - With an embedded pair, the step's error estimate is
      `y_error` $= \big((\Omega - \hat\Omega)^\wedge,\ x_1 - \hat x_1\big)$: a Lie-algebra
      increment (never a difference of matrices) arranged as a $4\times4$ so that the
      pytree matches `y`. `diffrax.PIDController` divides it elementwise by
      `atol + rtol * |g|`: for the rotation block this is a tolerance on angles (radians,
      entered twice, as $\pm\omega_k$), for the translation column a tolerance on lengths
      (the body-frame translation increment); the bottom row and the diagonal are zero.
    - Every stage is evaluated inside one `lax.scan`, FSAL tableaus included, so the
      vector field is traced once; reusing an FSAL stage would need a `lax.cond` or a
      second trace of the field, each dearer on the CPU than the evaluation it saves.
    - Under reverse-mode differentiation each stage is recomputed (`jax.checkpoint`)
      rather than the field's intermediates stored over the stages, which cost more;
      a field's outputs named `KEPT_FIELD_OUTPUTS` are kept instead (a field with its own
      reverse pass is then not evaluated twice).
    - Dense output: `LieLocalInterpolation`, the tableau's continuous extension in the
      chart $g_0\exp\hat\Theta$, which stays on the group. With `dense_output=False` a
      step evaluates only the stages that the solution and the error estimate use
      (`RKMK87`: 13 of its 14) and its dense output is NaN: `bundledyn.simulate` sets it
      when nothing interpolates (no `SaveAt(ts=...)`, no `SaveAt(dense=True)`, no event).
      The saved states are the same either way.

    - A field that is NaN or infinite at the (finite) state a step starts from raises
      (`equinox.error_if`, inside `jit` and `grad` too), naming the model as the cause:
      diffrax's controller would otherwise reject the step and shrink it until `max_steps`.

    Valid while the rotation part of the algebra increments stays below $2\pi$
    (where $\mathrm{dexp}^{-1}$ is singular); an adaptive controller keeps it far below.
    """

    tableau: ClassVar[LieButcherTableau]
    dense_output: eqx.AbstractVar[bool]
    term_structure: ClassVar = AbstractTerm
    interpolation_cls: ClassVar = LieLocalInterpolation

    def init(self, terms, t0, t1, y0, args):
        split(y0)  # validate the state layout early
        return None

    def func(self, terms, t0, y0, args):
        return terms.vf(t0, y0, args)

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        def field(i, t, y, control):
            del i
            return body_field(terms, t, y, args, control), None

        y1, y_error, dense_info, _ = self._step(terms, t0, t1, y0, args, field)
        return y1, y_error, dense_info, None, RESULTS.successful

    def stage_step(self, terms, t0, t1, y0, args, *, stage_terms=None, reverse_pass=False):
        r"""`step`, also returning the field's values at the stages, with the field of
        stage $i$ that of `stage_terms(i)` (default `terms`).

        `bundledyn.StoredStepsAdjoint` keeps the values in its forward solve and steps
        again in its reverse sweep with terms that give them back instead of evaluating
        the field (`ReplayedSceneTerm`).

        **Arguments:**

        - `terms`, `t0`, `t1`, `y0`, `args`: as for `step`; `terms` is an
          `AbstractBodyTerm` (or diffrax's wrapper of one).
        - `stage_terms`: a function of the stage's index giving the body term evaluated at
          that stage, with the structure of `terms`.
        - `reverse_pass`: differentiate the stages by their written-out reverse pass
          (`_stage_reverse.py`), as the adjoint's reverse sweep does; the step then has no
          forward-mode derivative.

        **Returns:**

        `(y1, y_error, dense_info, values)`: the step as `step` gives it, and the field's
        values $(\xi, \dot x)$ at the evaluated stages (before the control multiplies
        them), each leaf stacked over the stages first.
        """
        if body_term(terms)[0] is None:
            raise ValueError("`stage_step` needs an `AbstractBodyTerm`.")
        stage_terms = (lambda i: terms) if stage_terms is None else stage_terms

        def field(i, t, y, control):
            term, direction = body_term(stage_terms(i))
            assert term is not None  # `stage_terms` gives terms structured as `terms`
            values = term.body_vf(t * direction, y, args)
            return terms.prod(values, control), values

        return self._step(terms, t0, t1, y0, args, field, reverse_pass=reverse_pass)

    def _step(self, terms, t0, t1, y0, args, field, *, reverse_pass=False):
        """The step, with `field(i, t, y, control)` giving stage `i`'s field (in the
        form of `body_field`) and a value to stack over the stages; with `reverse_pass`,
        the stages differentiated by their written-out reverse pass."""
        y0 = recharted(terms, t0, y0)
        tab = self.tableau
        g0, rest0, treedef = split(y0)
        dtype = jnp.result_type(*jtu.tree_leaves(y0))
        control = terms.contr(t0, t1)
        a = jnp.asarray(tab.a, dtype=dtype)
        ts = t0 + jnp.asarray(tab.c_full, dtype=dtype) * (t1 - t0)
        n = tab.num_stages if self.dense_output else tab.step_stages
        run = stages_with_reverse_pass if reverse_pass else stages
        kappas, ks, values = run(field, a, g0, rest0, treedef, ts, control, n)[:3]

        b = jnp.asarray(tab.b_sol, dtype=dtype)
        y1 = from_chart(g0, rest0, treedef, combine(b, kappas), [combine(b, k) for k in ks])
        y1 = checked_start(y1, t0, t1, y0, [kappas[..., 0]] + [k[..., 0] for k in ks])

        if tab.b_error is None:
            y_error = None
        else:
            e = jnp.asarray(tab.b_error, dtype=dtype)
            err_leaves = [lie.hat(combine(e, kappas))] + [combine(e, k) for k in ks]
            y_error = jtu.tree_unflatten(treedef, err_leaves)

        if self.dense_output:
            d = jnp.asarray(tab.dense, dtype=dtype)
            coeffs = [combine(d, kappas)] + [combine(d, k) for k in ks]
        else:  # stages were skipped: an interpolation would be wrong, so make it NaN
            degree = tab.dense.shape[0]
            coeffs = [jnp.full((degree, *k.shape[:-1]), jnp.nan, k.dtype) for k in (kappas, *ks)]
        coeffs = jtu.tree_unflatten(treedef, coeffs)
        dense_info = dict(y0=y0, coeffs=coeffs)
        return y1, y_error, dense_info, values


class RKMK4(AbstractRKMK):
    r"""Runge–Kutta–Munthe-Kaas method with the classical fourth-order tableau.

    Fixed step (no error estimate; use `diffrax.ConstantStepSize`, or wrap in
    `diffrax.HalfSolver` — whose error estimate is then a difference of matrices). Four
    vector-field evaluations per step. Dense output: the tableau's free third-order
    continuous extension, on the group. See `AbstractRKMK` for the state layout.

    ??? cite "References"

        ```bibtex
        @article{munthekaas1999high,
            author={Munthe-Kaas, Hans},
            title={High order {R}unge--{K}utta methods on manifolds},
            journal={Applied Numerical Mathematics},
            volume={29},
            number={1},
            pages={115--127},
            year={1999}
        }
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

    tableau: ClassVar[LieButcherTableau] = rk4_tableau
    dense_output: bool = eqx.field(default=True, static=True)

    def order(self, terms):
        del terms
        return 4


class RKMK54(AbstractRKMK, AbstractAdaptiveSolver):
    r"""Runge–Kutta–Munthe-Kaas method with the Dormand–Prince 5(4) tableau.

    For loose tolerances (about 1e-3 to 1e-5), where its seven evaluations per step cost less
    than `RKMK87`'s fourteen. Fifth order, with an embedded fourth-order error estimate
    measured in the Lie algebra (see `AbstractRKMK`), so it works with
    `diffrax.PIDController`. Seven stages, all evaluated every step (see `AbstractRKMK`
    for why the FSAL stage is not reused). Dense output: the fourth-order quartic of
    `diffrax.Dopri5`, applied in the algebra chart, so it stays on the group.

    ??? cite "References"

        ```bibtex
        @article{munthekaas1998runge,
            author={Munthe-Kaas, Hans},
            title={{R}unge--{K}utta methods on {L}ie groups},
            journal={BIT Numerical Mathematics},
            volume={38},
            number={1},
            pages={92--111},
            year={1998}
        }
        @article{dormand1980family,
            author={Dormand, J. R. and Prince, P. J.},
            title={A family of embedded {R}unge--{K}utta formulae},
            journal={J. Comp. Appl. Math},
            volume={6},
            pages={19--26},
            year={1980}
        }
        @article{shampine1986some,
            author={Shampine, Lawrence F.},
            title={Some Practical {R}unge--{K}utta Formulas},
            journal={Mathematics of Computation},
            volume={46},
            number={173},
            pages={135--150},
            year={1986}
        }
        ```
    """

    tableau: ClassVar[LieButcherTableau] = dopri5_tableau
    dense_output: bool = eqx.field(default=True, static=True)

    def order(self, terms):
        del terms
        return 5


class RKMK87(AbstractRKMK, AbstractAdaptiveSolver):
    r"""Runge–Kutta–Munthe-Kaas method with the Dormand–Prince 8(7) tableau.

    The default of `bundledyn.simulate`. Eighth order, with an embedded seventh-order error
    estimate measured in the Lie algebra (see `AbstractRKMK`), so it works with
    `diffrax.PIDController`. A step costs 14 field evaluations, twice `RKMK54`'s 7, or 13
    with `dense_output=False` (the FSAL stage serves only the dense output, which
    `simulate` skips when nothing interpolates), but at tight tolerances it takes far
    fewer steps: from about rtol 1e-6 down it needs fewer evaluations per unit accuracy,
    which is why it is the default (`benchmarks/` measures the crossover).

    Dense output: the sextic of `diffrax.Dopri8` (which cites Bogacki & Shampine 1990),
    built on the 14 stages without extra ones, in the algebra chart, so it stays on the
    group. Between the step's ends it is of fifth order only (diffrax's docstring says
    eighth), so with the long steps this method takes `SaveAt(ts=...)`, `sol.evaluate`
    and events are less accurate than the steps (`diffrax.Dopri8` alike). Save at the
    steps (`SaveAt(steps=True)`, or `t1`) where that matters.

    ??? cite "References"

        ```bibtex
        @article{munthekaas1999high,
            author={Munthe-Kaas, Hans},
            title={High order {R}unge--{K}utta methods on manifolds},
            journal={Applied Numerical Mathematics},
            volume={29},
            number={1},
            pages={115--127},
            year={1999}
        }
        @article{prince1981high,
            author={Prince, P. J and Dormand, J. R.},
            title={High order embedded {R}unge--{K}utta formulae},
            journal={J. Comp. Appl. Math},
            year={1981},
            volume={7},
            number={1},
            pages={67--75}
        }
        @article{bogacki1990interpolating,
            author={Bogacki, P. and Shampine, L. F.},
            title={Interpolating high-order {R}unge--{K}utta formulas},
            journal={Comput. Math. with Appl.},
            year={1990},
            volume={20},
            number={3},
            pages={15--24},
            doi={https://doi.org/10.1016/0898-1221(90)90027-H}
        }
        ```
    """

    tableau: ClassVar[LieButcherTableau] = dopri8_tableau
    dense_output: bool = eqx.field(default=True, static=True)

    def order(self, terms):
        del terms
        return 8


INIT_DOC = """**Arguments:**

- `dense_output`: whether steps evaluate the stages that only the dense output uses
  (`SaveAt(ts=...)`, `SaveAt(dense=True)`, events); see `AbstractRKMK`.
"""
RKMK4.__init__.__doc__ = RKMK54.__init__.__doc__ = RKMK87.__init__.__doc__ = INIT_DOC
