"""The command line: `run` writes what a scene file asks for, `check` reports, mistakes exit cleanly."""

import json
import os
import pathlib
import re
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from systems import picture_size

import bundledyn as bd
from bundledyn._cli import main

# A torque-free body near its intermediate axis: energy and momentum are conserved.
DZHANIBEKOV = """
[system]
type = "rigid_body"
mass = 1.0
solid = "box"
size = [0.6, 0.4, 0.2]

[initial]
xi = [0.05, 6.0, 0.05, 0.0, 0.0, 0.0]

[time]
t1 = 4.0
saves = 41

[solver]
rtol = 1e-11
atol = 1e-13

[output]
trajectory = "spin.npz"
animation = true
frames = 6
"""


@pytest.fixture(scope="module")
def ran(tmp_path_factory):
    folder = tmp_path_factory.mktemp("run")
    scene = folder / "dzhanibekov.toml"
    scene.write_text(DZHANIBEKOV)
    out = folder / "out"
    out.mkdir()
    return scene, out, main(["run", str(scene), "--out", str(out)])


def test_run_writes_trajectory_with_its_scene(ran):
    scene, out, code = ran
    assert code == 0
    with np.load(out / "spin.npz") as archive:
        data = dict(archive)
    assert str(data["scene"]) == scene.read_text()
    metadata = json.loads(str(data["metadata"]))
    assert metadata["solver"] == "RKMK87" and metadata["bundledyn"] == bd.__version__
    assert data["g"].shape == (41, 4, 4) and data["q"].shape == (41, 0)
    np.testing.assert_allclose(data["ts"], np.linspace(0.0, 4.0, 41))
    # Torque-free: energy and spatial momentum conserved (to the solver's tolerance).
    energy, momentum = data["energy"], data["spatial_momentum"]
    assert np.abs(energy - energy[0]).max() < 1e-9 * energy[0]
    assert np.abs(momentum - momentum[0]).max() < 1e-9 * np.abs(momentum[0]).max()
    # The intermediate-axis flip happened (the Dzhanibekov effect), so something was simulated.
    assert data["xi"][:, 1].min() < -5.0


def test_run_writes_pictures_of_the_expected_size(ran):
    _, out, _ = ran
    assert picture_size(out / "spin_motion.png") == (700, 450, 1)
    assert picture_size(out / "spin_drift.png") == (700, 400, 1)
    assert picture_size(out / "spin.gif") == (320, 400, 6)
    assert sorted(p.name for p in out.iterdir()) == [
        "spin.gif",
        "spin.npz",
        "spin_drift.png",
        "spin_motion.png",
    ]


# The same box in gravity, seen from a frame falling with it (Theorem 3.4).
FALLING = """
[system]
type = "rigid_body"
mass = 1.0
solid = "box"
size = [0.6, 0.4, 0.2]

[[effects]]
type = "gravity"

[frame]
type = "free_falling"

[initial]
xi = [0.05, 6.0, 0.05, 0.0, 0.0, 0.0]

[time]
t1 = 0.5
saves = 6

[solver]
method = "LieEuler"
dt0 = 0.01
"""


def test_run_names_the_frame_of_every_printed_quantity(tmp_path, capsys):
    """Seen from a falling frame, the poses are in that frame while the energy and spatial
    momentum are in the Galilean frame: each printed line says which."""
    scene = tmp_path / "falling.toml"
    scene.write_text(FALLING)
    assert main(["run", str(scene), "--out", str(tmp_path), "--no-pictures"]) == 0
    lines = capsys.readouterr().out.splitlines()
    printed = {line.split()[0]: line for line in lines[1:] if not line.startswith("  wrote")}
    assert printed["system:"].endswith("seen from the falling frame")
    assert "; 1 effect; " in printed["system:"]
    assert printed["energy"].startswith("  energy in the Galilean frame: E(t1) - E(t0) = ")
    assert printed["spatial"].startswith("  spatial momentum in the Galilean frame (about its")
    assert printed["poses"].startswith("  poses in the falling frame: rotations orthogonal to")
    assert set(printed) == {"system:", "simulated", "energy", "spatial", "poses"}


