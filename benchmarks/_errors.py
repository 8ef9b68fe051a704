"""How far a final state is from a reference, and the time or setting at a given error."""

import bundledyn as bd


def state_parts(state):
    """`(g, q, xi, qdot)` of a `bd.State` or of such a tuple."""
    if isinstance(state, bd.State):
        return state.g, state.q, state.xi, state.qdot
    return tuple(state)


def final_state(traj):
    """`(g, q, xi, qdot)` at the end of a `bd.Trajectory`."""
    return traj.g[-1], traj.q[-1], traj.xi[-1], traj.qdot[-1]


def state_error(a, b):
    r"""The largest of $|\log(g_b^{-1}g_a)|_\infty$, $|q_a - q_b|_\infty$,
    $|\xi_a - \xi_b|_\infty$ and $|\dot q_a - \dot q_b|_\infty$ (states or tuples)."""
    import jax.numpy as jnp

    g, *rest = state_parts(a)
    g_ref, *rest_ref = state_parts(b)
    parts = [jnp.max(jnp.abs(bd.lie.se3_log(bd.lie.se3_inv(g_ref) @ g)))]
    parts += [jnp.max(jnp.abs(x - y), initial=0.0) for x, y in zip(rest, rest_ref, strict=True)]
    return float(jnp.max(jnp.stack(parts)))


def time_at_error(points, target):
    """Log–log interpolated time at `target` error over (error, time) points; None outside."""
    import numpy as np

    pts = sorted(
        ((p["error"], p["time"]["median"]) for p in points if p["error"] > 0), key=lambda x: -x[0]
    )
    for (e0, t0), (e1, t1) in zip(pts, pts[1:], strict=False):
        if e1 <= target <= e0:
            w = np.log(target / e0) / np.log(e1 / e0) if e1 != e0 else 0.0
            return float(np.exp(np.log(t0) + w * np.log(t1 / t0)))
    return None


def setting_at_error(points, target):
    """The loosest sweep setting whose error is at most `target` (the most accurate if none)."""
    ok = [p for p in points if p["error"] <= target] or [min(points, key=lambda p: p["error"])]
    return max(ok, key=lambda p: p["error"])["setting"]
