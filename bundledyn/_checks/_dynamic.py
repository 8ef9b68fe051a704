"""Dynamic checks: the same motion seen from two frames (Theorems 2.2 and 3.4, by simulation)."""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from .. import lie
from .._effects import Gravity
from .._frames import AbstractFrame, Boosted, FreeFalling
from .._scene import Scene
from .._simulate import simulate
from .._state import State
from .._systems._base import AbstractSystem


class Discrepancy(eqx.Module):
    r"""How far two simulations of one motion, seen from the same frame, end up apart.

    **Fields:**

    - `shape`: the largest $|q_1(t) - q_2(t)|$ over the saved times.
    - `pose`: the largest $|\log(g_1(t)^{-1} g_2(t))|$ over the saved times (rotation in
      radians and translation in the system's length unit, in one twist norm).
    """

    shape: Float[Array, ""]
    pose: Float[Array, ""]


def _saved_times(t1, points):
    return jnp.linspace(0.0, t1, points)


def _discrepancy(reference: Scene, observed: Scene, states, frame: AbstractFrame, ts, options):
    """Simulate `reference` from `states[0]` and `observed` from `states[1]`, then see the latter
    from `frame` (by $M(t)^{-1}$) and compare it with the former.

    The two scenes have one structure, so both motions run in one `vmap` of one compiled solve.
    """
    saveat = diffrax.SaveAt(ts=ts)
    scenes, states = (
        jax.tree.map(lambda *x: jnp.stack(x), *pair) for pair in ((reference, observed), states)
    )
    runs = eqx.filter_vmap(
        lambda scene, state: simulate(scene, state, ts[-1], saveat=saveat, **options)
    )(scenes, states)
    M_inv = lie.se3_inv(jax.vmap(frame.motion)(ts))
    relative = lie.se3_inv(runs.g[0]) @ M_inv @ runs.g[1]
    # The norm after the max: at t0 the two poses agree exactly, and the gradient of a norm
    # at 0 is NaN even where `max` does not pick it. Double `where`: 0 when all agree.
    squared = jnp.max(jnp.sum(lie.se3_log(relative) ** 2, axis=-1))
    apart = squared > 0.0
    pose = jnp.where(apart, jnp.sqrt(jnp.where(apart, squared, 1.0)), 0.0)
    shape = jnp.max(jnp.abs(runs.q[0] - runs.q[1]), initial=0.0)
    return Discrepancy(shape, pose)


def boost_discrepancy(
    system: AbstractSystem,
    state: State,
    velocity: Float[Array, "3"],
    t1,
    *,
    effects=(),
    points: int = 11,
    **options,
) -> Discrepancy:
    r"""Theorem 2.2 by simulation: a motion seen from a boosted frame against the same initial state in the Galilean frame.

    The frame $\mathcal R'$ translates with constant `velocity` $u$, $M(t) = (1, tu)$. From
    $\mathcal R'$ the system starts in `state`; in $\mathcal R$ that is the same pose with
    velocity $\mathbf V = u + \mathbf W$. The true motion is integrated in $\mathcal R$ and seen
    from $\mathcal R'$ by $M(t)^{-1}$; the Galilean equations (2.6) are integrated from `state`
    as if $\mathcal R'$ were the Galilean frame. The two agree to the solver's tolerance iff the
    frame terms of (2.9)–(2.10) vanish, i.e. under Theorem 2.2's conditions; otherwise they
    separate, more so the faster the boost (`boost_terms` gives the initial rate).

    **Arguments:**

    - `system`: any system; `state`: the initial state seen from $\mathcal R'$.
    - `velocity`: $u$, `(3,)`; `t1`: the duration.
    - `effects`: effects acting in both frames (e.g. a model's joint springs and dampers).
    - `points`: number of equally spaced times compared (static).
    - `options`: passed to `simulate` (`solver`, `rtol`, `atol`, `max_steps`, ...).

    **Returns:**

    A `Discrepancy`.
    """
    velocity = jnp.asarray(velocity, dtype=state.xi.dtype)
    boost = jnp.concatenate([jnp.zeros(3, velocity.dtype), velocity])
    xi_true = state.xi + lie.Ad(lie.se3_inv(state.g)) @ boost
    seen_from_R = State(state.g, state.q, xi_true, state.qdot)
    ts = _saved_times(t1, points)
    scene = Scene(system, effects)
    return _discrepancy(scene, scene, (state, seen_from_R), Boosted(velocity), ts, options)


def gravity_discrepancy(
    system: AbstractSystem,
    gravity: Gravity,
    state: State,
    t1,
    *,
    effects=(),
    points: int = 11,
    **options,
) -> Discrepancy:
    r"""Theorem 3.4 by simulation: the motion under `gravity` seen from a freely falling frame against the motion without gravity.

    The frame falls with $M(t) = \exp(z(t)\chi)$, $\ddot z = g$, $z(0) = \dot z(0) = 0$
    (`FreeFalling(gravity.g, gravity.direction)`). Under Theorem 2.2's conditions, and when
    the gravitational mass and centre equal the inertial ones, the two motions are the same
    (seed 004, §3). A `Gravity` with `gravitational_mass` or `centre_offset` set apart breaks
    the equality, as the seed's remark says.

    **Arguments:**

    - `system`: any system; `gravity`: a `Gravity` effect; `state`: the initial state.
    - `t1`, `effects`, `points`, `options`: as in `boost_discrepancy`.

    **Returns:**

    A `Discrepancy`.
    """
    frame = FreeFalling(gravity.g, gravity.direction)
    ts = _saved_times(t1, points)
    # Gravity of strength 0 is no gravity (its forces are exact zeros), in the same structure.
    weightless = eqx.tree_at(lambda e: e.g, gravity, jnp.zeros_like(gravity.g))
    effects = tuple(effects)
    reference = Scene(system, (*effects, weightless))
    observed = Scene(system, (*effects, gravity))
    return _discrepancy(reference, observed, (state, state), frame, ts, options)
