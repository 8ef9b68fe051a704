"""The rolling-bodies benchmark against sympy.physics.mechanics stays alive, and its two sides
are one problem: bundledyn's disc and bicycles follow sympy's `KanesMethod` trajectories, an
independent derivation, to the benchmark's target (timings are never asserted)."""

import json

import pytest

from benchmarks._output import RESULTS
from benchmarks.nonholonomic import cli
from benchmarks.nonholonomic.report import TARGETS, markdown


@pytest.mark.slow
def test_the_quick_run_agrees_with_sympy_and_writes_its_report(tmp_path):
    assert cli.main(["--quick", "--out", str(tmp_path), "--repeats", "1"]) == 0
    report = json.loads((tmp_path / "nonholonomic_quick.json").read_text())
    assert report["quick"] is True
    assert [p["name"] for p in report["problems"]] == [
        "rolling disc",
        "Whipple bicycle",
        "Whipple bicycle as a tree",
    ]
    for problem in report["problems"]:
        (member,) = problem["members"]
        # Each side at rtol 1e-10, and tighter: the difference shrinks with the tolerances.
        assert member["agreement"] < TARGETS["agreement"]
        assert member["agreement_tight"] < 0.25 * member["agreement"]
    assert (tmp_path / "nonholonomic_quick.md").read_text() == markdown(report)


def test_the_committed_results_redraw_and_agree_with_sympy(tmp_path):
    (tmp_path / "nonholonomic.json").write_bytes((RESULTS / "nonholonomic.json").read_bytes())
    assert cli.main(["--report-only", "--out", str(tmp_path)]) == 0
    text = (tmp_path / "nonholonomic.md").read_text()
    assert text == (RESULTS / "nonholonomic.md").read_text()
    report = json.loads((RESULTS / "nonholonomic.json").read_text())
    assert report["provenance"]["commit"] and not report["quick"]
    for problem in report["problems"]:
        assert len(problem["members"]) >= 6 and problem["repeats"] >= 3
        assert max(m["agreement"] for m in problem["members"]) < TARGETS["agreement"]
