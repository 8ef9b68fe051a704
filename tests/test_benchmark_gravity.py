"""The gravity benchmark stays alive and times the same gravity both ways: `Gravity`'s forces
equal those by autodiff of its potential to 1e-12 on every member (timings are never
asserted)."""

import json

import pytest

from benchmarks._output import RESULTS
from benchmarks.gravity import cli
from benchmarks.gravity.report import markdown

pytest.importorskip("mujoco")


@pytest.mark.slow
def test_the_quick_run_agrees_and_writes_its_report(tmp_path):
    assert cli.main(["--quick", "--out", str(tmp_path)]) == 0
    report = json.loads((tmp_path / "gravity_quick.json").read_text())
    assert report["quick"] is True
    (member,) = report["members"]
    assert member["agreement"] < 1e-12
    assert (tmp_path / "gravity_quick.md").read_text() == markdown(report)


def test_the_committed_results_redraw_and_agree(tmp_path):
    (tmp_path / "gravity.json").write_bytes((RESULTS / "gravity.json").read_bytes())
    assert cli.main(["--report-only", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "gravity.md").read_text() == (RESULTS / "gravity.md").read_text()
    report = json.loads((RESULTS / "gravity.json").read_text())
    assert not report["quick"] and len(report["members"]) >= 12
    assert all(member["agreement"] < 1e-12 for member in report["members"])
