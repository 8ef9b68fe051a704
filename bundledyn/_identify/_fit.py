r"""`fit`: identify a scene's parameters from measured motion, and say what the data determines.

The steps: a warm start by equation error (`warm_start`: spatial momentum and energy are
linear in the inertial parameters), then output error by multiple shooting
(`ShootingProblem`) minimized by Levenberg–Marquardt with exact Jacobians
(`levenberg_marquardt`), optionally after first-order steps of an optax optimizer, and
the identifiability analysis of the solution (`analyse`).
"""

import dataclasses
from typing import cast

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._modes import PrescribedBase
from .._scene import Scene
from .._simulate import simulate
from .._state import State
from ._base_parameters import standard_parameters
from ._clock import FitClock
from ._data import Inputs, Measurements, level
from ._gauge import AbstractGauge
from ._identifiability import (
    Identifiability,
    analyse,
    physical_quantities,
    theta_information,
)
from ._levenberg_marquardt import levenberg_marquardt
from ._parameters import Parameters
from ._progress import FitProgress
from ._regressor import warm_start as regressor_warm_start
from ._shooting import ShootingProblem, Windows, window_chart, window_starts

__all__ = ["FitResult", "fit"]


@dataclasses.dataclass(frozen=True)
class FitResult:
    r"""The outcome of `fit`.

    **Fields:**

    - `scene`: the fitted scene (the nominal scene with the fitted parameters; the known
      inputs are not in it).
    - `theta`: the fitted parameter vector; `parameters`: the `Parameters` it belongs to.
    - `identifiability`: the `Identifiability` report (singular values, undetermined
      directions in physical terms, standard errors).
    - `gauge`: what fixed the mass scale, in words.
    - `costs`: the merit ½‖r‖² + ½‖c‖² at the start and each accepted iterate, stage by
      stage (the windows are first joined loosely, then tightly; the merit jumps between
      the stages).
    - `warm_start`: $\theta$ from the equation-error warm start, or `None`.
    - `window_states`: the fitted (or measured) initial states of the windows, `(K, n_s)`.
    - `iterates`: $\theta$ at the start and after each accepted step.
    - `initial_residuals`, `residuals`: the weighted data residuals (each measured
      channel minus the model, in units of its noise level) at the start and at the
      solution; at the solution they look like unit Gaussian noise when the model and the
      stated noise levels are right. A sample two windows share is counted once: its rows
      in the earlier window are zero.
    - `stats`: `evaluations` of the residuals with their Jacobian, `trials` of trial steps
      (residuals alone), `chords` of them from an earlier Jacobian, `window_solves` (each window solved once per evaluation or
      trial; an evaluation carries the tangents too), accepted `steps`, whether
      Levenberg–Marquardt `converged`, the `seconds` taken, and where they went:
      `compile_seconds` (JAX tracing, lowering and compiling, wherever it happened),
      `jacobian_seconds` (the evaluations), `solve_seconds` (the trials), `start_seconds`
      (the warm start and the nominal motion), each without the compiling inside it; the
      rest is the steps' linear algebra and the analysis.
    """

    scene: Scene
    theta: jax.Array
    parameters: Parameters
    identifiability: Identifiability
    gauge: str
    costs: list
    warm_start: jax.Array | None
    window_states: jax.Array
    iterates: list
    initial_residuals: np.ndarray
    residuals: np.ndarray
    stats: dict

    def estimates(self):
        """The physical parameters with standard errors (`Identifiability.estimates`)."""
        return self.identifiability.estimates

    def _parameters_of(self, scene: Scene) -> Parameters:
        return Parameters(
            scene, bodies=self.parameters.bodies, joint_constants=self.parameters.joint_constants
        )

    def values_of(self, scene: Scene) -> dict[str, float]:
        """The same physical quantities as `estimates` (by name) in another scene of the
        same structure: the truth, when the data were synthetic, or the nominal scene."""
        other = self._parameters_of(scene)
        values = np.asarray(physical_quantities(other, other.initial()))
        return {e.name: float(v) for e, v in zip(self.estimates(), values, strict=True)}

    def base_values_of(self, scene: Scene) -> list[float]:
        """The base parameters' combinations (`Identifiability.base_parameters`, in order)
        in another scene of the same structure, e.g. the truth."""
        other = self._parameters_of(scene)
        standard = np.asarray(standard_parameters(other, other.initial()))
        return [float(b.coefficients @ standard) for b in self.identifiability.base_parameters]

    def report(self, truth: Scene | None = None) -> str:
        """A printable summary: the gauge, the convergence, the base parameters (what the
        data determine) with 95 % intervals, each body's parameters that are determined
        alone, and what the data leave undetermined; with `truth` (a scene of the same
        structure), each estimate's error."""
        ident = self.identifiability
        lines = [
            f"Identification of {len(self.parameters.bodies)} bodies "
            f"({self.parameters.size} parameters); gauge: {self.gauge}.",
            f"  {self.stats['steps']} Levenberg–Marquardt steps ({self.stats['trials']} tried), "
            f"{self.stats['evaluations']} Jacobians, {self.stats['window_solves']} window solves, "
            f"{self.stats['seconds']:.1f} s; cost {self.costs[0]:.3e} -> {self.costs[-1]:.3e}"
            f"{'' if self.stats['converged'] else ' (not converged)'}.",
            f"  noise scale {ident.noise_scale:.3g} (1 when the stated noise levels are right); "
            f"condition number {ident.condition_number:.3g}.",
        ]
        base = ident.base_parameters
        true_base = None if truth is None else self.base_values_of(truth)
        lines += [
            f"  What the data determine: {len(base)} base parameters (M mass, MX MY MZ its "
            "first moments m·c, XX … ZZ the inertia about the body frame's origin, in body "
            "axes; a child's parameters regrouped into its parent's):",
            _row("estimate", "± 95 %", "combination", truth is not None),
        ]
        for k, b in enumerate(base):
            error = None if true_base is None else (b.value - true_base[k], b.std)
            lines.append(_row(f"{b.value:.6g}", f"{1.96 * b.std:.3g}", b.name, error=error))
        alone = [e for e in ident.estimates if e.determined]
        true_values = None if truth is None else self.values_of(truth)
        lines += [
            f"  Determined alone: {len(alone)} of {len(ident.estimates)} physical parameters "
            "(mass, centre of mass, inertia about the centre of mass)" + (":" if alone else "."),
        ]
        for e in alone:
            error = None if true_values is None else (e.value - true_values[e.name], e.std)
            lines.append(_row(f"{e.value:.6g}", f"{1.96 * e.std:.3g}", e.name, error=error))
        if ident.undetermined:
            lines.append("  The data do not determine:")
            lines += [f"    - {u}" for u in ident.undetermined]
        else:
            lines.append("  The data determine every parameter.")
        return "\n".join(lines)


