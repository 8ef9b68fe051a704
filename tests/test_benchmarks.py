"""The benchmark scripts stay alive: `--quick` runs end to end (timings are never asserted)."""

import dataclasses
import json
import pathlib
import re

import numpy as np
import pytest

from benchmarks import accuracy_cost
from benchmarks._output import RESULTS
from benchmarks.accuracy_cost.sweep import default_solver

BENCHMARKS = {
    "accuracy_cost", "speed", "speed_gpu", "family", "identification", "stress", "nonholonomic",
    "tensorial", "gravity", "survey", "devices", "growth",
}  # fmt: skip


def test_accuracy_cost_quick_writes_its_report(tmp_path):
    report = accuracy_cost.main(["--quick", "--out", str(tmp_path), "--repeats", "2"])
    (problem,) = report["problems"]
    assert problem["reference_agreement"] < 1e-10
    for series in problem["series"]:
        errors = [p["error"] for p in series["points"]]
        assert all(p["ok"] for p in series["points"]) and np.all(np.isfinite(errors))
        assert errors[-1] < errors[0]  # a tighter setting is more accurate
    default = default_solver().__name__
    first = problem["series"][0]
    assert report["default_solver"] == first["method"] == default
    assert first["per_digit"]["points"] >= 3 and first["order"] == default_solver()().order(None)
    assert json.loads((tmp_path / "accuracy_cost_quick.json").read_text())["quick"] is True
    text = (tmp_path / "accuracy_cost_quick.md").read_text()
    assert "| RKMK54 |" in text and f"| {default} | {first['order']} | ×" in text
    png = (tmp_path / "accuracy_cost_dzhanibekov.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def test_accuracy_cost_report_redraws_from_its_json(tmp_path):
    """The committed accuracy-cost results rebuild the same markdown (`--report-only`), and
    were measured with today's default solver: first in every scene, with its cost per digit."""
    (tmp_path / "accuracy_cost.json").write_bytes((RESULTS / "accuracy_cost.json").read_bytes())
    report = accuracy_cost.main(["--report-only", "--out", str(tmp_path)])
    text = (tmp_path / "accuracy_cost.md").read_text()
    assert text == (RESULTS / "accuracy_cost.md").read_text()
    default = default_solver().__name__
    assert report["default_solver"] == default and not report["quick"]
    for problem in report["problems"]:
        first = problem["series"][0]
        assert first["method"] == default and "per_digit" in first
    assert report["problems"][0]["series"][0]["per_digit"] is not None  # the Dzhanibekov body


def test_every_benchmark_has_committed_results():
    assert {path.stem for path in RESULTS.glob("*.json")} >= BENCHMARKS


@pytest.mark.parametrize("name", sorted(path.stem for path in RESULTS.glob("*.json")))
def test_results_record_their_code_and_name_the_default_solver(name):
    """Every committed results file records the bundledyn version and the git commit it was
    measured with, and names `bundledyn.simulate`'s default solver (found in the library,
    so a change of default fails here until the results are measured again)."""
    report = json.loads((RESULTS / f"{name}.json").read_text())
    code = report.get("provenance") or {}
    assert code.get("bundledyn"), f"{name}.json records no bundledyn version: measure it again"
    assert re.fullmatch("[0-9a-f]{40}", code.get("commit") or ""), f"{name}.json records no commit"
    default = default_solver().__name__
    text = (RESULTS / f"{name}.json").read_text() + (RESULTS / f"{name}.md").read_text()
    assert re.search(rf"\b{default}\b", text), f"{name} does not name the default, {default}"


def test_speed_report_redraws_from_its_json(tmp_path):
    """The committed speed results are self-consistent: `--report-only` rebuilds the same
    markdown from the JSON (the CPU run's and the GPU batches'), and every target row states
    whether it was met."""
    from benchmarks import speed
    from benchmarks._output import RESULTS
    from benchmarks.speed.targets import targets

    names = [path.name for path in RESULTS.glob("speed*.json")]
    assert {"speed.json", "speed_gpu.json"} <= set(names)
    for name in names:
        (tmp_path / name).write_bytes((RESULTS / name).read_bytes())
    speed.main(["--report-only", "--out", str(tmp_path)])
    for name in names:
        md = name.replace(".json", ".md")
        assert (tmp_path / md).read_text() == (RESULTS / md).read_text()
    text = (tmp_path / "speed.md").read_text()
    report = json.loads((tmp_path / "speed.json").read_text())
    rows = targets(report)
    assert len(rows) >= 10
    for what, value, limit, met in rows:  # each row says "yes" exactly when within its limit
        assert met == (value <= limit)
        assert f"| {what} | {value:.3g} | {limit:g} | {'yes' if met else 'no'} |" in text


def test_speed_times_both_sides_in_alternation():
    """`interleaved` calls every sampler once per round, in reverse order every other round,
    so the two sides of a ratio share the machine's slow phases; a sampler's own
    measurement is kept as it returns it."""
    from benchmarks._timing import interleaved

    calls = []

    def sampler(name, seconds=None):
        return lambda: calls.append(name) or seconds

    timings = interleaved({"a": sampler("a", 2.0), "b": sampler("b")}, repeats=3)
    assert calls == ["a", "b", "a", "b", "b", "a", "a", "b"]  # warm-up, then rounds
    (first_a, runs_a), (_, runs_b) = timings["a"], timings["b"]
    assert first_a == 2.0 and runs_a == {"median": 2.0, "min": 2.0, "max": 2.0}
    assert 0.0 <= runs_b["min"] <= runs_b["median"] <= runs_b["max"] < 1.0


def test_speed_gradient_profile_units_run():
    """Part 5c's units (the body field, an RKMK87 step and their VJPs) run in their compiled
    loops: each returns a time per call."""
    from benchmarks._models import chain_scene, initial_state
    from benchmarks.speed.gradient import gradient_units

    scene = chain_scene(2)
    units, profile = gradient_units(scene, initial_state(scene), 0.5, 1e-4)
    assert profile["steps"] >= 1 and profile["stages"] == 13
    assert all(0.0 < sample() < 1.0 for sample in units.values())


def test_speed_gradient_baselines_solve_their_odes():
    """Part 5a's baselines solve what they say. Linear ($L = 1$, $K$ skew): the flow is
    orthogonal, so the loss $|y(t_1)|^2$ is $|y_0|^2$ and its gradient $2y_0$, to the
    solve's tolerance. Three layers: the loss's gradient matches central differences."""
    import jax
    import jax.numpy as jnp

    from benchmarks.speed.gradient import baseline_loss, skew_network_ode

    field, y0 = skew_network_ode(1)
    loss = baseline_loss(field, 2.0, 1e-10)
    assert y0.shape == (30,)
    assert jnp.allclose(loss(y0), jnp.sum(y0**2), rtol=1e-8)
    assert jnp.allclose(jax.grad(loss)(y0), 2 * y0, rtol=1e-7, atol=1e-8)

    field, y0 = skew_network_ode(3)
    loss = baseline_loss(field, 1.0, 1e-11)
    e = jnp.zeros(30).at[4].set(1e-5)
    fd = (loss(y0 + e) - loss(y0 - e)) / 2e-5
    assert jnp.allclose(jax.grad(loss)(y0)[4], fd, rtol=1e-8)


@pytest.mark.parametrize("name", ["chain", "arm", "tumble", "tree 2028", "arm 0"])
def test_identification_error_ignores_exactly_what_motion_cannot_show(name):
    """The identification benchmark scores fits beside `null_directions`, built from the
    geometry. MuJoCo confirms them: moving every fitted body's pseudo-inertia along a random
    combination of them (1e-4 of the smallest body's size) leaves the recorded motion unchanged to
    rounding, while a random change outside them, as large, changes it visibly. On the named
    data sets and on two generated members: a floating tree on a universal and a ball joint
    (three bodies), and an arm under gravity."""
    mujoco = pytest.importorskip("mujoco")
    from benchmarks.identification import metric, records
    from benchmarks.identification.cases import CASES
    from benchmarks.identification.family import member

    kind, _, seed = name.partition(" ")
    named = CASES.get(name) or member(kind, int(seed), bodies=3 if kind == "tree" else None)
    case = dataclasses.replace(named, t1=1.0)
    P = metric.model_pseudo_inertias(mujoco.MjModel.from_xml_string(case.mjcf), case.bodies)
    D = metric.null_directions(case, P)
    rng = np.random.default_rng(0)
    hidden = D @ rng.normal(size=D.shape[1])
    seen = rng.normal(size=P.size)
    seen = (seen + seen.reshape(P.shape).transpose(0, 2, 1).reshape(-1)) / 2  # symmetric
    seen -= D @ np.linalg.lstsq(D, seen, rcond=None)[0]

    def moved(direction):
        size = np.min(np.linalg.norm(P, axis=(1, 2)))
        step = 1e-4 * size * direction / np.linalg.norm(direction)
        model = metric.model_with(case, P + step.reshape(P.shape))
        _, qpos, qvel = records.mujoco_record(case, 0, case.t1, model=model)
        return np.max(np.abs(np.hstack([qpos - qpos0, qvel - qvel0])))

    _, qpos0, qvel0 = records.mujoco_record(case, 0, case.t1)
    assert moved(hidden) < 1e-10
    assert moved(seen) > 1e-6


def test_identification_report_redraws_from_its_json(tmp_path):
    """The committed identification results are self-consistent: `--report-only` rebuilds
    the same markdown from the JSON, which names the code it measured."""
    from benchmarks import identification
    from benchmarks._output import RESULTS

    (tmp_path / "identification.json").write_bytes((RESULTS / "identification.json").read_bytes())
    report = identification.main(["--report-only", "--out", str(tmp_path)])
    text = (tmp_path / "identification.md").read_text()
    assert text == (RESULTS / "identification.md").read_text()
    assert report["provenance"]["commit"] and f"`{report['provenance']['commit'][:12]}`" in text
    assert set(report["cases"]) == {"chain", "arm", "tumble"}
    assert all(set(c["summary"]) == {"0", "0.001", "0.01"} for c in report["cases"].values())


@pytest.mark.parametrize("index", [0, 3, 5, "humanoid"])
def test_family_members_are_one_system_in_both_simulators(index):
    """Each kind of member (hinge, ball and composite trees, the humanoid) is the same
    mechanical system in bundledyn and MuJoCo: the kinetic energy at its tumbling start
    equals MuJoCo's ½ qvelᵀ M qvel to 1e-12."""
    mujoco = pytest.importorskip("mujoco")
    import bundledyn as bd
    from benchmarks.family.measure import member_scene
    from benchmarks.family.members import initial_qpos_qvel, members, mujoco_model

    family = members(quick=False)
    member = family[-1] if index == "humanoid" else family[2 * index]
    scene = member_scene(member)
    model = mujoco_model(member, 1e-2)
    qpos, qvel = initial_qpos_qvel(model, member.rate, 0)
    state = bd.state_from_mujoco(scene.system, qpos, qvel, qpos0=model.qpos0)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = qpos, qvel
    mujoco.mj_forward(model, data)
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    T_mujoco = 0.5 * qvel @ M @ qvel
    T = float(bd.kinetic_energy(scene.system, state.q, state.xi, state.qdot))
    assert abs(T - T_mujoco) <= 1e-12 * T_mujoco


def test_family_report_redraws_from_its_json(tmp_path):
    """The committed family results rebuild the same markdown (`--report-only`), and each
    target's verdict is its worst case against its limit."""
    from benchmarks import family
    from benchmarks._output import RESULTS
    from benchmarks.family.report import target_rows

    (tmp_path / "family.json").write_bytes((RESULTS / "family.json").read_bytes())
    family.main(["--report-only", "--out", str(tmp_path)])
    text = (tmp_path / "family.md").read_text()
    assert text == (RESULTS / "family.md").read_text()
    report = json.loads((tmp_path / "family.json").read_text())
    assert len(report["members"]) == 18
    for what, _, worst, _, limit, met, _ in target_rows(report):
        assert met == (worst is not None and worst <= limit)
        assert f"| {what} |" in text


def _curve(*points):
    return [{"error": e, "time": {"median": t}} for e, t in points]


def test_family_ratios_at_an_error():
    """Interpolated log–log where a sweep brackets the error, the cheapest point where the
    whole sweep is within it, infinite where bundledyn's sweep does not reach it, and
    unmeasured where MuJoCo's does not."""
    from benchmarks.family.measure import ratios

    mujoco = _curve((1e-7, 1.0), (1e-9, 4.0), (1e-11, 16.0))
    ours = _curve((1e-6, 0.5), (1e-8, 1.0), (1e-10, 2.0))
    r = ratios({"RKMK87": ours, "MuJoCo RK4": mujoco})
    assert r["coarse_error"] == 1e-7
    np.testing.assert_allclose(r["coarse"], np.sqrt(0.5 * 1.0) / 1.0)  # halfway in log
    np.testing.assert_allclose(r["fine"], np.sqrt(1.0 * 2.0) / 4.0)
    fast = _curve((1e-12, 0.1), (1e-13, 0.2))
    assert ratios({"RKMK87": fast, "MuJoCo RK4": mujoco})["fine"] == 0.1 / 4.0
    short = _curve((1e-6, 0.5), (1e-8, 1.0))
    assert ratios({"RKMK87": short, "MuJoCo RK4": mujoco})["fine"] == float("inf")
    assert ratios({"RKMK87": ours, "MuJoCo RK4": mujoco[:1]})["fine"] is None
    assert ratios({})["coarse"] is None
    # The alternative solver's, under its own key; a setting whose solve failed (no time,
    # infinite error) counts for nothing.
    failed = {"error": float("inf"), "steps": None}
    r = ratios({"RKMK87": ours, "RKMK54": [failed, *fast], "MuJoCo RK4": mujoco})
    assert r["RKMK54 fine"] == 0.1 / 4.0 and r["RKMK54 coarse"] == 0.1 / 1.0
    np.testing.assert_allclose(r["fine"], np.sqrt(1.0 * 2.0) / 4.0)
    assert ratios({"RKMK87": ours, "RKMK54": [failed], "MuJoCo RK4": mujoco})["RKMK54 fine"] == (
        float("inf")
    )


def _gradient_part(forward, grads, vjps, failed=None):
    """A member's synthetic gradient part: times in seconds, `grads` per adjoint."""
    stats = lambda t: {"median": t, "min": t, "max": t}  # noqa: E731
    adjoints = {name: {"grad": stats(forward * r), "compile": 1.0} for name, r in grads.items()}
    adjoints |= {failed: {"error": "RuntimeError: diverged"}} if failed else {}
    ratios = {name: grads.get(name) for name in adjoints} | {
        "field_vjp": vjps[0],
        "step_vjp": vjps[1],
    }
    return {"forward": stats(forward), "adjoints": adjoints, "ratios": ratios}


def test_family_gradient_part_reports_and_merges(monkeypatch):
    """The gradient part (synthetic numbers on the committed members): its targets are the
    worst case over the members measured, a failed adjoint is “–” and listed, a report of
    the gradients alone draws without the MuJoCo columns; `--only gradient` adds to the
    results already there and `--only mujoco` keeps their gradients."""
    from benchmarks.family.cli import kept
    from benchmarks.family.gradient import checked_sampler, gradient_header
    from benchmarks.family.report import markdown, target_rows

    report = json.loads((RESULTS / "family.json").read_text())
    monkeypatch.setattr("benchmarks._provenance.provenance", lambda: report["provenance"])
    report["gradient"] = gradient_header(("bundledyn",), 3, report["horizons"])
    names = report["gradient"]["adjoints"]
    for member in report["members"]:  # the committed run's gradients give way to these
        member.pop("gradient", None)
    first, second = report["members"][:2]
    first["gradient"] = _gradient_part(
        0.01, dict(zip(names, (3.0, 3.2, 3.5, 9.0), strict=True)), (2.0, 2.5)
    )
    second["gradient"] = _gradient_part(
        0.02, dict(zip(names[:3], (5.0, 4.5, 2.0), strict=True)), (4.0, 1.0), names[3]
    )
    rows = {row[0]: row for row in target_rows(report)}
    (default,) = (row for what, row in rows.items() if "simulate's default" in what)
    assert default[1:] == (4.0, 5.0, second["name"], 4.0, False, 2)  # median, worst, …
    backsolve = rows["gradient / forward solve, BacksolveAdjoint"]
    assert backsolve[2:] == (9.0, first["name"], 4.0, False, 1)
    assert rows["RKMK87 step's VJP / step"][2:4] == (2.5, first["name"])
    text = markdown(report)
    assert f"| {first['name']} |" in text and "| 10 | 3 | 3.2 | 3.5 | 9 | 2 | 2.5 |" in text
    assert "| 20 | 5 | 4.5 | 2 | – | 4 | 1 |" in text
    assert f"- {second['name']}, BacksolveAdjoint: RuntimeError: diverged" in text
    assert "| one field evaluation / mj_forward |" in text

    alone = report | {
        "members": [{k: v for k, v in first.items() if k not in ("field", "solves", "ratios")}]
    }
    text = markdown(alone)
    assert "mj_forward" not in text and "| 3 | 3.2 | 3.5 | 9 | 2 | 2.5 |" in text

    fresh = {"horizons": report["horizons"], "members": []}
    merged, known = kept(dict(fresh), report, ("gradient",))
    assert merged["provenance"] == report["provenance"] and merged["members"] == []
    assert known[first["name"]] is first
    remeasured, _ = kept(dict(fresh), report, ("mujoco",))
    assert remeasured["gradient"] is report["gradient"]
    assert kept(dict(fresh), None, ("gradient",)) == (fresh, {})

    assert checked_sampler(lambda: np.full(2, np.inf))[2] == "non-finite gradient"
    assert checked_sampler(lambda: 1 / 0)[2].startswith("ZeroDivisionError")
    sampler, seconds, error = checked_sampler(lambda: np.ones(2))
    assert error is None and seconds >= 0.0 and sampler() is None


def test_stress_results_redraw_and_the_docs_quote_them(tmp_path):
    """The committed stress results rebuild the same markdown (`--report-only`), record the
    code they measured, cover the battery and every shipped model, and the hard-cases guide's
    table is the one they give."""
    from benchmarks._output import RESULTS
    from benchmarks.stress.cli import MODELS, main, summary_table

    (tmp_path / "stress.json").write_bytes((RESULTS / "stress.json").read_bytes())
    main(["--report-only", "--out", str(tmp_path)])
    assert (tmp_path / "stress.md").read_text() == (RESULTS / "stress.md").read_text()
    report = json.loads((RESULTS / "stress.json").read_text())
    assert report["provenance"]["commit"] and not report["quick"]
    assert [b["model"] for b in report["reports"][1:]] == [*MODELS, "humanoid.xml"]
    assert all(r["passed"] for b in report["reports"] for r in b["rows"])
    guide = (pathlib.Path(__file__).parents[1] / "docs" / "how-to" / "stress.md").read_text()
    assert summary_table(report) in guide


@pytest.mark.slow  # three evaluations of bundledyn's fit cost and four of mujoco.sysid's
# Each cost solves every window of the record: unoptimised, the second and third took 13 s
# each, optimised 1 s (one core).
@pytest.mark.usefixtures("optimized_test_compilation")
def test_the_identification_benchmark_poses_each_method_the_problem_that_made_the_record():
    """On the arm's noise-free record (motors following the torque log read linearly), the
    cost at the true parameters over the cost at the start is at rounding level for
    bundledyn (reading the log linearly) and, where it is installed, for mujoco.sysid
    (given what each step held) alone and over 8 pieces; read as a cubic through the log's
    samples, a different signal, bundledyn's ratio is far from it, as the benchmark's check
    would say before timing anything."""
    import dataclasses as dc

    mujoco = pytest.importorskip("mujoco")
    import bundledyn as bd
    from benchmarks.identification import metric, records, sysid
    from benchmarks.identification.cases import CASES, nominal_spec
    from benchmarks.identification.ours import Bundledyn
    from benchmarks.identification.run import ROUNDING, SEGMENTS

    case = CASES["arm"]
    P_true = metric.model_pseudo_inertias(mujoco.MjModel.from_xml_string(case.mjcf), case.bodies)
    P_nominal = metric.model_pseudo_inertias(nominal_spec(case).compile(), case.bodies)
    ours = Bundledyn(case, P_nominal)
    record = records.noisy_record(case, 0, 0.0)
    start = ours.cost_at(record, P_nominal)
    ratios = {"bundledyn": ours.cost_at(record, P_true) / start}
    if sysid.available():  # the check's other half, as `costs_at_truth` computes it
        truth = mujoco.MjSpec.from_string(case.mjcf)
        for method, segments in (("sysid", 1), ("sysid_segments", SEGMENTS)):
            at_truth = sysid.cost_at(case, record, truth, segments)
            ratios[method] = at_truth / sysid.cost_at(case, record, nominal_spec(case), segments)
    assert max(ratios.values()) <= ROUNDING, ratios
    assert record.inputs is not None
    cubic = bd.identify.Inputs(record.inputs.ts, joint_forces=record.inputs.joint_forces)
    assert ours.cost_at(dc.replace(record, inputs=cubic), P_true) / start > 100 * ROUNDING


@pytest.mark.parametrize("name", ["survey", "devices"])
def test_survey_and_devices_reports_redraw_from_their_json(tmp_path, name):
    """The committed results rebuild the same markdown (`--report-only`)."""
    from importlib import import_module

    (tmp_path / f"{name}.json").write_bytes((RESULTS / f"{name}.json").read_bytes())
    import_module(f"benchmarks.{name}").main(["--report-only", "--out", str(tmp_path)])
    assert (tmp_path / f"{name}.md").read_text() == (RESULTS / f"{name}.md").read_text()


@pytest.mark.slow  # two models imported, compiled and solved beside MuJoCo
def test_the_survey_compares_each_model_with_mujoco(tmp_path):
    """The quick survey (bundledyn's two floating MJCF models, 0.1 s): both import, their
    metric is MuJoCo's mass matrix to 1e-12 and their motion MuJoCo RK4's to 1e-9; every
    tolerance of the sweep reaches the fine reference to its own order, the gradient is
    timed, and the diagram is drawn."""
    from benchmarks import survey

    assert survey.main(["--quick", "--out", str(tmp_path), "--repeats", "2"]) == 0
    report = json.loads((tmp_path / "survey_quick.json").read_text())
    assert [m["status"] for m in report["models"]] == ["imported", "imported"]
    assert all(m["passed"] and m["metric_error"] < 1e-12 for m in report["models"])
    for m in report["models"]:
        assert all(p["error"] < 100 * p["setting"] for p in m["solves"]["points"]), m["solves"]
        assert m["gradient"]["ratio"] > 0 and m["gradient"]["compile"]["grad"] > 0
    assert report["figure"] == "survey.png" and (tmp_path / "survey.png").stat().st_size > 0
    assert (
        "2 model files: 2 import, 2 of them equal MuJoCo"
        in (tmp_path / "survey_quick.md").read_text()
    )


@pytest.mark.slow  # a worker process per device count, each compiling the batch
def test_the_devices_benchmark_spreads_the_batch_as_one_device_runs_it(tmp_path):
    """The quick run (64 rollouts on 1 and 2 devices): each count's final poses are one
    device's `jax.vmap`'s, with MuJoCo's rollout timed beside them. At the batch's rtol
    (5e-7) the adaptive steps carry the two programs' different rounding to about 1e-10
    (under the suite's unoptimised compilation); `test_batches.py` shows the equality to
    1e-13 at rtol 1e-10."""
    from benchmarks import devices

    assert devices.main(["--quick", "--out", str(tmp_path)]) == 0
    report = json.loads((tmp_path / "devices_quick.json").read_text())
    assert [entry["devices"] for entry in report["counts"]] == [1, 2]
    for entry in report["counts"]:
        method = entry["methods"]["RKMK87"]
        assert method["difference_from_one_device"] < 1e-9 and method["lockstep_overhead"] >= 1
        assert entry["methods"]["MuJoCo"]["rollouts_per_second"] > 0


def test_identification_parts_merge_only_where_they_measured_this_code(tmp_path):
    """`--merge` joins the parts of a run split case by case (`parts.py`) into the report
    a run in one piece writes: the cases in order, the family summarized, each part's
    commit listed; a part of other code, or run with other settings, is refused by name."""
    from benchmarks import identification
    from benchmarks._provenance import code_hash
    from benchmarks.identification import parts

    whole = json.loads((RESULTS / "identification.json").read_text())
    settings = {key: whole.get(key) for key in parts.SETTINGS}
    for name in ("tumble", "chain"):  # written out of order
        part = {key: value for key, value in whole.items() if key not in ("cases", "seconds")}
        part["provenance"] = whole["provenance"] | {"code": code_hash(), "dirty": False}
        part["cases"] = {name: whole["cases"][name] | {"seconds": 10.0}}
        parts.write(tmp_path, name, part)
    assert parts.current(tmp_path, "chain", settings)
    assert not parts.current(tmp_path, "chain", settings | {"seeds": 5})
    assert not parts.current(tmp_path, "arm", settings)
    report = identification.main(["--merge", "--out", str(tmp_path)])
    assert list(report["cases"]) == ["chain", "tumble"]
    assert report["seconds"] == 20.0
    assert report["cases"]["chain"]["summary"] == whole["cases"]["chain"]["summary"]
    text = (tmp_path / "identification.md").read_text()
    assert "Merged from 2 parts" in text and f"`{whole['provenance']['commit'][:12]}`" in text

    stale = json.loads(parts.path(tmp_path, "tumble").read_text())
    stale["provenance"]["code"] = "another"
    parts.path(tmp_path, "tumble").write_text(json.dumps(stale))
    with pytest.raises(SystemExit, match=r"\['tumble'\] measured other code"):
        identification.main(["--merge", "--out", str(tmp_path)])
    stale["provenance"]["code"], stale["seeds"] = code_hash(), 7
    parts.path(tmp_path, "tumble").write_text(json.dumps(stale))
    with pytest.raises(SystemExit, match=r"\['tumble'\] were run with other settings"):
        identification.main(["--merge", "--out", str(tmp_path)])
