"""The capability marker of the solvers that step on the group."""

from diffrax import AbstractSolver

__all__ = ["AbstractLieGroupSolver"]


class AbstractLieGroupSolver(AbstractSolver):
    r"""A diffrax solver that steps on SE(3): the pose is only ever multiplied by
    exponentials of the algebra, so its rotation stays orthogonal to rounding error.

    A capability marker, as `diffrax.AbstractAdaptiveSolver` is one: `simulate` returns the
    poses of these solvers as they are, while it projects those of any other solver (which
    integrates the pose in its $4\times4$ embedding) back onto SE(3) and reports their drift.
    Subclass it (or `AbstractRKMK`) for a Lie-group method of your own.
    """