def _row(estimate: str, interval: str, name: str, heading: bool = False, error=None) -> str:
    """One line of the report's tables; `error`: (estimate - truth, standard error)."""
    if heading:
        middle = f"{'error':>12}{'error/σ':>9}"
    elif error is not None:
        difference, std = error
        middle = f"{difference:12.3g}{difference / std if std > 0 else float('nan'):9.2f}"
    else:
        middle = ""
    return f"    {estimate:>14}{interval:>11}{middle}  {name}"


def _window_starts(windows: Windows, parameters: Parameters, measurements: Measurements, guess):
    """The windows' reference poses and initial states: measured where measured, from a
    nominal trajectory `guess` otherwise."""
    starts = window_starts(measurements.ts, windows)
    d = parameters.scene.system.shape_dim
    take = lambda measured, guessed: (guessed if measured is None else measured)[starts]
    g = take(measurements.pose, guess.g)
    states = window_chart(parameters.scene).coordinates(
        jnp.reshape(take(measurements.q, guess.q), (starts.size, d)),
        take(measurements.xi, guess.xi),
        jnp.reshape(take(measurements.qdot, guess.qdot), (starts.size, d)),
    )
    return g, states


def _measured_states(scene: Scene, measurements: Measurements) -> State | None:
    r"""The states at the samples, if measured: the whole state of a floating base; $q$ and
    $\dot q$ on a prescribed base, whose motion gives the rest."""
    if isinstance(scene.base, PrescribedBase):
        if measurements.q is None or measurements.qdot is None:
            return None
        g, xi, _ = jax.vmap(scene.base.at)(measurements.ts)
        return jax.vmap(State)(g, measurements.q, xi, measurements.qdot)
    return measurements.states


