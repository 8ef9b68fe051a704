"""Scene files of chains of Lagrange gyroscopes (issue 58): the shipped file, its initial states
read as MuJoCo reads the same joints, the command line's run and its first integrals, the
formulations from files, and the mistakes named.

The independent reference for the initial states is MuJoCo's forward kinematics of the
chain's own MJCF, with the file's numbers as its `qpos`/`qvel`."""

import re
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import bundledyn as bd
from bundledyn import lie
from bundledyn._cli import main

SHIPPED = bd.scenes / "gyroscope_chain.toml"

UNIVERSAL = """
[gyroscopes]
masses = [1.0, 0.8, 0.6]
lengths = [0.4, 0.35, 0.3]
centres = [0.2, 0.18, 0.15]
transverse_inertias = [0.01, 0.008, 0.006]
axial_inertias = [0.006, 0.005, 0.004]
formulation = "universal"

[initial]
rotation = [0.3, 0.2, 0.0]
rate = [0.5, 0.2, 30.0]
angles = [[0.4, -0.3], [0.2, 0.5]]
angle_rates = [[1.0, -2.0], [0.5, 1.5]]

[time]
t1 = 0.5
saves = 11
"""


def _write(tmp_path, text, name="chain.toml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def _mujoco_bodies(chain, joints, qpos, qvel):
    """MuJoCo's body rotations and world angular velocities at `qpos`, `qvel`."""
    mujoco = pytest.importorskip("mujoco")
    model = mujoco.MjModel.from_xml_string(chain.to_mjcf(joints))
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = qpos, qvel
    mujoco.mj_forward(model, data)
    return data.xmat[2:].reshape(-1, 3, 3), data.cvel[2:, :3]


def test_the_shipped_file_starts_where_mujoco_puts_the_same_ball_joints():
    """The file's relative rotation vectors and rates, as MuJoCo's ball-joint qpos (their
    quaternions) and qvel, give MuJoCo's bodies the rotations and angular velocities of the
    file's initial state, to 1e-14; the chain is the one the file lists."""
    chain_file = bd.GyroscopeChainFile.load(SHIPPED)
    assert chain_file.formulation == "rotations" and chain_file.chain.size == 3
    np.testing.assert_array_equal(chain_file.chain.masses, [1.0, 0.8, 0.6])
    turns = [[0.3, 0.2, 0.0], [0.4, -0.2, 0.1], [-0.2, 0.3, 0.0]]
    rates = [[0.5, 0.2, 30.0], [0.1, -0.3, -5.0], [0.0, 0.2, -45.0]]
    quaternions = [lie.quaternion_from_rotation(lie.so3_exp(jnp.asarray(t))) for t in turns]
    Z, omega = _mujoco_bodies(
        chain_file.chain, "ball", np.concatenate(quaternions), np.ravel(rates)
    )
    X, V = chain_file.y0
    np.testing.assert_allclose(X.rotations, Z, rtol=0, atol=1e-14)
    np.testing.assert_allclose(V.rotations, omega, rtol=0, atol=1e-13)


def test_a_universal_joint_file_starts_where_mujoco_puts_the_same_hinges(tmp_path):
    """Body 1's rotation and rate and the joints' angles and rates, as MuJoCo's qpos/qvel of
    the universal chain's MJCF, give its bodies the rotations and angular velocities of the
    file's state (through `universal_joint_rotations` and the relative axes' rates)."""
    chain_file = bd.GyroscopeChainFile.load(_write(tmp_path, UNIVERSAL))
    qpos = np.concatenate(
        [
            lie.quaternion_from_rotation(lie.so3_exp(jnp.array([0.3, 0.2, 0.0]))),
            [0.4, -0.3, 0.2, 0.5],
        ]
    )
    qvel = np.array([0.5, 0.2, 30.0, 1.0, -2.0, 0.5, 1.5])
    Z, omega = _mujoco_bodies(chain_file.chain, "universal", qpos, qvel)
    X, V = chain_file.y0
    bodies = chain_file.bodies(*jax.tree.map(lambda x: x[None], (X, V)))
    np.testing.assert_allclose(bodies.rotations[0], Z, rtol=0, atol=1e-14)
    np.testing.assert_allclose(bodies.angular_velocities[0], omega, rtol=0, atol=1e-13)


def test_the_command_line_runs_the_shipped_chain_and_reports_its_first_integrals(tmp_path, capsys):
    """`bundledyn run` on the shipped chain prints the energy and the vertical angular
    momentum with their drifts and writes them, the rotations and a plot: over 3 s at rtol
    1e-11 both drift by less than 1e-8 of their scale, and the rotations stay orthogonal to
    1e-14."""
    assert main(["run", str(SHIPPED), "--out", str(tmp_path)]) == 0
    printed = capsys.readouterr().out
    assert "3 Lagrange gyroscopes in rotations" in printed
    assert "vertical angular momentum about the pivot" in printed
    with np.load(tmp_path / "gyroscope_chain.npz") as saved:
        energy, vertical = saved["energy"], saved["vertical_momentum"]
        Z = saved["rotations"]
    assert np.abs(energy - energy[0]).max() < 1e-8 * abs(energy[0])
    assert np.abs(vertical - vertical[0]).max() < 1e-8 * abs(vertical[0])  # 1.69 kg m²/s
    assert np.abs(np.swapaxes(Z, -1, -2) @ Z - np.eye(3)).max() < 1e-14
    assert np.abs(Z[-1] - Z[0]).max() > 1.0  # the chain does move
    assert (tmp_path / "gyroscope_chain_drift.png").stat().st_size > 1000


def test_the_chain_in_axes_from_a_file_moves_as_in_rotations(tmp_path):
    """The shipped chain with `formulation = "axes"` moves its bodies as the file in
    rotations does, to 1e-8 over 0.5 s."""
    text = SHIPPED.read_text().replace('formulation = "rotations"', 'formulation = "axes"')
    text = text.replace("t1 = 3.0", "t1 = 0.5\nsaves = 6")
    rotations_text = SHIPPED.read_text().replace("t1 = 3.0", "t1 = 0.5\nsaves = 6")
    moved = []
    for name, body in (("axes.toml", text), ("rotations.toml", rotations_text)):
        chain_file = bd.GyroscopeChainFile.load(_write(tmp_path, body, name))
        solution = chain_file.solve()
        moved.append(chain_file.bodies(*solution.ys).rotations[..., 2])
    np.testing.assert_allclose(moved[0], moved[1], rtol=0, atol=1e-8)


MISTAKES = {
    "formulation": (
        ("rotations", 'formulation = "rotations"', 'formulation = "angles"'),
        "field `gyroscopes.formulation` = 'angles': must be one of axes, rotations, universal",
    ),
    "shape": (
        ("rotations", "centres = [0.2, 0.18, 0.15]", "centres = [0.2, 0.18]"),
        "field `gyroscopes.centres` = [0.2, 0.18]: must be numbers of shape (3,)",
    ),
    "unknown field": (
        ("rotations", "[time]", "[time]\nt_end = 2.0"),
        "unknown field `time.t_end`",
    ),
    "fixed step without dt0": (
        ("rotations", "[solver]", '[solver]\nmethod = "TensorialRKMK4"'),
        "TensorialRKMK4 takes fixed steps: give the step `dt0`",
    ),
    "negative mass": (
        ("rotations", "masses = [1.0, 0.8, 0.6]", "masses = [1.0, -0.8, 0.6]"),
        "masses` must be finite and positive",
    ),
    "initial rates of the wrong shape": (
        (
            "rotations",
            "rates = [[0.5, 0.2, 30.0], [0.1, -0.3, -5.0], [0.0, 0.2, -45.0]]",
            "rates = [1.0]",
        ),
        "field `initial.rates` = [1.0]: must be numbers of shape (3, 3)",
    ),
}


@pytest.mark.parametrize("mistake", MISTAKES)
def test_mistakes_name_the_file_the_field_and_the_value(tmp_path, mistake):
    (_, old, new), message = MISTAKES[mistake]
    text = SHIPPED.read_text()
    assert old in text
    path = _write(tmp_path, text.replace(old, new))
    with pytest.raises(bd.SceneFileError, match=re.escape(message)):
        bd.GyroscopeChainFile.load(path)
