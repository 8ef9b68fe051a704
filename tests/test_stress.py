"""The stress battery: every case meets its bound at the suite's settings, and a model built
to fail is reported with the reason (the shipped models' cases: test_stress_models.py)."""

import functools

import jax.numpy as jnp
import numpy as np
import pytest

import bundledyn as bd
from bundledyn._cli import main
from bundledyn._stress._battery import CASES


@functools.cache
def quick_battery():
    return bd.stress.battery(quick=True)


@pytest.mark.slow  # every case of the battery, solves and gradients: minutes
def test_every_case_meets_its_bound():
    report = quick_battery()
    assert report.passed, str(report)
    named = {row.case.split(" ")[0] for row in report.rows}
    names = {case.__name__ for case, _, _ in CASES} - {"rigid_gradients"}
    assert names | {"singular_gradients"} == named  # every case gave rows
    assert len(report.rows) >= 40
    text = str(report)
    assert text.startswith("Stress battery on the shipped cases (quick settings): PASSED")
    assert report.markdown().count("| pass |") == len(report.rows)


def test_the_flip_interval_is_the_elliptic_period():
    """`flip_interval` against the period of the linearised motion near the axis: for
    ω ≈ Ω e3 (the stable major axis, M² > 2EI₂) the small components oscillate at
    λ = Ω √((I3−I1)(I3−I2)/(I1I2)), and K → π/2 as k → 0, so the interval → π/λ."""
    moments, spin = (1.0, 2.0, 3.0), 2.0
    interval = bd.stress.flip_interval(moments, (1e-7, 1e-7, spin))
    lam = spin * np.sqrt((3.0 - 1.0) * (3.0 - 2.0) / (1.0 * 2.0))
    assert interval == pytest.approx(np.pi / lam, rel=1e-10)


def test_a_force_that_injects_energy_fails_the_energy_row_with_its_figure():
    from bundledyn._stress._models import chain as make_chain

    pump = bd.ShapeForce(lambda t, q, qdot: 0.05 * qdot)  # negative damping: does work
    energy, momentum, orthogonality = bd.stress.free_motion(
        make_chain((1.0, 1.5, 2.0)), effects=[pump], t1=2.0
    )
    assert not energy.passed and energy.measured > 1e3 * energy.bound
    assert momentum.passed and orthogonality.passed  # internal forces keep the momentum
    report = bd.stress.StressReport("pumped chain", (energy, momentum, orthogonality))
    assert not report.passed and report.failed == (energy,)
    assert "FAILED 1 of 3" in str(report) and "FAIL" in str(report).splitlines()[2]


def test_a_field_that_is_nan_where_the_step_starts_is_named():
    from bundledyn._stress._start import start_of

    system, state = start_of()
    broken = bd.ShapeForce(lambda t, q, qdot: jnp.full_like(q, jnp.nan))
    with pytest.raises(Exception, match="NaN or infinite at a finite state"):
        bd.simulate(bd.Scene(system, [broken]), state, 1.0)


def test_fixed_steps_too_large_for_the_motion_are_told_to_shrink():
    """Lie–Euler at dt = 0.8 on a body spinning at 2 rad/s runs away until its field
    overflows; the message names that case too, not only a broken model."""
    import diffrax

    body = bd.RigidBody(1.0, [0.0, 0.0, 0.0], np.diag([1.0, 2.0, 3.0]))
    state = bd.State(jnp.eye(4), (), jnp.array([0.01, 2.0, 0.01, 0.0, 0.0, 0.0]), ())
    fixed = dict(dt0=0.8, stepsize_controller=diffrax.ConstantStepSize())
    with pytest.raises(Exception, match="take smaller steps"):
        bd.simulate(bd.Scene(body), state, 20.0, solver=bd.LieEuler(), **fixed)


@pytest.mark.parametrize(
    "argv, message",
    [
        (["check", "MODEL", "--samples", "0"], "--samples: must be positive, got 0"),
        (["check", "MODEL", "--tolerance", "-1"], "--tolerance: must be positive, got -1"),
    ],
)
def test_bad_numbers_on_the_command_line_get_one_line(argv, message, capsys):
    argv = [str(bd.models / "tree4.xml") if a == "MODEL" else a for a in argv]
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 2
    assert message in capsys.readouterr().err


def test_a_models_springs_are_run_and_their_stiffest_period_scales_with_the_stiffness():
    """The springs' case on a chain with joint springs: energy and momentum within bounds,
    and the stiffest period 10× shorter for 100× the stiffness (ω² ∝ k)."""
    from bundledyn._stress._models import chain
    from bundledyn._stress._start import start_of

    system, state = start_of(chain((1.0, 1.5, 2.0)))
    soft, stiff = bd.ShapeSpring(jnp.array([3.0, 1.0])), bd.ShapeSpring(jnp.array([300.0, 100.0]))
    ratio = bd.stress.stiffest_period(system, [soft], state.q) / bd.stress.stiffest_period(
        system, [stiff], state.q
    )
    assert ratio == pytest.approx(10.0, rel=1e-12)
    energy, momentum = bd.stress.springs_motion(system, [stiff])
    assert energy.passed and momentum.passed, (energy, momentum)
    assert "per period of the stiffest mode" in energy.note