def _nominal_trajectory(scene: Scene, measurements: Measurements, initial_state: State | None):
    """The states at the samples: measured, or simulated with the nominal scene."""
    states = _measured_states(scene, measurements)
    if states is not None:
        return states
    if initial_state is None:
        raise ValueError(
            "the measurements do not hold the whole state (pose, q, xi, qdot; q and qdot on "
            "a prescribed base): give `initial_state`, an estimate of the state at the first "
            "sample, from which the nominal model is simulated to start the unmeasured "
            "parts of the windows."
        )
    ts = measurements.ts
    traj = simulate(scene, initial_state, ts[-1], t0=ts[0], saveat=diffrax.SaveAt(ts=ts))
    return jax.vmap(State)(traj.g, traj.q, traj.xi, traj.qdot)


def fit(
    parameters: Parameters,
    measurements: Measurements,
    *,
    gauge: AbstractGauge,
    inputs: Inputs | None = None,
    windows: Windows | None = None,
    warm_start: bool = True,
    initial_state: State | None = None,
    optimizer=None,
    optimizer_steps: int = 0,
    max_steps: int = 50,
    progress: bool | None = None,
) -> FitResult:
    r"""Identify the free parameters of a scene from measured motion.

    The shooting windows are solved in one batch, spread over the local devices when there
    are several (`vmap_over_devices`, each device solving its share): on a CPU, start JAX with
    `XLA_FLAGS=--xla_force_host_platform_device_count=N` to use N cores.

    **Arguments:**

    - `parameters`: the `Parameters`: the nominal scene and what is free.
    - `measurements`: the `Measurements`.
    - `gauge`: what fixes the mass scale (`KnownMass`, `KnownBodies` or `MeasuredInputs`):
      required, because free motion alone does not determine it.
    - `inputs`: the known forces (`Inputs`), added to the scene as effects.
    - `windows`: the shooting `Windows` (default: one window per 20 sample intervals,
      fitted window states, and as many `RKMK87` steps per sample interval as keep the
      fastest measured rate within 0.75 rad per step).
    - `warm_start`: start from the equation-error solution (`warm_start`) when the
      measurements hold the whole state ($q$ and $\dot q$ on a prescribed base); otherwise
      from the nominal parameters.
    - `initial_state`: the state at the first sample, needed when a channel of the state
      is not measured (the windows' unmeasured parts start from the nominal motion).
    - `optimizer`, `optimizer_steps`: an optax optimizer and how many first-order steps it
      takes before Levenberg–Marquardt (with the exact gradient $J^Tr + C^Tc$).
    - `max_steps`: the most Levenberg–Marquardt trial steps from new Jacobians (each may be
      followed by chord steps, which reuse it and are not counted).
    - `progress`: show the continuation stage, step, merit and time at each accepted
      step: `True` always, `False` never, `None` (default) on a terminal once the fit has
      run a few seconds.

    **Returns:**

    A `FitResult`.
    """
    with FitClock() as clock:
        progress_line = FitProgress(progress, clock)
        try:
            result = _fit(
                parameters, measurements, gauge, inputs, windows, warm_start, initial_state,
                optimizer, optimizer_steps, max_steps, clock, progress_line,
            )  # fmt: skip
        finally:
            progress_line.close()
    result.stats.update(
        seconds=clock.seconds["total"],
        compile_seconds=clock.compile_seconds,
        **{f"{name}_seconds": clock.seconds.get(name, 0.0) for name in _SECTIONS},
    )
    return result


# The largest turn one `RKMK87` step of a window takes by default (radians). Measured on
# MuJoCo's records: the benchmark's arm at 0.6 rad per step is reproduced to 1e-8 over a
# window; a tree spinning at 1.5 rad per step not at all (errors of the order of the motion).
_TURN_PER_STEP = 0.75