def test_bad_scene_exits_with_a_message_and_writes_nothing(tmp_path, capsys):
    scene = tmp_path / "bad.toml"
    scene.write_text(DZHANIBEKOV.replace("size = [0.6, 0.4, 0.2]", "size = [0.6, 0.4]"))
    assert main(["run", str(scene), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "bad.toml" in err and "system.size" in err and "[0.6, 0.4]" in err
    assert [p.name for p in tmp_path.iterdir()] == ["bad.toml"]


def test_run_refuses_a_model_file_saying_what_it_takes(tmp_path, capsys):
    assert main(["run", str(bd.models / "chain5.xml"), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "chain5.xml" in err and "scene file (.toml)" in err and 'type = "mjcf"' in err
    assert list(tmp_path.iterdir()) == []


def test_a_terminated_run_leaves_no_file_behind(tmp_path, monkeypatch):
    """SIGTERM while the trajectory is being written: the half-written file goes, and the
    command exits as a terminated process does (128 + 15)."""
    scene = tmp_path / "spin.toml"
    scene.write_text(DZHANIBEKOV.replace("t1 = 4.0", "t1 = 1.0"))

    def terminated_while_writing(path, **arrays):
        pathlib.Path(path).write_bytes(b"half a file")
        os.kill(os.getpid(), signal.SIGTERM)

    handler = signal.getsignal(signal.SIGTERM)
    monkeypatch.setattr(np, "savez", terminated_while_writing)
    with pytest.raises(SystemExit) as info:
        main(["run", str(scene), "--out", str(tmp_path), "--no-pictures"])
    assert info.value.code == 128 + signal.SIGTERM
    assert [p.name for p in tmp_path.iterdir()] == ["spin.toml"]
    assert signal.getsignal(signal.SIGTERM) == handler


def test_failed_solve_exits_and_leaves_no_output(tmp_path, capsys):
    scene = tmp_path / "short.toml"
    scene.write_text(DZHANIBEKOV.replace("atol = 1e-13", "atol = 1e-13\nmax_steps = 3"))
    assert main(["run", str(scene), "--out", str(tmp_path)]) == 1
    assert "maximum number of solver steps" in capsys.readouterr().err
    assert [p.name for p in tmp_path.iterdir()] == ["short.toml"]


def test_run_over_a_batch_of_initial_states_is_each_run_alone(tmp_path, capsys):
    """`--batch` simulates every row of an .npz's `xi` (the rest from the file's
    [initial]) in chunks of two, spread over the devices: each member's saved poses and
    energy are those of its run alone, and the summary says what lockstep cost."""
    scene = tmp_path / "spin.toml"
    scene.write_text(DZHANIBEKOV)
    # Spins far from the intermediate axis, whose flip would amplify the rounding
    # differences between a batched program and a single one.
    xi = np.array(
        [
            [6.0, 0.05, 0.05, 0.0, 0.0, 0.0],
            [0.05, 0.05, 5.0, 0.0, 0.0, 0.0],
            [2.0, 0.3, 3.0, 0.1, 0.0, 0.0],
        ]
    )
    np.savez(tmp_path / "states.npz", xi=xi)
    command = ["run", str(scene), "--out", str(tmp_path), "--batch", str(tmp_path / "states.npz")]
    assert main([*command, "--chunk-size", "2"]) == 0
    out = capsys.readouterr().out
    assert "3 members on 1 device, 2 at a time" in out and "chunk 2/2: members 2-2 of 3" in out
    assert "lockstep ran" in out and "energy: largest" in out
    with np.load(tmp_path / "spin_batch.npz") as archive:
        saved = dict(archive)
    assert len(set(saved["num_steps"].tolist())) == 3
    file = bd.SceneFile.load(scene)
    for member, twist in enumerate(xi):
        alone = file.simulate(state=bd.State(file.state.g, file.state.q, twist))
        # A batched program rounds differently from a single one, and the step-size
        # controller carries that to the solve's tolerance (the file's rtol, 1e-11).
        np.testing.assert_allclose(saved["g"][member], alone.g, rtol=0, atol=1e-10)
        np.testing.assert_allclose(saved["energy"][member], alone.energy(), rtol=1e-12)
        assert abs(int(saved["num_steps"][member]) - int(alone.stats["num_steps"])) <= 1


@pytest.mark.parametrize(
    "arrays, message",
    [
        ({"xi": np.zeros((3, 5))}, r"`xi` has shape \(3, 5\).*need \(3, 6\)"),
        ({"omega": np.zeros((3, 3))}, r"arrays named g, q, xi, qdot.*\['omega'\]"),
    ],
)
def test_a_batch_that_does_not_fit_the_scene_is_refused(tmp_path, capsys, arrays, message):
    scene = tmp_path / "spin.toml"
    scene.write_text(DZHANIBEKOV)
    np.savez(tmp_path / "states.npz", **arrays)
    assert main(["run", str(scene), "--batch", str(tmp_path / "states.npz")]) == 1
    assert re.search(message, capsys.readouterr().err)


def test_progress_meter(tmp_path, capsys):
    scene = tmp_path / "spin.toml"
    scene.write_text(DZHANIBEKOV.replace("t1 = 4.0", "t1 = 1.0"))
    assert main(["run", str(scene), "--out", str(tmp_path), "--progress", "--no-pictures"]) == 0
    out = capsys.readouterr().out
    assert "100.00%" in out and [p.name for p in sorted(tmp_path.iterdir())] == [
        "spin.npz",
        "spin.toml",
    ]


def test_missing_files(tmp_path, capsys):
    assert main(["run", str(tmp_path / "none.toml")]) == 2
    assert main(["check", str(tmp_path / "none.xml")]) == 2
    err = capsys.readouterr().err
    assert err.count("no such file") == 1 and "cannot read the file" in err


def test_demo_summarises_and_checks(tmp_path, capsys):
    assert main(["demo", "--no-pictures", "--out", str(tmp_path / "demo")]) == 0
    out = capsys.readouterr().out
    angle = float(out.split("net rotation after one shape loop: ")[1].split(" deg")[0])
    assert 10.0 < angle < 180.0
    (turn,) = [line for line in out.splitlines() if "net rotation" in line]
    assert turn.endswith("] in the Galilean frame")
    assert "PASSED" in out and not (tmp_path / "demo").exists()


def test_check_reports_invariance(capsys):
    # The demo's model and sample count: its compiled check is reused.
    assert main(["check", str(bd.scenes / "falling_cat.toml"), "--samples", "64"]) == 0
    out = capsys.readouterr().out
    assert "on 64 sampled shapes" in out and "PASSED" in out


def test_run_and_check_a_model_with_passive_joints_and_its_gravity(tmp_path, capsys):
    """A scene file takes an MJCF model with its springs, dampers and gravity (`passive`,
    `gravity = "model"`); `run` simulates it and `check` finds the imported model (rotor
    inertia included) Galilean-invariant."""
    from systems import PASSIVE

    (tmp_path / "model.xml").write_text(PASSIVE)
    scene = tmp_path / "passive.toml"
    scene.write_text(
        '[system]\ntype = "mjcf"\npath = "model.xml"\npassive = true\ngravity = "model"\n'
        "[initial]\nxi = [0.3, 0.2, -0.4, 0.1, 0.0, 0.2]\nqdot = 0.5\n"
        "[time]\nt1 = 0.5\nsaves = 11\n"
    )
    with pytest.warns(UserWarning, match="tendon"), pytest.warns(UserWarning, match=r"'j2' \(ref"):
        assert main(["run", str(scene), "--out", str(tmp_path), "--no-pictures"]) == 0
        assert main(["check", str(tmp_path / "model.xml"), "--samples", "16"]) == 0
        effects = [type(e).__name__ for e in bd.SceneFile.load(scene).scene.effects]
    printed = capsys.readouterr().out
    assert "PASSED" in printed and "FAILED" not in printed
    assert effects == ["ShapeDamper", "ShapeSpring", "ShapeSpring", "Gravity"]


def test_console_script_is_installed_as_a_module():
    result = subprocess.run(
        [sys.executable, "-m", "bundledyn", "--help"], capture_output=True, text=True, check=True
    )
    assert all(c in result.stdout for c in ("demo", "run", "check"))


def test_scene_file_docstring_names_every_solver():
    doc = textwrap.dedent(bd.SceneFile.__doc__)
    from bundledyn._scene_file import SOLVERS

    assert all(f"`{name}`" in doc for name in SOLVERS)
