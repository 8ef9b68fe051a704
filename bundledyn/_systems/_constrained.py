r"""Holonomic constraints among shape coordinates, solved for the dependent ones (seed 001, §54).

Constraints $f(q) = 0$ that give some shape coordinates as functions of the others,
$q = \Phi(p)$, are eliminated by taking the others, $p$, as the shape coordinates: the
configurations that satisfy them are exactly the $\Phi(p)$. The system on $p$ has the
metric pulled back by $T = \operatorname{diag}(I_6, \partial\Phi/\partial p)$,
$G_p(p) = T^T G(\Phi(p))\,T$, since $[\xi; \dot q] = T\,[\xi; \dot p]$; the constraints
are ideal (their reactions do no work on motions that keep them), so (2.6)–(2.7) for $G_p$
are the constrained motion, and every mode, solver and adjoint integrates it as any system.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ._base import AbstractSystem, autodiff_metric_jet

__all__ = ["ConstrainedSystem", "JointCoupling"]


class JointCoupling(eqx.Module):
    r"""Shape coordinates coupled by polynomials of others, as MuJoCo's joint equalities:
    $q_j - \bar q_j = \sum_{k=0}^{4} a_{jk}\,(q_i - \bar q_i)^k$ (seed 001, §54: holonomic
    constraints solved for the dependent coordinates).

    **Arguments:**

    - `shape_dim`: $d$, the number of shape coordinates $q$ (static).
    - `couplings`: a sequence of `(dependent, independent, coefficients)`: the index $j$ of
      the coordinate it sets, the index $i$ of the coordinate it follows (`None`: $q_j$ is
      held at $\bar q_j + a_{j0}$), and $(a_0, \dots, a_4)$ (fewer are padded with zeros).
      An independent coordinate must not itself be set by a coupling.
    - `reference`: $\bar q$, shape `(d,)`; default zeros (MuJoCo's `qpos0`).
    """

    shape_dim: int = eqx.field(static=True)
    dependent: tuple[int, ...] = eqx.field(static=True)
    independent: tuple[int | None, ...] = eqx.field(static=True)
    coefficients: Float[Array, "r 5"]
    reference: Float[Array, " d"]

    def __init__(self, shape_dim, couplings, reference=None):
        self.shape_dim = int(shape_dim)
        couplings = tuple(couplings)
        self.dependent = tuple(int(j) for j, _, _ in couplings)
        self.independent = tuple(None if i is None else int(i) for _, i, _ in couplings)
        rows = []
        for _, _, a in couplings:
            a = np.asarray(a, dtype=float).reshape(-1)
            if a.size > 5:
                raise ValueError(
                    f"`JointCoupling` takes at most 5 coefficients (degree 4), got {a.size}."
                )
            rows.append(np.pad(a, (0, 5 - a.size)))
        self.coefficients = jnp.asarray(np.reshape(rows, (len(rows), 5)), dtype=float)
        self.reference = (
            jnp.zeros(self.shape_dim) if reference is None else jnp.asarray(reference, float)
        )

    def __check_init__(self):
        d = self.shape_dim
        if self.reference.shape != (d,):
            raise ValueError(
                f"`JointCoupling.reference` must have shape ({d},), got {self.reference.shape}."
            )
        named = [j for j in self.dependent] + [i for i in self.independent if i is not None]
        if any(not 0 <= k < d for k in named):
            raise ValueError(f"`JointCoupling` indices must lie in [0, {d}), got {named}.")
        if len(set(self.dependent)) != len(self.dependent):
            raise ValueError("`JointCoupling` sets each dependent coordinate once.")
        followed = set(self.dependent) & {i for i in self.independent if i is not None}
        if followed:
            raise ValueError(
                f"`JointCoupling`: coordinates {sorted(followed)} are both set by a coupling "
                "and followed by one; couple each to a free coordinate instead."
            )

    @property
    def free(self) -> tuple[int, ...]:
        """The indices of the coordinates no coupling sets: those of $p$, in order (static)."""
        return tuple(k for k in range(self.shape_dim) if k not in self.dependent)

    def _set_values(self, q):
        """$\\bar q_j + \\sum_k a_{jk}(q_i - \\bar q_i)^k$ for every coupling, shape `(r,)`."""
        values = []
        for row, i in enumerate(self.independent):
            x = jnp.zeros((), q.dtype) if i is None else q[i] - self.reference[i]
            values.append(jnp.polyval(self.coefficients[row, ::-1], x))
        ref = self.reference[np.asarray(self.dependent, dtype=int)]
        return ref + jnp.stack(values) if values else ref

    def __call__(self, p: Float[Array, " m"]) -> Float[Array, " d"]:
        r"""$q = \Phi(p)$: the free coordinates `p` and the coupled ones they set."""
        q = jnp.zeros(self.shape_dim, p.dtype).at[np.asarray(self.free, dtype=int)].set(p)
        if not self.dependent:
            return q
        return q.at[np.asarray(self.dependent, dtype=int)].set(self._set_values(q))

    def residual(self, q: Float[Array, " d"]) -> Float[Array, " r"]:
        r"""$f(q)$: each coupled coordinate minus the value its coupling sets; zero on the
        constraints."""
        return q[np.asarray(self.dependent, dtype=int)] - self._set_values(q)

    def free_coordinates(self, q: Float[Array, " d"]) -> Float[Array, " m"]:
        """$p$: the free coordinates of a full shape `q`."""
        return q[np.asarray(self.free, dtype=int)]


class ConstrainedSystem(AbstractSystem):
    r"""A system whose shape coordinates are tied by holonomic constraints solved as
    $q = \Phi(p)$: the same system on the free coordinates $p$ (seed 001, §54).

    Its metric is $G_p(p) = T^T G(\Phi(p))\,T$, $T = \operatorname{diag}(I_6,
    \partial\Phi/\partial p)$, and its jet comes by forward-mode autodiff of it; the
    locked inertia is the system's, so gravity and the section frame are unchanged. States,
    trajectories and effects on the shape are in $p$; `constraints(p)` gives the full $q$.

    ```python
    gripper = bd.ConstrainedSystem(arm, bd.JointCoupling(arm.shape_dim, [(5, 4, (0.0, -1.0))]))
    ```

    **Arguments:**

    - `system`: the unconstrained system, with $d$ shape coordinates.
    - `constraints`: a `JointCoupling` of $d$ coordinates.
    """

    system: AbstractSystem
    constraints: JointCoupling

    def __check_init__(self):
        if not isinstance(self.system, AbstractSystem):
            raise ValueError(
                "`ConstrainedSystem.system` must be an AbstractSystem, got "
                f"{type(self.system).__name__}."
            )
        if not isinstance(self.constraints, JointCoupling):
            raise ValueError(
                "`ConstrainedSystem.constraints` must be a `JointCoupling`, got "
                f"{type(self.constraints).__name__}."
            )
        if self.constraints.shape_dim != self.system.shape_dim:
            raise ValueError(
                f"`ConstrainedSystem`: the coupling is of {self.constraints.shape_dim} shape "
                f"coordinates, the system has {self.system.shape_dim}."
            )

    @property
    def shape_dim(self) -> int:
        return len(self.constraints.free)

    def metric(self, q):
        full = self.constraints(q)
        d = self.system.shape_dim
        m = self.shape_dim
        J = jax.jacfwd(self.constraints)(q)
        T = jnp.block(
            [
                [jnp.eye(6, dtype=q.dtype), jnp.zeros((6, m), q.dtype)],
                [jnp.zeros((d, 6), q.dtype), J],
            ]
        )
        return T.T @ self.system.metric(full) @ T

    def metric_jet(self, q):
        return autodiff_metric_jet(self, q)

    def checked(self) -> "ConstrainedSystem":
        """The system with its unconstrained system's run-time checks."""
        return ConstrainedSystem(self.system.checked(), self.constraints)
