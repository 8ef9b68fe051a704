r"""The abstract mechanical system: an invariant metric in a local trivialization."""

import abc
from typing import TYPE_CHECKING, ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._metric_jet import AbstractMetricJet, DenseMetricJet


class AbstractSystem(eqx.Module):
    r"""A mechanical system whose configuration space is a principal SE(3) bundle.

    In a local trivialization $s = g \cdot r(q)$ (seed 004, §2) a system is known by its
    invariant kinetic-energy metric. With $\xi = g^{-1}\dot g$ the body velocity of the
    section frame and $\dot q$ the shape velocity,

    $$T = \tfrac12 [\xi; \dot q]^T G(q) [\xi; \dot q], \quad
      G = \begin{bmatrix} I_r & B \\ B^T & M \end{bmatrix}.$$

    Everything else (locked inertia, connection, shape metric, curvature, the equations
    (2.6)–(2.7)) follows from `metric` and `metric_jet`. Subclasses implement
    `shape_dim`, `metric`, `metric_jet` (a closed form, or `autodiff_metric_jet`) and
    `checked`.
    """

    @property
    @abc.abstractmethod
    def shape_dim(self) -> int:
        """The number $d$ of shape coordinates $q$ (static)."""

    @abc.abstractmethod
    def metric(self, q: Float[Array, " d"]) -> Float[Array, "6+d 6+d"]:
        r"""The metric $G(q)$ of the kinetic energy in the trivialization variables $(\xi, \dot q)$.

        **Arguments:**

        - `q`: shape coordinates, shape `(d,)`.

        **Returns:**

        $G(q)$, symmetric positive definite, shape `(6 + d, 6 + d)`.
        """

    @abc.abstractmethod
    def metric_jet(self, q: Float[Array, " d"]) -> AbstractMetricJet:
        """The metric and its first derivative at $q$, for the contractions (2.6)–(2.7) use.

        **Arguments:**

        - `q`: shape coordinates, shape `(d,)`.

        **Returns:**

        An `AbstractMetricJet`.
        """

    def constraint_residual(self, q: Float[Array, " d"]) -> Float[Array, " r"]:
        """The residuals of the constraints among shape coordinates the system eliminates, at
        its shape `q`: zero where they hold; empty (`r = 0`) for a system that has none, which
        is every system but a `ConstrainedSystem`.

        **Arguments:**

        - `q`: shape coordinates, shape `(d,)`.

        **Returns:**

        The residuals, shape `(r,)`.
        """
        return jnp.zeros((0,), q.dtype)

    @abc.abstractmethod
    def checked(self) -> "AbstractSystem":
        """The system with run-time checks of its parameters attached (`equinox.error_if`).

        Construction checks concrete parameters; parameters that are traced (inside
        `jax.jit` or `jax.grad`) or changed afterwards (an optimizer's update, `eqx.tree_at`)
        are checked here instead, each with the message construction would give.
        `simulate` calls it once per solve.

        **Returns:**

        The same system, its parameters passed through `equinox.error_if`.
        """

    def metric_and_derivative(self, q):
        r"""$G(q)$ and its partial derivatives $\partial G / \partial q_k$, from `metric_jet`.

        **Arguments:**

        - `q`: shape coordinates, shape `(d,)`.

        **Returns:**

        A pair `(G, dG)` with `G` of shape `(6+d, 6+d)` and `dG[k]` $= \partial G/\partial q_k$,
        shape `(d, 6+d, 6+d)` (derivative index first, so that contractions are batched
        matrix products).
        """
        jet = self.metric_jet(q)
        return jet.metric, jet.derivative()


class AbstractInertialSystem(AbstractSystem):
    r"""A system whose mass data are bodies' pseudo-inertias: the parameters identification fits.

    Each body's ten inertial parameters are its 4×4 pseudo-inertia
    $P = \begin{bmatrix}\Sigma & mc \\ mc^T & m\end{bmatrix}$ in its own frame
    (`bundledyn.identify.pseudo_inertia`); the system's metric is linear in them.

    `fixed_centres` is `True` for systems whose section frame sits at the centre of mass by
    construction (the affine body): their $c$ is not a parameter.
    """

    if TYPE_CHECKING:  # pyright takes only `typing.ClassVar` itself for a class variable
        fixed_centres: ClassVar[bool]
    else:
        fixed_centres: eqx.AbstractClassVar[bool]

    @abc.abstractmethod
    def pseudo_inertias(self) -> Float[Array, "n 4 4"]:
        """The bodies' pseudo-inertias, shape `(n, 4, 4)`, in body order."""

    @abc.abstractmethod
    def with_pseudo_inertias(self, P: Float[Array, "n 4 4"]) -> "AbstractInertialSystem":
        """The same system with the bodies' pseudo-inertias `P`, shape `(n, 4, 4)`."""


def autodiff_metric_jet(system: AbstractSystem, q) -> DenseMetricJet:
    r"""The metric jet of any system by forward-mode autodiff of its `metric`.

    **Arguments:**

    - `system`: the system; `q`: shape coordinates, shape `(d,)`.

    **Returns:**

    A `DenseMetricJet` holding $G(q)$ and every $\partial G/\partial q_k$.
    """
    return DenseMetricJet(system.metric(q), jnp.moveaxis(jax.jacfwd(system.metric)(q), -1, 0))
