"""The documentation site builds with `mkdocs build --strict`, and documents every public name."""

import html
import json
import os
import pathlib
import re
import socket
import subprocess
import sys
from importlib import import_module

import numpy as np
import pytest

import bundledyn as bd

ROOT = pathlib.Path(__file__).resolve().parents[1]
SUBMODULES = ("lie", "checks", "identify", "stress", "viz")


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """The site built once, strictly: a broken link or reference, or any warning, fails it."""
    out = tmp_path_factory.mktemp("site")
    done = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env=dict(os.environ, NO_MKDOCS_2_WARNING="1"),
    )
    assert done.returncode == 0, done.stderr[-4000:]
    return out


def public_names():
    """Every public name, as its reference entry's anchor: `bundledyn.X`, `bundledyn.lie.Y`, ..."""
    names = [f"bundledyn.{n}" for n in bd.__all__ if n not in SUBMODULES]
    for module in SUBMODULES:
        names += [f"bundledyn.{module}.{n}" for n in import_module(f"bundledyn.{module}").__all__]
    return names


def reference_entries(site):
    """Each anchor on the API pages with the text of its entry's documentation."""
    entries = {}
    for page in (site / "api").rglob("index.html"):
        text = page.read_text()
        headings = list(re.finditer(r'<h[2-4] id="([\w.]+)" class="doc doc-heading">', text))
        for here, after in zip(headings, headings[1:] + [None], strict=True):
            body = text[here.end() : after.start() if after else len(text)]
            body = re.sub(r'<p class="doc doc-class-bases">.*?</p>', "", body, flags=re.S)
            contents = re.search(r'<div class="doc doc-contents[^>]*>', body)
            words = re.sub(r"<[^>]+>", " ", body[contents.end() :]) if contents else ""
            entries[here.group(1)] = " ".join(html.unescape(words).split())
    return entries


def test_every_public_name_has_a_documented_reference_entry(site):
    entries = reference_entries(site)
    missing = [n for n in public_names() if n not in entries]
    assert not missing, f"not on any API page (docs/api/*.md): {missing}"
    # An entry without a docstring renders its heading and signature only.
    bare = [n for n in public_names() if len(entries[n]) < 20]
    assert not bare, f"rendered without documentation: {bare}"


def test_simulate_is_documented_as_a_function_with_its_signature(site):
    page = html.unescape(
        re.sub(r"<[^>]+>", "", (site / "api" / "simulate" / "index.html").read_text())
    )
    assert "functools.wraps" not in page and "_numbers_as_data" not in page
    assert re.search(
        r"simulate\(\s*scene.*state0.*t1.*rtol.*=.*None.*max_steps.*=.*16384", page, flags=re.S
    )


def test_the_reference_check_sees_a_missing_docstring(site, tmp_path):
    """The check above reads what a reader sees: an entry with its text removed is caught."""
    page = (site / "api" / "simulate" / "index.html").read_text()
    start = page.index('id="bundledyn.project_to_se3"')
    contents = page.index('<div class="doc doc-contents', start)
    end = page.index("</div>", contents)
    emptied = page[:contents] + '<div class="doc doc-contents first">' + page[end:]
    copy = tmp_path / "api" / "simulate"
    copy.mkdir(parents=True)
    (copy / "index.html").write_text(emptied)
    assert len(reference_entries(tmp_path)["bundledyn.project_to_se3"]) < 20
    assert len(reference_entries(site)["bundledyn.project_to_se3"]) > 100


def test_notebooks_and_results_are_pages(site):
    """The notebooks render with their figures, and every results file is a page."""
    for notebook in (ROOT / "notebooks").glob("*.ipynb"):
        page = (site / "notebooks" / notebook.stem / "index.html").read_text()
        assert "data:image/png;base64" in page, notebook.name
    for results in (ROOT / "benchmarks" / "results").glob("*.md"):
        assert (site / "results" / results.stem / "index.html").exists(), results.name


def test_readme_is_short_and_links_into_the_docs():
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 200
    linked = set(re.findall(r"\(docs/([\w/.-]+\.md)", readme))
    assert linked, "the README links no documentation page"
    assert all((ROOT / "docs" / page).exists() for page in linked), linked


def first_python_block(path):
    """The first ```python block of a page: the example a reader copies."""
    return re.findall(r"```python\n(.*?)```", (ROOT / path).read_text(), re.S)[0]


