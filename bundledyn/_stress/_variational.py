"""A long run of the variational integrator: bounded energy error, momentum to rounding."""

import diffrax
import jax.numpy as jnp
import numpy as np

from .._scene import Scene
from .._simulate import simulate
from .._solver._variational import VariationalMidpoint
from .._state import State
from ._conservation import momentum_row
from ._models import chain
from ._row import StressRow
from ._start import XI0

# Newton iterations per step: the default 8 leaves a residual of about 1e-14 a step, which
# 1e5 steps accumulate to 1e-9 in the momentum; 12 converge to rounding.
ITERATIONS = 12


def energy_trend(ts, energy) -> tuple[float, float]:
    """The change over the last half that a straight line fitted there gives, and the
    energy error's peak-to-peak over the whole run."""
    ts, energy = np.asarray(ts, dtype=float), np.asarray(energy, dtype=float)
    half = len(ts) // 2
    slope = np.polyfit(ts[half:], energy[half:], 1)[0]
    return abs(slope) * (ts[-1] - ts[half]), float(np.ptp(energy))


def variational_long_run(*, steps: int = 100_000, dt: float = 0.01) -> tuple[StressRow, ...]:
    r"""`steps` steps of `VariationalMidpoint` on a free three-link chain.

    A symplectic integrator's energy error oscillates without a trend; a non-symplectic one
    (or a wrong one) drifts. The case fits a line to the energy over the last half of the
    run: its change there must be below a tenth of the error's peak-to-peak. The spatial
    momentum is conserved by the discrete equations exactly, so to rounding: each step may
    add about ε, so the bound is $10N\varepsilon$ (the Newton iteration run to rounding).

    Guards against MJX's semi-implicit Euler on a tumbling box (35 % energy gained in 20 s)
    and against "symplectic" claims checked over a few periods only.

    **Returns:**

    Rows: the trend against the peak-to-peak, the energy error, the momentum.
    """
    system = chain((1.0, 1.5, 2.0))
    state = State(jnp.eye(4), jnp.array([0.3, -0.5]),
                  jnp.asarray(XI0), jnp.array([1.0, -2.0]))  # fmt: skip
    t1 = steps * dt
    traj = simulate(Scene(system), state, t1, solver=VariationalMidpoint(iterations=ITERATIONS), dt0=dt,
                    saveat=diffrax.SaveAt(steps=True), max_steps=steps)  # fmt: skip
    energy = np.asarray(traj.energy())
    trend, spread = energy_trend(traj.ts, energy)
    case = f"variational_long_run ({steps:.0e} steps)"
    return (
        StressRow(
            case, "energy trend over the last half / peak-to-peak error", trend / spread, 0.1
        ),  # fmt: skip
        StressRow(
            case,
            "energy, relative change (second order, h = 0.01)",
            float(np.abs(energy - energy[0]).max() / abs(energy[0])),
            1e-3,
        ),  # fmt: skip
        momentum_row(
            case,
            traj,
            10 * steps * float(np.finfo(float).eps),
            f"rounding: 10 N ε; {ITERATIONS} Newton iterations a step",
        ),  # fmt: skip
    )
