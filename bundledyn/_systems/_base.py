"""The abstract mechanical system: an invariant metric in a local trivialization."""

import abc

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._metric_jet import AbstractMetricJet, DenseMetricJet


class AbstractSystem(eqx.Module):
    """A mechanical system whose configuration space is a principal SE(3) bundle.

    In a local trivialization $s = g \\cdot r(q)$ (seed 004, §2) a system is known by its
    invariant kinetic-energy metric. With $\\xi = g^{-1}\\dot g$ the body velocity of the
    section frame and $\\dot q$ the shape velocity,

    $$T = \\tfrac12 [\\xi; \\dot q]^T G(q) [\\xi; \\dot q], \\quad
      G = \\begin{bmatrix} I_r & B \\\\ B^T & M \\end{bmatrix}.$$

    Everything else (locked inertia, connection, shape metric, curvature, the equations
    (2.6)–(2.7)) follows from `metric`. Subclasses give `shape_dim` and `metric`; they may
    override `metric_and_derivative` or `metric_jet` with a closed form.
    """

    @property
    @abc.abstractmethod
    def shape_dim(self) -> int:
        """The number $d$ of shape coordinates $q$ (static)."""

    @abc.abstractmethod
    def metric(self, q: Float[Array, " d"]) -> Float[Array, "6+d 6+d"]:
        """The metric $G(q)$ of the kinetic energy in the trivialization variables $(\\xi, \\dot q)$.

        **Arguments:**

        - `q`: shape coordinates, shape `(d,)`.

        **Returns:**

        $G(q)$, symmetric positive definite, shape `(6 + d, 6 + d)`.
        """

    def metric_and_derivative(self, q):
        """$G(q)$ and its partial derivatives $\\partial G / \\partial q_k$.

        **Arguments:**

        - `q`: shape coordinates, shape `(d,)`.

        **Returns:**

        A pair `(G, dG)` with `G` of shape `(6+d, 6+d)` and `dG[k]` $= \\partial G/\\partial q_k$,
        shape `(d, 6+d, 6+d)` (derivative index first, so that contractions are batched
        matrix products). The default is forward-mode autodiff of `metric`.
        """
        return self.metric(q), jnp.moveaxis(jax.jacfwd(self.metric)(q), -1, 0)

    def metric_jet(self, q) -> AbstractMetricJet:
        """The metric and its first derivative at $q$, for the contractions (2.6)–(2.7) use.

        **Arguments:**

        - `q`: shape coordinates, shape `(d,)`.

        **Returns:**

        An `AbstractMetricJet`; the default stores `metric_and_derivative(q)`.
        """
        return DenseMetricJet(*self.metric_and_derivative(q))