def _default_windows(measurements: Measurements) -> Windows:
    """One window per 20 sample intervals, with as many steps per interval as keep the
    fastest measured rate (the twist's turning, the shape velocities) within
    `_TURN_PER_STEP` per step: a fixed step far too long for the motion would make the
    model's prediction its integration error, not its parameters'."""
    ts = np.asarray(measurements.ts)
    n = ts.shape[0]
    rates = [0.0]
    if measurements.qdot is not None:
        rates.append(np.abs(np.asarray(measurements.qdot)).max(initial=0.0))
    if measurements.xi is not None:
        rates.append(np.linalg.norm(np.asarray(measurements.xi)[:, :3], axis=1).max())
    fastest = max(rates) * float(np.max(np.diff(ts)))
    return Windows(
        count=max(1, (n - 1) // 20), substeps=max(1, int(np.ceil(fastest / _TURN_PER_STEP)))
    )


# Steps from one Jacobian (`levenberg_marquardt`'s `reuse`): a window's Jacobian carries a
# tangent per parameter and per state coordinate, so it costs as much as tens of trial
# solves, and a step from the last Jacobian that still achieves half of the reduction it
# predicts is far cheaper than a new Jacobian.
_CHORD_STEPS = 3

# The sections of a fit timed apart (`FitResult.stats`).
_SECTIONS = ("start", "jacobian", "solve")


def _fit(
    parameters, measurements, gauge, inputs, windows, warm_start, initial_state, optimizer,
    optimizer_steps, max_steps, clock: FitClock, progress_line: FitProgress,
) -> FitResult:  # fmt: skip
    """`fit`'s work, timed by `clock` and shown by `progress_line`."""
    gauge.check(parameters, inputs)
    windows = _default_windows(measurements) if windows is None else windows
    extra = [] if inputs is None else inputs.effects()
    theta0 = parameters.initial()
    start = None
    with clock.section("start"):
        states = _measured_states(parameters.scene, measurements)
        if warm_start and states is not None:
            start = regressor_warm_start(parameters, measurements, inputs, gauge, states)
            theta0 = start
        guess = _nominal_trajectory(
            eqx.tree_at(
                lambda s: s.effects,
                parameters.to_scene(theta0),
                [*parameters.scene.effects, *extra],
            ),
            measurements,
            initial_state,
        )
    references, window_states = _window_starts(windows, parameters, measurements, guess)
    problem = ShootingProblem(parameters, extra, measurements, windows, references)
    # Inputs and outputs of the evaluations on the host: no input is then committed to one
    # device where the windows are spread over several (`over_windows`), and the
    # Levenberg–Marquardt step factorizes the whole Jacobian on one device.
    problem, gauge, window_states = jax.device_get((problem, gauge, window_states))

    def evaluate(z, problem=problem):
        with clock.section("jacobian"):
            return jax.device_get(_evaluate(problem, gauge, window_states, jax.device_get(z)))

    def trial(z, problem=problem):
        with clock.section("solve"):
            return jax.device_get(_residuals(problem, gauge, window_states, jax.device_get(z)))

    def decision(theta):
        return jnp.concatenate([theta, window_states.reshape(-1)]) if windows.fit_states else theta

    z0 = decision(theta0)
    if start is not None and _merit(trial(decision(parameters.initial()))) < _merit(trial(z0)):
        z0 = decision(parameters.initial())  # the warm start was worse than the nominal values
    z0 = _first_order(evaluate, z0, optimizer, optimizer_steps)
    data_rows = -gauge.residuals(parameters, theta0).shape[0] or None
    r0, _ = trial(z0)
    initial_residuals = np.asarray(r0)[:data_rows]
    iterates = [z0[: parameters.size]]
    stage_number = [0]

    def record(step, z, cost, damping):
        del damping
        iterates.append(z[: parameters.size])
        progress_line.update(stage_number[0], len(stages), len(iterates) - 1, cost)

    state_units = problem.chart.units(measurements.noise)
    units = jnp.concatenate(
        [jnp.asarray(parameters.scales(theta0)), jnp.tile(state_units, window_states.shape[0])]
    )
    # Continuation in the continuity: first the windows join loosely (at the data's noise
    # level, like process noise), which keeps the first steps near-linear however far the
    # noisy window starts and the nominal parameters put the windows' ends from their
    # successors' starts; then ever more tightly, down to `windows.continuity`.
    # Each stage tightens the continuity tenfold, from the noise level down; the stages
    # before the last only need to bring the windows near the data: a coarse tolerance.
    stages = [(problem, 1e-8)]
    if windows.fit_states and windows.count > 1:
        looser = 1.0
        while looser > windows.continuity * 1.01:
            stage = eqx.tree_at(lambda p: p.windows.continuity, problem, level(looser))
            stages.insert(-1, (stage, 1e-4))
            looser /= 10.0
    costs, evaluations, trials, chords, steps = [], 0, 0, 0, 0
    solutions, previous = [], None
    for stage_number[0], (stage, tolerance) in enumerate(stages, start=1):
        solution = levenberg_marquardt(
            lambda z, stage=stage: evaluate(z, stage),
            lambda z, stage=stage: trial(z, stage),
            z0, max_steps=max(1, max_steps - (trials - chords)), ftol=tolerance,
            units=units[: z0.shape[0]], callback=record, reuse=_CHORD_STEPS,
            start=None if previous is None
            else _reweighted(solutions[-1].evaluation(), previous, stage),
        )  # fmt: skip
        solutions.append(solution)
        z0, previous = solution.z, stage
        costs += solution.costs
        evaluations += solution.evaluations
        trials, chords = trials + solution.trials, chords + solution.chords
        steps += solution.steps
    solution = solutions[-1]  # the last stage's, at the measurements' own continuity
    theta, fitted_states = problem.split(solution.z)
    information = theta_information(
        solution.jacobian, solution.constraint_jacobian, parameters.size
    )
    residuals = np.asarray(solution.residuals[:data_rows])
    chi2 = float(np.sum(residuals**2))
    # A sample two windows share is measured once: its row in the earlier window is zero.
    dof = int(np.count_nonzero(residuals)) - (solution.z.shape[0] - solution.defects.shape[0])
    return FitResult(
        scene=parameters.to_scene(theta),
        theta=theta,
        parameters=parameters,
        identifiability=analyse(parameters, theta, information, chi2, dof),
        gauge=gauge.describe(parameters),
        costs=costs,
        warm_start=start,
        window_states=fitted_states if windows.fit_states else window_states,
        iterates=iterates,
        initial_residuals=initial_residuals,
        residuals=residuals,
        stats=dict(
            evaluations=evaluations,
            trials=trials,
            chords=chords,
            window_solves=(evaluations + trials) * windows.count,
            steps=steps,
            converged=solution.converged,
        ),
    )


@eqx.filter_jit
def _residuals(
    problem: ShootingProblem, gauge: AbstractGauge, window_states, z
) -> tuple[jax.Array, jax.Array]:
    """`(r, c)` of the problem with the gauge's pseudo-measurements appended to `r`."""
    r, c = problem.residuals(z, window_states)
    return jnp.concatenate(
        [r, gauge.residuals(problem.parameters, z[: problem.parameters.size])]
    ), c


@eqx.filter_jit
def _evaluate(
    problem: ShootingProblem, gauge: AbstractGauge, window_states, z
) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
    """`(r, J, c, C)` of the problem with the gauge's pseudo-measurements appended to `r`."""
    r, J, c, C = problem.residuals_and_jacobian(z, window_states)
    P = problem.parameters.size

    def extra(theta):
        return gauge.residuals(problem.parameters, theta)

    G = jax.jacfwd(extra)(z[:P])
    G = jnp.concatenate([G, jnp.zeros((G.shape[0], z.shape[0] - P), G.dtype)], axis=1)
    return jnp.concatenate([r, extra(z[:P])]), jnp.concatenate([J, G]), c, C


def _reweighted(evaluation: tuple, previous: ShootingProblem, problem: ShootingProblem) -> tuple:
    r"""`evaluation` `(r, J, c, C)` of `previous` at some $z$, made `problem`'s at the same
    $z$: the continuity defects and their Jacobian are divided by the continuity level
    (`ShootingProblem`), which alone changes from stage to stage, so a stage starts without
    evaluating the Jacobian again."""
    r, J, c, C = evaluation
    ratio = previous.windows.continuity / problem.windows.continuity
    return r, J, c * ratio, C * ratio


def _merit(residuals) -> float:
    r, c = residuals
    merit = 0.5 * float(r @ r + c @ c)
    return merit if np.isfinite(merit) else np.inf


def _first_order(evaluate, z0, optimizer, steps: int) -> jax.Array:
    """`steps` steps of an optax optimizer on the merit, with the exact gradient."""
    if optimizer is None or steps == 0:
        return z0
    import optax

    state = optimizer.init(z0)
    z = z0
    for _ in range(steps):
        r, J, c, C = evaluate(z)
        gradient = J.T @ r + C.T @ c
        updates, state = optimizer.update(gradient, state, z)
        z = cast(jax.Array, optax.apply_updates(z, updates))
    return z
