"""Why a solve ran out of steps: the stiffest mode of the field at the initial state."""

import math

import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

from ._scene import Scene
from ._state import State
from ._term import SceneTerm

__all__ = ["stiffest_rate", "out_of_steps_advice"]

# The stability boundary of the explicit Runge–Kutta methods of order 4 to 8 on the
# imaginary axis, h|λ| ≲ 3 (Hairer & Wanner, Solving ODEs II, §IV.2): a step longer than
# 3/|λ| makes the fastest oscillation grow, and the error control rejects it.
_STABLE_STEP = 3.0


def stiffest_rate(scene: Scene, state: State, t=0.0) -> float:
    r"""The largest $|\lambda|$ of the field's Jacobian $\partial\dot x/\partial x$ at `state`.

    $x$ is what the scene's mode integrates besides the pose (shape, velocities); at rest
    under springs $K$ and shape metric $J$ its eigenvalues are $\pm i\omega$ with
    $\omega^2$ the eigenvalues of $J^{-1}K$, so this is the fastest mode's angular
    frequency (rad/s), and $2\pi/|\lambda|$ its period.

    **Arguments:**

    - `scene`: the scene.
    - `state`: the state to linearize about.
    - `t`: its time.

    **Returns:**

    $\max|\lambda|$, in 1/s.
    """
    term = SceneTerm(scene)
    g, x = term.encode(t, state)
    flat, unflatten = ravel_pytree(x)

    def rate(flat):
        _, x_dot = term.body_vf(t, (g, unflatten(flat)), None)
        return ravel_pytree(x_dot)[0]

    jacobian = jax.jit(jax.jacfwd(rate))(flat)
    return float(jnp.max(jnp.abs(jnp.linalg.eigvals(jacobian)), initial=0.0))


def out_of_steps_advice(scene: Scene, state: State, t0, t1, max_steps) -> str:
    """What to do when a solve of `scene` from `state` ran out of its `max_steps`: the
    stiffest mode's period, the steps an explicit solver needs for it, and the alternative.

    **Arguments:**

    - `scene`, `state`, `t0`, `t1`, `max_steps`: the solve's.

    **Returns:**

    A paragraph for the error message; empty where the field cannot be linearized at the
    state, since the diagnosis must not replace the error it explains.
    """
    try:
        rate = stiffest_rate(scene, state, t0)
    except Exception:  # noqa: BLE001 (any failure of the diagnosis leaves diffrax's message)
        return ""
    if rate == 0.0:
        return "The field has no oscillation or decay at the initial state to blame."
    needed = math.ceil(abs(float(t1) - float(t0)) * rate / _STABLE_STEP)
    return (
        f"The stiffest mode at the initial state has |λ| = {rate:.4g}/s (period "
        f"{2 * np.pi / rate:.3g} s): an explicit solver needs steps below about "
        f"{_STABLE_STEP / rate:.2g} s there, about {needed} for this horizon against "
        f"max_steps = {max_steps}. Raise max_steps past that, or step over the fast mode with "
        "the implicit `VariationalMidpoint` (fixed steps: `dt0` and "
        "`diffrax.ConstantStepSize()`), stable at any step."
    )
