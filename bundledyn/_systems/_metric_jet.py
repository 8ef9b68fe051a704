"""The metric and its first derivative at one shape, read through the contractions the equations use."""

import abc
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float


class AbstractMetricJet(eqx.Module):
    r"""The 1-jet of the metric at a shape $q$: $G(q)$ and the derivatives $\partial_k G$.

    (2.6)–(2.7) (seed 004) never need the whole tensor $\partial_k G$, only its contractions
    with the velocities: the derivative along the shape velocity and a few covectors
    $k \mapsto x^T \partial_k G\, y$ (`along`, `along_applied`, `forms`). A system with
    structure (a tree of bodies) computes these directly, at the cost of the metric, instead
    of $d$ derivatives of a matrix.

    A jet gives `metric` and every method. One without a closed form for some of them gives
    those from the others, as `DenseMetricJet` does: `X @ self.along(u)` for
    `along_applied`, `jax.jvp` of `forms` along `jet_along(u)` for `forms_along`, the two
    separately for `along_both`, `along` of each unit vector for `derivative`.
    """

    metric: eqx.AbstractVar[Float[Array, "6+d 6+d"]]

    @abc.abstractmethod
    def along(self, u: Float[Array, " d"]) -> Float[Array, "6+d 6+d"]:
        r"""$\partial_u G = \sum_k u_k\,\partial G/\partial q_k$, the derivative along a shape velocity."""

    @abc.abstractmethod
    def along_applied(
        self, u: Float[Array, " d"], X: Float[Array, "m 6+d"]
    ) -> Float[Array, "m 6+d"]:
        r"""$(\partial_u G)\, x_i$ for each velocity $x_i$ (row of `X`): all that (2.6)–(2.7)
        need of the derivative along the shape velocity (`X @ self.along(u)` without a
        closed form)."""

    @abc.abstractmethod
    def forms(self, X: Float[Array, "m 6+d"]) -> Float[Array, "m m d"]:
        r"""The covectors $k \mapsto x_i^T (\partial G/\partial q_k)\, x_j$ of every pair of velocities.

        **Arguments:**

        - `X`: $m$ velocities $x_i = [\xi_i; \dot q_i]$ as rows.

        **Returns:**

        `F[i, j, k]` $= x_i^T \partial_k G\, x_j$, symmetric in `i, j`.
        """

    @abc.abstractmethod
    def forms_along(
        self,
        u: Float[Array, " d"],
        X: Float[Array, "m 6+d"],
        jet_along: Callable[[Float[Array, " d"]], "AbstractMetricJet"],
    ) -> Float[Array, "m m d"]:
        r"""$\partial_u$ of `forms(X)` at fixed velocities: $x_i^T\,\partial_u\partial_k G\,x_j$.

        **Arguments:**

        - `u`: a shape velocity, shape `(d,)`.
        - `X`: as in `forms`.
        - `jet_along`: the jet's own derivative along $u$ (`jax.jvp` of the system's
          `metric_jet`). Without a closed form, push it forward through `forms`; a jet
          with a closed form does not call it.

        **Returns:**

        Shape `(m, m, d)`, as `forms`.
        """

    @abc.abstractmethod
    def along_both(
        self,
        u: Float[Array, " d"],
        X: Float[Array, "m 6+d"],
        jet_along: Callable[[Float[Array, " d"]], "AbstractMetricJet"],
    ) -> tuple[Float[Array, "m 6+d"], Float[Array, "m m d"]]:
        r"""`along_applied(u, X)` and `forms_along(u, X, jet_along)` together, which a jet
        may compute from the same rates (else the two calls)."""

    @abc.abstractmethod
    def derivative(self) -> Float[Array, "d 6+d 6+d"]:
        r"""All partial derivatives, `dG[k]` $= \partial G/\partial q_k$ (without the tensor
        at hand, one `along` per coordinate)."""


# The contractions of a jet from its others, for the jets without closed forms of them.


def along_applied_by_along(
    jet: AbstractMetricJet, u: Float[Array, " d"], X: Float[Array, "m 6+d"]
) -> Float[Array, "m 6+d"]:
    r"""`jet.along_applied(u, X)` as `X @ jet.along(u)`: the matrix $\partial_u G$ applied."""
    return X @ jet.along(u)


def forms_along_by_jvp(
    jet: AbstractMetricJet,
    u: Float[Array, " d"],
    X: Float[Array, "m 6+d"],
    jet_along: Callable[[Float[Array, " d"]], AbstractMetricJet],
) -> Float[Array, "m m d"]:
    r"""`jet.forms_along(u, X, jet_along)` by pushing `jet_along(u)` forward through `forms`."""
    return jax.jvp(lambda jet: jet.forms(X), (jet,), (jet_along(u),))[1]


def along_both_separately(
    jet: AbstractMetricJet,
    u: Float[Array, " d"],
    X: Float[Array, "m 6+d"],
    jet_along: Callable[[Float[Array, " d"]], AbstractMetricJet],
) -> tuple[Float[Array, "m 6+d"], Float[Array, "m m d"]]:
    """`jet.along_both(u, X, jet_along)` as its two contractions, each on its own."""
    return jet.along_applied(u, X), jet.forms_along(u, X, jet_along)


def derivative_by_along(jet: AbstractMetricJet) -> Float[Array, "d 6+d 6+d"]:
    r"""`jet.derivative()` as `jet.along` of each unit shape velocity."""
    d = jet.metric.shape[0] - 6
    return jax.vmap(jet.along)(jnp.eye(d, dtype=jet.metric.dtype))


class DenseMetricJet(AbstractMetricJet):
    r"""A metric jet stored as the full derivative tensor (any system; autodiff by default).

    **Arguments:**

    - `metric`: $G(q)$, shape `(6+d, 6+d)`.
    - `dG`: `dG[k]` $= \partial G/\partial q_k$, shape `(d, 6+d, 6+d)`.
    """

    metric: Float[Array, "6+d 6+d"]
    dG: Float[Array, "d 6+d 6+d"]

    def along(self, u):
        return jnp.tensordot(u, self.dG, 1)

    def along_applied(self, u, X):
        return along_applied_by_along(self, u, X)

    def forms(self, X):
        return jnp.einsum("ia,kab,jb->ijk", X, self.dG, X)

    def forms_along(self, u, X, jet_along):
        return forms_along_by_jvp(self, u, X, jet_along)

    def along_both(self, u, X, jet_along):
        return along_both_separately(self, u, X, jet_along)

    def derivative(self):
        return self.dG
