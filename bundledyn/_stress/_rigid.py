"""Cases on one free rigid body: Dzhanibekov flips, high spin, long horizons, a thin rod."""

import diffrax
import jax.numpy as jnp
import numpy as np

from .._scene import Scene
from .._simulate import simulate
from .._state import State
from .._systems._rigid_body import RigidBody
from ._conservation import energy_row, momentum_row, orthogonality_row
from ._row import StressRow

# Principal moments I1 < I2 < I3 of the asymmetric bodies the cases spin.
MOMENTS = (1.0, 2.0, 3.0)


def _spin(moments, omega, t1, *, rtol, saveat=None, max_steps=16384):
    body = RigidBody(1.0, jnp.zeros(3), jnp.diag(jnp.asarray(moments, dtype=float)))
    state = State(jnp.eye(4), xi=jnp.concatenate([jnp.asarray(omega, dtype=float), jnp.zeros(3)]))
    return simulate(Scene(body), state, jnp.asarray(t1), rtol=rtol, atol=rtol, saveat=saveat,
                    max_steps=max_steps)  # fmt: skip


def _elliptic_k(k2: float) -> float:
    """The complete elliptic integral $K(k)$, from the arithmetic-geometric mean."""
    a, b = 1.0, np.sqrt(1.0 - k2)
    while abs(a - b) > 1e-16 * a:
        a, b = (a + b) / 2.0, np.sqrt(a * b)
    return np.pi / (2.0 * a)


def flip_interval(moments, omega) -> float:
    r"""The time between two sign changes of $\omega_2$ in the torque-free motion: $2K(k)/\lambda$.

    Landau & Lifshitz, Mechanics §37: with $I_1 < I_2 < I_3$, $2E = \sum I_i\omega_i^2$ and
    $M^2 = \sum I_i^2\omega_i^2$, $\omega_2 \propto \operatorname{sn}(\lambda t, k)$; for
    $M^2 > 2EI_2$, $\lambda^2 = (I_3 - I_2)(M^2 - 2EI_1)/(I_1I_2I_3)$ and
    $k^2 = (I_2 - I_1)(2EI_3 - M^2)/((I_3 - I_2)(M^2 - 2EI_1))$; for $M^2 < 2EI_2$ the
    suffixes 1 and 3 are exchanged.
    """
    I1, I2, I3 = moments
    w = np.asarray(omega, dtype=float)
    two_e, m2 = float(np.dot(moments, w**2)), float(np.dot(np.square(moments), w**2))
    if m2 < two_e * I2:
        I1, I3 = I3, I1
    lam2 = (I3 - I2) * (m2 - two_e * I1) / (I1 * I2 * I3)
    k2 = (I2 - I1) * (two_e * I3 - m2) / ((I3 - I2) * (m2 - two_e * I1))
    return 2.0 * _elliptic_k(k2) / np.sqrt(lam2)


def sign_changes(ts, values, rates) -> np.ndarray:
    """The times where `values` changes sign, each refined by one Newton step with `rates`
    from the nearer saved point (at a zero of sn the second derivative vanishes too)."""
    ts, values, rates = (np.asarray(a, dtype=float) for a in (ts, values, rates))
    i = np.nonzero(np.sign(values[1:]) != np.sign(values[:-1]))[0]
    nearer = np.where(np.abs(values[i]) < np.abs(values[i + 1]), i, i + 1)
    return ts[nearer] - values[nearer] / rates[nearer]


def dzhanibekov(*, t1: float = 100.0, rtol: float = 1e-10) -> tuple[StressRow, ...]:
    r"""A body spun about its intermediate axis flips over and back: flip times against the
    elliptic-function closed form (`flip_interval`), energy and momentum to tolerance.

    Guards against MJX's Euler/implicitfast integrators, where a tumbling box gained 35 %
    of its energy in 20 s and went NaN at 108 s, and against checks of a Lie-group RK method
    that only test staying on the group (pylie's dropped coupling term passed them).

    **Arguments:**

    - `t1`: the horizon, seconds (about 6 flips per 10 s).
    - `rtol`: the solver's tolerance (atol alike).

    **Returns:**

    Rows: the largest flip-time error relative to the flip interval, energy, momentum.
    """
    omega = np.array([1e-3, 1.0, 1e-3])
    ts = jnp.linspace(0.0, t1, int(20 * t1) + 1)
    traj = _spin(MOMENTS, omega, t1, rtol=rtol, saveat=diffrax.SaveAt(ts=ts))
    w = np.asarray(traj.xi[:, :3])
    I1, I2, I3 = MOMENTS
    w2dot = (I3 - I1) * w[:, 2] * w[:, 0] / I2  # Euler's equation for the intermediate axis
    flips = sign_changes(ts, w[:, 1], w2dot)
    interval = flip_interval(MOMENTS, omega)
    n = np.arange(len(flips))
    error = np.abs(flips - flips[0] - n * interval).max() / interval if len(flips) > 2 else np.nan
    case = "dzhanibekov"
    return (
        StressRow(
            case,
            f"flip times vs the elliptic closed form ({len(flips)} flips in {t1:g} s)",
            float(error),
            1e3 * rtol,
            "" if len(flips) > 2 else "fewer than 3 flips",
        ),  # fmt: skip
        energy_row(case, traj, 1e2 * rtol),
        momentum_row(case, traj, 1e2 * rtol),
    )


def high_spin(*, rate: float = 1e4, turns: float = 1e3, rtol: float = 1e-10):
    r"""A body spinning at `rate` rad/s about a skew axis for `turns` turns: the rotation stays
    orthogonal to rounding, energy and momentum within bounds set by the tolerance alone.

    Guards against rotations that leave SO(3) at high rates (a pose integrated in its
    matrix embedding, or a quaternion, drifts with every step taken) and against energy
    errors that grow with the turns (MJX's tumbling box gained 35 % in 20 s).

    **Returns:**

    Rows: orthogonality, energy, momentum.
    """
    omega = rate * np.array([0.6, 0.0, 0.8]) + np.array([0.0, 1e-2 * rate, 0.0])
    t1 = 2 * np.pi * turns / rate
    saveat = diffrax.SaveAt(ts=jnp.linspace(0.0, t1, 1001))
    traj = _spin(MOMENTS, omega, t1, rtol=rtol, saveat=saveat, max_steps=2**20)
    case = f"high_spin {rate:.0e} rad/s"
    return (
        orthogonality_row(case, traj, 1e-13),
        energy_row(case, traj, 1e2 * rtol),
        momentum_row(case, traj, 1e2 * rtol),
    )


def long_horizon(*, t1: float = 1e4, rtol: float = 1e-12) -> tuple[StressRow, ...]:
    r"""A tumbling body over `t1` seconds (about $t_1/6$ turns): orthogonality to rounding,
    energy and momentum to a bound set by the tolerance.

    Guards against integrators whose rotation drifts off SO(3) with time (the embedding's
    error grows with the steps; exponentials of the algebra keep it at rounding).

    **Returns:**

    Rows: orthogonality, energy, momentum.
    """
    saveat = diffrax.SaveAt(ts=jnp.linspace(0.0, t1, 1001))
    traj = _spin(MOMENTS, np.array([0.3, 1.0, 0.2]), t1, rtol=rtol, saveat=saveat,
                 max_steps=2**20)  # fmt: skip
    case = f"long_horizon ({t1:.0e} s)"
    return (
        orthogonality_row(case, traj, 1e-13),
        energy_row(case, traj, 1e3 * rtol),
        momentum_row(case, traj, 1e3 * rtol),
    )
