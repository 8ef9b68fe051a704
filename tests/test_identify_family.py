"""Identification on a system written by no one (issue 62): a member of the identification
benchmark's generated family (`benchmarks/identification/family.py`) at a seed chosen here,
recorded by MuJoCo, fitted as the benchmark fits it; and where a fit's time goes."""

import dataclasses
import io

import mujoco
import numpy as np
import pytest
from traced import lowerings

from benchmarks.identification import metric, records
from benchmarks.identification.cases import nominal_spec
from benchmarks.identification.family import member
from benchmarks.identification.ours import Bundledyn
from bundledyn import identify
from bundledyn._identify._clock import FitClock
from bundledyn._identify._progress import FitProgress

# Not one of the benchmark's seeds (0, 1, ...): a floating tree of three bodies on a
# universal and a ball joint, two driven hinges, 10-20 % off at the start.
SEED = 2028
LEVEL = 0.01  # the noise: 1 % of each channel's spread


# Compiled as users' code is: the fit solves its windows hundreds of times, and unoptimised
# code made this file take 182 s instead of 58 s (one core).
@pytest.fixture(scope="module")
def fitted(optimized_compilation):
    # Half the benchmark's record (2 s, 10 windows) and held-out motion: the suite's budget.
    case = dataclasses.replace(member("tree", SEED, bodies=3), t1=2.0, held_out_t1=1.0)
    truth = mujoco.MjModel.from_xml_string(case.mjcf)
    P_nominal = metric.model_pseudo_inertias(nominal_spec(case).compile(), case.bodies)
    ours = Bundledyn(case, P_nominal)
    record = records.noisy_record(case, 0, LEVEL)
    result = identify.fit(
        ours.parameters, record.measurements, inputs=record.inputs, gauge=ours.gauge
    )
    return case, truth, ours, result


@pytest.mark.slow  # an identification fit of a three-body tree
@pytest.mark.xdist_group("identify_family")  # one worker fits once for both
def test_a_generated_tree_is_fitted_physical_and_predicts_motion_it_never_saw(fitted):
    case, truth, _, result = fitted
    assert result.stats["converged"]
    P = np.asarray(result.scene.system.pseudo_inertias())
    assert np.all(np.linalg.eigvalsh(P) > 0), "every fitted body physical"
    model = metric.model_with(case, P[[result.scene.system.names.index(b) for b in case.bodies]])
    prediction = records.prediction_error(case, model, records.held_out(case, 0))
    assert max(prediction.values()) <= 2 * LEVEL, prediction
    # The noise-free truth's prediction is MuJoCo's own motion: the score is the model's.
    assert max(records.prediction_error(case, truth, records.held_out(case, 0)).values()) == 0


@pytest.mark.slow  # an identification fit of a three-body tree, and a step of another
@pytest.mark.xdist_group("identify_family")
def test_another_record_of_the_same_model_compiles_nothing(fitted):
    case, _, ours, first = fitted
    assert first.stats["compile_seconds"] > 0
    record = records.noisy_record(case, 1, LEVEL)

    def second_fit():  # every compiled part runs (warm start, windows, a step per stage)
        second_fit.result = identify.fit(
            ours.parameters, record.measurements, inputs=record.inputs, gauge=ours.gauge,
            max_steps=1,
        )  # fmt: skip
        return second_fit.result.theta

    _, programs = lowerings(second_fit)
    stats = second_fit.result.stats
    assert programs == 0
    assert stats["compile_seconds"] == 0.0
    parts = ("start", "jacobian", "solve")
    assert all(stats[f"{p}_seconds"] > 0 for p in parts)
    assert sum(stats[f"{p}_seconds"] for p in parts) < stats["seconds"]


def test_the_clock_counts_compiling_apart_from_the_section_that_caused_it():
    import jax
    import jax.numpy as jnp

    @jax.jit
    def f(x):
        return jnp.sin(x) * 3.0

    x, y = jnp.arange(7.0), jnp.arange(1.0, 8.0)
    with FitClock() as clock:
        with clock.section("work"):
            f(x).block_until_ready()
        compiled = clock.compile_seconds
        with clock.section("work"):
            f(y).block_until_ready()  # cached: compiles nothing
    assert compiled > 0 and clock.compile_seconds == compiled
    assert 0 <= clock.seconds["work"] < clock.seconds["total"] - compiled + 1e-6
    with FitClock() as outside:
        pass
    jax.jit(lambda x: x + 2.0)(jnp.ones(3))  # after the clock stopped: not counted
    assert outside.compile_seconds == 0.0


class _Terminal(io.StringIO):
    def isatty(self):
        return True


@pytest.mark.parametrize(
    ("show", "stream", "lines"),
    [(True, io.StringIO(), 2), (None, io.StringIO(), 0), (False, _Terminal(), 0)],
)
def test_the_progress_line_is_shown_when_asked_or_on_a_terminal(show, stream, lines):
    with FitClock() as clock:
        progress = FitProgress(show, clock, stream=stream)
        progress.update(1, 2, 1, 0.5)
        progress.update(2, 2, 2, 0.25)
        progress.close()
    assert stream.getvalue().count("\n") == lines
    if lines:
        assert "stage 2/2, step 2, cost 2.500000e-01" in stream.getvalue()


def test_on_a_terminal_the_progress_line_is_rewritten_in_place(monkeypatch):
    from bundledyn._identify import _progress

    monkeypatch.setattr(_progress, "_QUIET_SECONDS", 0.0)
    stream = _Terminal()
    with FitClock() as clock:
        progress = FitProgress(None, clock, stream=stream)
        progress.update(1, 1, 1, 0.5)
        progress.update(1, 1, 2, 0.25)
        progress.close()
    text = stream.getvalue()
    assert text.count("\r") == 2 and text.count("\n") == 1 and text.endswith("\n")


@pytest.mark.parametrize(("fastest", "substeps"), [(0.0, 1), (60.0, 1), (140.0, 2), (400.0, 6)])
def test_the_default_windows_step_as_finely_as_the_fastest_measured_rate(fastest, substeps):
    """One window per 20 samples, and steps of at most 0.75 rad at the fastest measured
    rate (here a hinge's, sampled at 100 Hz)."""
    import jax.numpy as jnp

    from bundledyn._identify._fit import _default_windows

    ts = jnp.linspace(0.0, 1.0, 101)
    qdot = jnp.stack([jnp.sin(3.0 * ts), fastest * jnp.cos(ts) ** 2], axis=1)
    measured = identify.Measurements(
        ts, q=jnp.zeros((101, 2)), qdot=qdot, noise=identify.Noise(q=1e-3, qdot=1e-2)
    )
    windows = _default_windows(measured)
    assert windows.count == 5 and windows.substeps == substeps
