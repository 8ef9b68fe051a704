"""The growth benchmark stays alive and times the fields it checked: every member's metric
equals MuJoCo's mass matrix to 1e-12, and its recursive field the dense one within the
rounding their solves carry, the mass matrix's condition number times epsilon (ten times
that for the VJPs, which solve with the metric twice); timings are never asserted."""

import json

import numpy as np
import pytest

from benchmarks._output import RESULTS
from benchmarks.growth import cli
from benchmarks.growth.members import SIZES
from benchmarks.growth.report import exponent, markdown

pytest.importorskip("mujoco")


def _checked(member):
    rounding = member["condition"] * np.finfo(float).eps
    agreement = member["agreement"]
    return (
        member["metric_error"] < 1e-12
        and agreement["field"] <= rounding
        and agreement["vjp"] <= 10 * rounding
    )


@pytest.mark.slow
def test_the_quick_run_checks_and_writes_its_report(tmp_path):
    assert cli.main(["--quick", "--out", str(tmp_path)]) == 0
    report = json.loads((tmp_path / "growth_quick.json").read_text())
    assert report["quick"] is True and len(report["members"]) == 2
    assert all(map(_checked, report["members"]))
    assert all(member["gradient"]["ratio"] > 0 for member in report["members"])
    assert (tmp_path / "growth_quick.md").read_text() == markdown(report)
    png = (tmp_path / "growth.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_exponent_is_the_power_the_times_grow_by():
    # linear up to 20 bodies, quadratic from there (continuous at 20)
    members = [
        {"bodies": n, "times": {"field": {"median": 1e-6 * max(n, n * n / 20)}}}
        for n in (10, 20, 40, 80)
    ]
    assert exponent(members, "field", least_bodies=20) == pytest.approx(2.0, rel=1e-12)
    assert 1.0 < exponent(members, "field") < 2.0
    assert exponent(members[:1], "field") != exponent(members[:1], "field")  # one size: NaN


def test_the_committed_results_redraw_and_were_checked(tmp_path):
    (tmp_path / "growth.json").write_bytes((RESULTS / "growth.json").read_bytes())
    assert cli.main(["--report-only", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "growth.md").read_text() == (RESULTS / "growth.md").read_text()
    report = json.loads((RESULTS / "growth.json").read_text())
    assert not report["quick"] and {m["bodies"] for m in report["members"]} == set(SIZES)
    assert all(map(_checked, report["members"]))
