"""`galilean_invariance`: Theorems 2.2 and 2.3 on a batch of sampled shapes, in one compiled call."""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.core import Tracer
from jax.sharding import Mesh

from .._batches import DeviceBatch, vmap_over_devices
from .._precision import default_residual_tolerance, warn_in_callers_code
from .._systems._base import AbstractSystem
from ._conditions import invariance_residuals

CONDITIONS = (
    ("(a)", "C(s)(U, X) = 0: the frozen system's inertial forces are objective"),
    ("(b)", "∇J(s)(U, X) = 0 along horizontal directions"),
    ("(c)", "J(s)(U, X) = 0 for X in the span of the curvature values"),
)
PROPERTIES = (
    ("1.", "J(X, Y) = m X(c)·Y(c) + l(ω_X)·ω_Y (rigid when frozen)"),
    ("2.", "m constant; c fixed along horizontal curves"),
    ("3.", "curvature values are rotations about c"),
)


class InvarianceReport(eqx.Module):
    """The outcome of `galilean_invariance`: the worst residual of each condition and where.

    **Fields:**

    - `system_name`: the checked system's class name.
    - `shapes`: the sampled shapes, `(n, d)`.
    - `conditions`: residuals of Theorem 2.2 (a), (b), (c) at every shape, `(n, 3)`.
    - `properties`: residuals of Theorem 2.3's properties 1, 2, 3 at every shape, `(n, 3)`
      (the same statements in the form of Lemmas 1–2; they fail together with (a)–(c)).
    - `mass`: the total mass at the first shape.
    - `tolerance`: the relative residual above which a condition counts as broken.
    """

    system_name: str
    shapes: np.ndarray
    conditions: np.ndarray
    properties: np.ndarray
    mass: float
    tolerance: float

    @property
    def worst(self) -> np.ndarray:
        """The worst residual of (a), (b), (c), shape `(3,)`."""
        return self.conditions.max(axis=0, initial=0.0)

    @property
    def failed(self) -> tuple[str, ...]:
        """The conditions of Theorem 2.2 broken somewhere, e.g. `("(b)", "(c)")`."""
        return tuple(
            name for (name, _), w in zip(CONDITIONS, self.worst, strict=True) if w > self.tolerance
        )

    @property
    def passed(self) -> bool:
        """Whether (a), (b) and (c) hold to `tolerance` at every sampled shape."""
        return not self.failed

    def __str__(self) -> str:
        n = self.shapes.shape[0]
        verdict = "PASSED" if self.passed else "FAILED: " + ", ".join(self.failed)
        lines = [
            f"Galilean invariance of {self.system_name} (m = {self.mass:.6g}) on {n} sampled "
            f"shapes, tolerance {self.tolerance:.0e}: {verdict}",
            f"  {'':6}{'condition':66}{'worst':>10}  at shape",
        ]
        for title, names, residuals in (
            ("Theorem 2.2", CONDITIONS, self.conditions),
            ("Theorem 2.3", PROPERTIES, self.properties),
        ):
            lines.append(f"  {title}")
            for (name, text), column in zip(names, residuals.T, strict=True):
                where = int(np.argmax(column)) if n else 0
                mark = "  " if column.max(initial=0.0) <= self.tolerance else "✗ "
                shape = np.array2string(self.shapes[where], precision=3) if n else "-"
                lines.append(
                    f"  {mark}{name:4}{text:66}{column.max(initial=0.0):10.1e}  #{where} {shape}"
                )
        return "\n".join(lines)


@functools.cache
def _battery(devices: tuple) -> DeviceBatch:
    """`invariance_residuals` over a batch of shapes, spread over `devices`."""
    mesh = Mesh(np.array(devices), ("shapes",))
    return vmap_over_devices(invariance_residuals, in_axes=(None, 0), mesh=mesh)


@eqx.filter_jit
def _mass(system, q):
    return jnp.trace(system.metric(q)[3:6, 3:6]) / 3.0


def _tolerance(tolerance, dtype) -> float:
    if tolerance is None:
        return default_residual_tolerance(dtype)
    if not tolerance > 0:
        raise ValueError(f"the tolerance must be positive, got {tolerance}.")
    eps = float(jnp.finfo(dtype).eps)
    if tolerance < 1e3 * eps:
        warn_in_callers_code(
            f"a residual tolerance of {tolerance:g} is below 1000 times {jnp.dtype(dtype).name}'s "
            f"rounding error {eps:.1e}: valid models can fail by rounding alone; call "
            "`bundledyn.enable_x64()` before building the model, or leave `tolerance` at its "
            "default."
        )
    return float(tolerance)


def galilean_invariance(
    system: AbstractSystem,
    key,
    n: int = 256,
    *,
    shapes=None,
    scale: float = 1.0,
    tolerance: float | None = None,
) -> InvarianceReport:
    r"""Check that `system` is an acceptable mechanical model: Theorems 2.2 and 2.3 on sampled shapes.

    Samples `n` shapes uniformly in $[-\text{scale}, \text{scale}]^d$ and evaluates
    `galilean_conditions` and `rigid_structure` at all of them in one vmapped call, spread
    over the local devices (`vmap_over_devices`).
    The translations $U$, twists $X$ and shape directions $\delta q$ the theorems quantify over
    enter through bases (the conditions are linear in each), so only shapes are sampled.

    **Arguments:**

    - `system`: any system.
    - `key`: a JAX PRNG key for the shapes.
    - `n`: number of shapes.
    - `shapes`: optional `(n, d)` array of shapes to check instead of sampling.
    - `scale`: half-width of the sampling box, in the shape coordinates' units.
    - `tolerance`: largest relative residual that counts as zero; by default it follows the
      working precision (`default_residual_tolerance`: 1e-10 in float64, 1e-4 in float32).
      One below about $1000\varepsilon$ of the working precision warns: rounding alone can
      exceed it.

    **Returns:**

    An `InvarianceReport`: `report.passed`, `report.failed`, `report.worst`, and a readable
    `str(report)`.
    """
    if any(isinstance(leaf, Tracer) for leaf in jax.tree.leaves((system, key, shapes))):
        raise TypeError(
            "`galilean_invariance` returns a report of concrete values, so it cannot run under "
            "`jax.vmap` or `jax.jit`. Batch its arrays instead: `jax.vmap` over "
            "`bundledyn.checks.galilean_conditions(system, q)` and `rigid_structure(system, q)` "
            "(their `.residuals`) checks many systems or shapes in one call; or call it once per "
            "system."
        )
    d = system.shape_dim
    if shapes is None:
        shapes = scale * jax.random.uniform(key, (n, d), minval=-1.0, maxval=1.0)
    shapes = jnp.asarray(shapes, dtype=float)
    if shapes.ndim != 2 or shapes.shape[1] != d or shapes.shape[0] == 0:
        raise ValueError(
            f"`galilean_invariance` needs shapes of shape (n >= 1, {d}), got {shapes.shape}."
        )
    conditions, properties = _battery(tuple(jax.local_devices()))(system, shapes)
    mass = _mass(system, shapes[0])
    tolerance = _tolerance(tolerance, conditions.dtype)
    return InvarianceReport(
        type(system).__name__,
        np.asarray(shapes),
        np.asarray(conditions),
        np.asarray(properties),
        float(mass),
        tolerance,
    )
