r"""A Lie-group solver that also keeps the field's values at its stages, for reverse mode.

`StoredStepsAdjoint` steps a solve with it in its forward pass: the values of the last
`capacity` accepted steps are then at hand in its reverse sweep, which steps again with
terms that give them back (`ReplayedSceneTerm`) instead of evaluating the field a second
time.
"""

import math

import diffrax
import equinox as eqx
import jax.numpy as jnp
import jax.tree_util as jtu

from ._rkmk import AbstractRKMK

__all__ = ["StageRecorder", "nbytes", "slot_values", "stage_values_shape", "with_values"]


def stage_values_shape(solver: AbstractRKMK, terms, t0, y0, args):
    """The shapes and dtypes of a step's stage values (`AbstractRKMK.stage_step`)."""
    return eqx.filter_eval_shape(
        lambda: solver.stage_step(terms, t0, t0, y0, args)[3],
    )


class StageRecorder(diffrax.AbstractSolver):
    r"""`solver`, whose state keeps the field's values at the stages of the last
    `capacity` accepted steps: those of accepted step $k$ in slot $k \bmod$ `capacity`.

    A rejected step writes the slot of the step that replaces it, and diffrax keeps the
    state of accepted steps only, so the slot holds the accepted step's values.

    **Arguments:**

    - `solver`: the `AbstractRKMK` method (its own state is `None`).
    - `capacity`: how many steps' values are kept.
    """

    solver: AbstractRKMK
    capacity: int = eqx.field(static=True)

    @property
    def term_structure(self):
        return self.solver.term_structure

    @property
    def interpolation_cls(self):
        return self.solver.interpolation_cls

    def order(self, terms):
        return self.solver.order(terms)

    def error_order(self, terms):
        return self.solver.error_order(terms)

    def func(self, terms, t0, y0, args):
        return self.solver.func(terms, t0, y0, args)

    def init(self, terms, t0, t1, y0, args):
        values = stage_values_shape(self.solver, terms, t0, y0, args)
        buffer = jtu.tree_map(lambda v: jnp.zeros((self.capacity, *v.shape), v.dtype), values)
        return jnp.array(0), buffer

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        del made_jump
        count, buffer = solver_state
        y1, y_error, dense_info, values = self.solver.stage_step(terms, t0, t1, y0, args)
        buffer = with_values(buffer, count, self.capacity, values)
        return y1, y_error, dense_info, (count + 1, buffer), diffrax.RESULTS.successful


def slot_values(buffer, k, capacity):
    """The stage values kept for step `k` (`StageRecorder`)."""
    return jtu.tree_map(lambda b: b[k % capacity], buffer)


def with_values(buffer, k, capacity, values):
    """`buffer` with `values` in step `k`'s slot."""
    return jtu.tree_map(lambda b, v: b.at[k % capacity].set(v), buffer, values)


def nbytes(values) -> int:
    """The bytes of a pytree of arrays or shapes."""
    return sum(math.prod(v.shape) * jnp.dtype(v.dtype).itemsize for v in jtu.tree_leaves(values))
