"""The battery: every case on the shipped systems, or the cases that apply to a user's model."""

from collections.abc import Callable

import jax
import jax.numpy as jnp

from .._effects import ShapePotential, ShapeSpring
from .._geometry import shape_metric
from .._scene import Scene
from ._conservation import free_run, orthogonality_row
from ._failures import advice, bad_values, float32
from ._gradients import model_gradients, rigid_gradients
from ._orbit import orbital_speed
from ._ratios import (
    ball_turns,
    degenerate_stretch,
    folded_chain,
    mass_ratio,
    stiff_springs,
    thin_rod,
)
from ._rigid import dzhanibekov, high_spin, long_horizon
from ._row import StressReport, StressRow
from ._start import start_of
from ._variational import variational_long_run

# (case, settings of the full battery, cheap settings of the suite's run)
CASES: tuple[tuple[Callable[..., tuple[StressRow, ...]], dict, dict], ...] = (
    (rigid_gradients, {}, {}),
    (dzhanibekov, {}, {}),
    (variational_long_run, {}, {"steps": 5_000}),
    (thin_rod, {}, {}),
    (mass_ratio, {}, {}),
    (stiff_springs, {}, {"t1": 0.5}),
    (folded_chain, {}, {}),
    (degenerate_stretch, {}, {}),
    (ball_turns, {}, {"turns": 5.0}),
    (high_spin, {"rate": 1e3}, {"rate": 1e3, "turns": 100.0}),
    (high_spin, {"rate": 1e4}, {"rate": 1e4, "turns": 100.0}),
    (long_horizon, {}, {"t1": 1e3}),
    (orbital_speed, {}, {"t1": 20.0}),
    (float32, {}, {}),
    (advice, {}, {}),
    (bad_values, {}, {}),
)


def battery(*, quick: bool = False) -> StressReport:
    """Run every case on the systems it builds.

    **Arguments:**

    - `quick`: cheaper settings (shorter horizons, fewer steps), the suite's; each case's
      bound is the same.

    **Returns:**

    A `StressReport`; `print` it for the table.
    """
    rows = [row for case, full, cheap in CASES for row in case(**(cheap if quick else full))]
    return StressReport("the shipped cases" + (" (quick settings)" if quick else ""), tuple(rows))


def free_motion(
    system, *, effects=(), t1: float = 10.0, rtol: float = 1e-10, spin: float | None = None
) -> tuple[StressRow, ...]:
    """The model moving from the cases' start (`start_of`): energy and spatial momentum,
    exactly conserved, to a bound set by the tolerance; orthogonality.

    **Arguments:**

    - `system`: the model.
    - `effects`: none by default (free motion); conservative shape effects keep both
      invariants, and a force that does work fails the energy row.
    - `t1`, `rtol`: horizon and tolerance.
    - `spin`: the start's angular speed, rad/s (default `start_of`'s, 0.54): the high-spin
      case of a model.
    """
    system, state = start_of(system, spin=spin)
    case = f"free_motion ({t1:g} s)" if spin is None else f"high_spin ({spin:g} rad/s, {t1:g} s)"
    traj, energy, momentum = free_run(case, Scene(system, list(effects)), state, t1=t1, rtol=rtol)
    return energy, momentum, orthogonality_row(case, traj, 1e-13)


def springs_of(scene: Scene) -> list:
    """The scene's internal conservative effects (`ShapeSpring`, `ShapePotential`): its
    springs, which keep the energy (theirs included) and the momentum."""
    return [e for e in scene.effects if isinstance(e, ShapeSpring | ShapePotential)]


def stiffest_period(system, springs, q) -> float:
    r"""$2\pi/\omega_{max}$, $\omega_{max}^2$ the largest eigenvalue of $J(q)^{-1}K$: $K$ the
    springs' Hessian, $J$ the shape metric (the locked body free) at `q`."""

    def potential(q):
        return sum(s.potential(system, 0.0, jnp.eye(4), q) for s in springs)

    K = jax.hessian(potential)(q)
    rates = jnp.linalg.eigvals(jnp.linalg.solve(shape_metric(system, q), K))
    return float(2 * jnp.pi / jnp.sqrt(jnp.max(jnp.real(rates))))


def springs_motion(system, springs, *, t1: float = 2.0) -> tuple[StressRow, ...]:
    """The model moving under its own springs: energy (the springs' included) and momentum,
    with the steps the default solver took per period of the stiffest mode in the note.

    Guards against explicit methods that go unstable on stiff springs (they take more steps
    instead; the note says how many per period, the cost of stiffness) and implicit ones
    that damp the stiff mode's energy away.
    """
    _, state = start_of(system)
    period = stiffest_period(system, springs, state.q)
    energy, momentum, _ = free_motion(system, effects=springs, t1=t1)
    steps = int(energy.note.split()[0])
    note = (
        f"{steps} steps, {steps * period / t1:.1f} per period of the stiffest mode ({period:.2g} s)"
    )
    return (
        StressRow("springs", energy.shows, energy.measured, energy.bound, note),
        StressRow("springs", momentum.shows, momentum.measured, momentum.bound),
    )


def model_battery(scene: Scene, name: str = "the model") -> StressReport:
    """Run the cases that apply to a model: gradients at zero twist, free motion (10 s, and
    1 s spinning at 100 rad/s), its springs
    (`springs_of`: MuJoCo's joint and tendon springs, a scene's shape potentials), float32.
    Other effects of `scene` are not used.

    **Arguments:**

    - `scene`: the model's scene (`bundledyn.load_scene(path, passive=True)` for a file).
    - `name`: what the report calls it.

    **Returns:**

    A `StressReport`.
    """
    system, state = start_of(scene.system)
    springs = springs_of(scene)
    rows = (
        *model_gradients(Scene(system), state),
        *free_motion(system),
        *free_motion(system, t1=1.0, spin=1e2),
        *(springs_motion(system, springs) if springs else ()),
        *float32(system),
    )
    return StressReport(name, rows)
