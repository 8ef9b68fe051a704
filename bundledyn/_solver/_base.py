"""The capability markers of the solvers that step on the group."""

import abc
from typing import Any

from diffrax import AbstractSolver

__all__ = ["AbstractLieGroupSolver", "AbstractStageReplaySolver"]


class AbstractLieGroupSolver(AbstractSolver):
    r"""A diffrax solver that steps on SE(3): the pose is only ever multiplied by
    exponentials of the algebra, so its rotation stays orthogonal to rounding error.

    A capability marker, as `diffrax.AbstractAdaptiveSolver` is one: `simulate` returns the
    poses of these solvers as they are, while it projects those of any other solver (which
    integrates the pose in its $4\times4$ embedding) back onto SE(3) and reports their drift.
    Subclass it (or `AbstractRKMK`) for a Lie-group method of your own.
    """


class AbstractStageReplaySolver(AbstractLieGroupSolver):
    r"""A Lie-group solver whose step can give the field's values at its stages, and step
    again with those values given back instead of evaluated (`stage_step`).

    A capability marker: `StoredStepsAdjoint` keeps the stage values of these solvers'
    steps in its forward solve and replays them in its reverse sweep, through the written-out
    reverse pass of the stages; with any other solver it evaluates each step again.
    """

    @abc.abstractmethod
    def stage_step(
        self, terms, t0, t1, y0, args, *, stage_terms=None, reverse_pass=False
    ) -> tuple[Any, Any, dict[str, Any], Any]:
        r"""`step`, also returning the field's values $(\xi, \dot x)$ at the stages, with
        the field of stage $i$ that of `stage_terms(i)` (default `terms`): `(y1, y_error,
        dense_info, values)`, each leaf of `values` stacked over the stages first. With
        `reverse_pass`, the stages are differentiated by a written-out reverse pass."""
