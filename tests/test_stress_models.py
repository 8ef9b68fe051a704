"""The stress cases that apply to a model pass on every shipped model: from the command line
on one, from the library on the others (a file of its own, so that the suite's two workers
share the battery's time)."""

import contextlib

import pytest
from systems import CHAIN5_REFS

import bundledyn as bd
from bundledyn._cli import main

# Eleven cases a model, several solves and gradients each: `.ci/run`'s slow part.
pytestmark = pytest.mark.slow

# What importing each model warns of, where it does.
IMPORT_WARNINGS = {
    "floating_chain.xml": "ignored from the MuJoCo model: 2 actuator",  # its motors
    "chain5.xml": CHAIN5_REFS,
    "arm.urdf": "ignored from the MuJoCo model: contacts of 1 collision geom",
}


def _importing(name):
    warning = IMPORT_WARNINGS.get(name)
    return pytest.warns(UserWarning, match=warning) if warning else contextlib.nullcontext()


def test_the_command_runs_the_models_cases(capsys):
    with _importing("floating_chain.xml"):
        code = main(["stress", str(bd.models / "floating_chain.xml")])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "PASSED" in out
    for shows in ("rollout gradient at ξ0 = 0", "free_motion", "high_spin", "float32 at rtol 1e-5"):
        assert shows in out


@pytest.mark.parametrize("name", ["tree4.xml", "chain5.xml", "arm.urdf"])
def test_the_other_shipped_models_pass_their_cases(name):
    with _importing(name):
        scene = bd.load_scene(bd.models / name, passive=True)
    report = bd.stress.model_battery(scene, name)
    assert report.passed and len(report.rows) == 11, str(report)
