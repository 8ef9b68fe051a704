r"""A Lie-group solver that also keeps the field's values at its stages, for reverse mode.

`StoredStepsAdjoint` steps a solve with it in its forward pass: the start states and
stage values of the last `capacity` accepted steps are then at hand in its reverse sweep,
which steps again with terms that give the values back (`ReplayedSceneTerm`) instead of
evaluating the field a second time, and the other steps can be stepped again from the
checkpoints it keeps.
"""

import math

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.tree_util as jtu

from ._base import AbstractStageReplaySolver

__all__ = ["Kept", "StageRecorder", "nbytes", "slot_values", "stage_values_shape", "with_values"]


def stage_values_shape(solver: AbstractStageReplaySolver, terms, t0, y0, args):
    """The shapes and dtypes of a step's stage values (`AbstractRKMK.stage_step`)."""
    return eqx.filter_eval_shape(
        lambda: solver.stage_step(terms, t0, t0, y0, args)[3],
    )


class Kept(eqx.Module):
    r"""What `StageRecorder` keeps: for the last `capacity` accepted steps, each step's
    start state and the field's values at its stages, step $k$ in slot $k \bmod$
    `capacity`; and the start state of every `capacity`-th step, step $c\,$`capacity` in
    `checkpoints[c]`, from which the others can be stepped again."""

    count: jax.Array
    values: object
    states: object
    checkpoints: object


class StageRecorder(diffrax.AbstractSolver):
    r"""`solver`, whose state (`Kept`) keeps what the reverse sweep of
    `StoredStepsAdjoint` steps again from: the start states and the field's values at the
    stages of the last `capacity` accepted steps, and the start states of every
    `capacity`-th step.

    A rejected step writes the slot of the step that replaces it, and diffrax keeps the
    state of accepted steps only, so a slot holds the accepted step's.

    **Arguments:**

    - `solver`: an `AbstractStageReplaySolver` (its own state is `None`).
    - `capacity`: how many steps' values and states are kept.
    - `checkpoints`: how many checkpoints are kept (`max_steps / capacity`, rounded up).
    """

    solver: AbstractStageReplaySolver
    capacity: int = eqx.field(static=True)
    checkpoints: int = eqx.field(static=True)

    # The wrapped solver's, as diffrax's own wrappers give them: properties for what
    # `AbstractSolver` declares class variables.
    @property
    def term_structure(self):  # pyright: ignore[reportIncompatibleVariableOverride]
        return self.solver.term_structure

    @property
    def interpolation_cls(self):  # pyright: ignore[reportIncompatibleMethodOverride]
        return self.solver.interpolation_cls

    def order(self, terms):
        return self.solver.order(terms)

    def error_order(self, terms):
        return self.solver.error_order(terms)

    def func(self, terms, t0, y0, args):
        return self.solver.func(terms, t0, y0, args)

    def init(self, terms, t0, t1, y0, args):
        values = stage_values_shape(self.solver, terms, t0, y0, args)

        def buffer(tree, length):
            return jtu.tree_map(lambda v: jnp.zeros((length, *jnp.shape(v)), v.dtype), tree)

        return Kept(
            jnp.array(0),
            buffer(values, self.capacity),
            buffer(y0, self.capacity),
            buffer(y0, self.checkpoints),
        )

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        del made_jump
        kept, k = solver_state, solver_state.count
        y1, y_error, dense_info, values = self.solver.stage_step(terms, t0, t1, y0, args)
        c = k // self.capacity
        checkpoint = jtu.tree_map(
            lambda old, y: jnp.where(k % self.capacity == 0, y, old[c]), kept.checkpoints, y0
        )
        kept = Kept(
            k + 1,
            with_values(kept.values, k, self.capacity, values),
            with_values(kept.states, k, self.capacity, y0),
            jtu.tree_map(lambda b, y: b.at[c].set(y), kept.checkpoints, checkpoint),
        )
        return y1, y_error, dense_info, kept, diffrax.RESULTS.successful


def slot_values(buffer, k, capacity):
    """What is kept for step `k` in `buffer` (`Kept.values` or `Kept.states`)."""
    return jtu.tree_map(lambda b: b[k % capacity], buffer)


def with_values(buffer, k, capacity, values):
    """`buffer` with `values` in step `k`'s slot (`Kept.values` or `Kept.states`)."""
    return jtu.tree_map(lambda b, v: b.at[k % capacity].set(v), buffer, values)


def nbytes(values) -> int:
    """The bytes of a pytree of arrays or shapes."""
    return sum(math.prod(v.shape) * jnp.dtype(v.dtype).itemsize for v in jtu.tree_leaves(values))
