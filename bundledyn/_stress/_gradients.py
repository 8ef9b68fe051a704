"""Gradients of a rollout's loss at the singular points of the rotation maps."""

import jax
import jax.numpy as jnp
import numpy as np

from .. import lie
from .._scene import Scene
from .._simulate import simulate
from .._state import State
from .._systems._rigid_body import RigidBody
from ._row import StressRow

RTOL = 1e-12
# A NumPy constant: a JAX array made at import would start JAX's backend (and in float32).
PROBE = np.array([[0.3, -0.7, 0.2, 0.1], [0.5, 0.1, -0.4, 0.3], [-0.2, 0.6, 0.9, -0.1]])


def _relative(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300))


def _final_pose_loss(scene: Scene, state: State, t1: float):
    r"""$\theta \mapsto \langle P, g(t_1)\rangle + |q(t_1)|^2$ of the initial body twist $\theta$,
    with a fixed probe $P$ of the pose's top three rows."""

    def loss(xi0):
        traj = simulate(scene, with_twist(state, xi0), t1, rtol=RTOL, atol=RTOL)
        return jnp.sum(PROBE * traj.g[-1, :3]) + jnp.sum(traj.q[-1] ** 2)

    return loss


def with_twist(state: State, xi) -> State:
    """`state` with body twist `xi`."""
    return State(state.g, state.q, xi, state.qdot)


def central_differences(f, x, h: float = 1e-6):
    """The gradient of scalar `f` at `x` by central differences, one call of `f` a probe
    (a jitted `f` then compiles once, where a `vmap` of it would compile again)."""
    steps = h * jnp.eye(x.shape[0], dtype=x.dtype)
    return jnp.stack([(f(x + e) - f(x - e)) / (2 * h) for e in steps])


def model_gradients(scene: Scene, state: State, *, t1: float = 1.0) -> tuple[StressRow, ...]:
    r"""`jax.grad` of a loss of the final pose and shape, in the initial body twist, at
    $\xi_0 = 0$ exactly and at $|\omega_0| = 10^{-9}$, against central differences.

    Guards against MJX and Brax, whose gradients at zero rotation came out NaN or silently
    zero (a norm differentiated at the origin).

    **Arguments:**

    - `scene`, `state`: the model and its starting pose and shape (its twist is replaced).
    - `t1`: the horizon.

    **Returns:**

    One row per point: the gradient's largest relative difference from central differences.
    """
    # One compiled function serves both: the differences read its value.
    value_and_grad = jax.jit(jax.value_and_grad(_final_pose_loss(scene, state, t1)))
    rows = []
    for label, xi0 in (
        ("ξ0 = 0", jnp.zeros(6)),
        ("|ω0| = 1e-9", jnp.array([6e-10, -8e-10, 0.0, 0.0, 0.0, 0.0])),
    ):
        g = value_and_grad(xi0)[1]
        reference = central_differences(lambda x: value_and_grad(x)[0], xi0)
        rows.append(
            StressRow(
                "singular_gradients",
                f"rollout gradient at {label} vs central differences",
                _relative(g, reference) if np.all(np.isfinite(g)) else np.nan,
                1e-6,
                "" if np.all(np.isfinite(g)) else "the gradient is not finite",
            )  # fmt: skip
        )
    return tuple(rows)


def rigid_gradients(*, t1: float = 1.0) -> tuple[StressRow, ...]:
    r"""Rollout gradients of an asymmetric body at its singular points, against closed forms.

    - At $\omega_0 = 0$ and $|\omega_0| = 10^{-9}$: Euler's equations are quadratic in
      $\omega$, so to first order $R(t_1) = \exp(t_1\hat\omega_0)$ and
      $\partial\langle P, R(t_1)\rangle/\partial\omega_{0,i} = t_1\langle P, \hat e_i\rangle$.
    - At $\theta(t_1) \to \pi$, the logarithm's branch: a steady spin $\omega_0 = \omega e_3$
      about a principal axis turns by $\theta = \omega t_1$, so
      $\partial|\log R(t_1)|^2/\partial\omega_0 = (0, 0, 2\theta t_1)$ (a sideways
      $\delta\omega$ tilts the axis without changing the angle to first order).

    Guards against MJX and Brax (NaN or zero gradients at zero rotation) and against logs
    that lose half their digits near $\pi$ (arccos of the trace).

    **Returns:**

    One row per point: the gradient's largest relative difference from the closed form.
    """
    body = RigidBody(1.0, jnp.zeros(3), jnp.diag(jnp.array([1.0, 2.0, 3.0])))
    scene, state = Scene(body), State(jnp.eye(4))

    def final_rotation(omega):
        xi0 = jnp.concatenate([omega, jnp.zeros(3)])
        return simulate(scene, with_twist(state, xi0), t1, rtol=RTOL, atol=RTOL).g[-1, :3, :3]

    probe = jax.jit(jax.grad(lambda w: jnp.sum(PROBE[:, :3] * final_rotation(w))))
    squared_angle = jax.jit(jax.grad(lambda w: jnp.sum(lie.so3_log(final_rotation(w)) ** 2)))
    linear = t1 * jnp.stack([jnp.sum(PROBE[:, :3] * lie.so3_hat(e)) for e in jnp.eye(3)])
    rows = []
    for label, omega in (
        ("ω0 = 0", jnp.zeros(3)),
        ("|ω0| = 1e-9", jnp.array([6e-10, -8e-10, 0.0])),
    ):
        rows.append(_closed_form_row(f"rollout gradient at {label}", probe(omega), linear, 1e-8))
    for gap in (1e-6, 1e-9):
        theta = np.pi - gap
        g = squared_angle(jnp.array([0.0, 0.0, theta / t1]))
        rows.append(_closed_form_row(f"gradient of |log R|² at θ = π - {gap:.0e}", g,
                                     jnp.array([0.0, 0.0, 2 * theta * t1]), 1e-8))  # fmt: skip
    return tuple(rows)


def _closed_form_row(shows, value, closed_form, bound) -> StressRow:
    finite = bool(np.all(np.isfinite(value)))
    error = _relative(value, closed_form) if finite else np.nan
    return StressRow("singular_gradients", shows + " vs closed form", error, bound,
                     "" if finite else "the gradient is not finite")  # fmt: skip