def run_example(path, cwd, **environment):
    env = dict(
        os.environ,
        PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
        **environment,
    )
    done = subprocess.run(
        [sys.executable, "-c", first_python_block(path)],
        cwd=cwd,
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-4000:]
    return done.stdout


def test_the_readme_example_runs_and_draws(tmp_path):
    out = run_example("README.md", tmp_path)
    assert "PASSED" in out
    rotation = [float(x) for x in re.findall(r"-?\d+\.\d+(?:e-?\d+)?", out.splitlines()[-1])]
    assert rotation[0] == pytest.approx(1.33, abs=0.005)  # the comment's "1.33 rad about x"
    assert max(abs(x) for x in rotation[1:]) < 0.01  # about x: 5e-3 off the axis
    assert (tmp_path / "cat_motion.png").stat().st_size > 10_000
    assert (tmp_path / "cat.gif").stat().st_size > 10_000


@pytest.mark.slow  # an interpreter of its own compiling a batch of rollouts
def test_the_batch_guide_shards_over_two_devices(tmp_path):
    """The guide's batch runs on two devices and gives the one-device answers exactly."""
    out = run_example("docs/how-to/batches.md", tmp_path).splitlines()
    assert out[-2].count("CpuDevice") == 2
    assert float(out[-1]) < 1e-12


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("localhost", 0))
        return probe.getsockname()[1]


@pytest.mark.slow  # three interpreters compiling a batch of rollouts
def test_the_cluster_guide_runs_two_processes_as_one(tmp_path):
    """The guide's program as two `jax.distributed` processes over localhost (two CPU
    devices each: ten members on four devices, two of them in the other process) prints
    what it prints as one process alone: every member's steps, which differ, and its final
    position, to rounding."""
    program = tmp_path / "batch.py"
    program.write_text(first_python_block("docs/how-to/cluster.md"))
    env = dict(
        os.environ,
        PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
        COORDINATOR=f"localhost:{_free_port()}",
    )
    run = [sys.executable, str(program)]
    processes = [
        subprocess.Popen(run + [str(i)], cwd=tmp_path, env=env, stdout=subprocess.PIPE, text=True)
        for i in (0, 1)
    ]
    alone = subprocess.run(run, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    outputs = [p.communicate(timeout=600)[0].splitlines()[-3:] for p in processes]
    assert all(p.returncode == 0 for p in processes) and alone.returncode == 0, alone.stderr
    single = alone.stdout.splitlines()[-3:]
    assert single[0] == "1 2" and [out[0] for out in outputs] == ["2 4", "2 4"]
    steps = json.loads(single[1])
    assert len(set(steps)) > 3
    for out in outputs:
        assert json.loads(out[1]) == steps
        np.testing.assert_allclose(json.loads(out[2]), json.loads(single[2]), rtol=0, atol=1e-13)


@pytest.mark.slow  # an identification fit
def test_the_identification_guide_runs_and_its_intervals_cover_the_truth(tmp_path):
    """The guide's program, as a user runs it (compiled as users' code is): MuJoCo's record
    of the shipped chain with noise stated in MuJoCo's layout is fitted to the noise (scale
    0.9-1.1: the body-frame velocity's level includes the orientation's share), and each of
    its 24 base parameters is within 3.5 of its standard errors of the truth, χ² per base
    parameter 0.3-2.5: a second record, motion and noise beside `test_identify_mujoco.py`'s."""
    pytest.importorskip("mujoco")
    report = run_example(
        "docs/how-to/identification.md", tmp_path, JAX_DISABLE_MOST_OPTIMIZATIONS="0"
    )
    assert "not converged" not in report
    scale = float(re.search(r"noise scale ([\d.]+)", report).group(1))
    assert 0.9 < scale < 1.1
    assert "What the data determine: 24 base parameters" in report
    table = report.split("combination\n")[1].split("  Determined alone")[0]
    scores = np.array([float(line.split()[3]) for line in table.splitlines()])
    assert scores.size == 24 and np.max(np.abs(scores)) < 3.5, scores
    assert 0.3 < np.mean(scores**2) < 2.5, np.mean(scores**2)


def test_the_gradient_guide_runs(tmp_path):
    out = run_example("docs/how-to/gradients.md", tmp_path)
    assert "nan" not in out.lower()
