"""Identification of a floating chain from motion that MuJoCo generated, with 1 % noise.

MuJoCo (an independent simulator, the same MJCF, RK4 at 0.2 ms, torques from its motors,
set at every step from a smooth signal) records 4 s of a free-floating three-body chain
driven at its two hinges; the record gets 1 % Gaussian noise (of each channel's spread),
the torques are known. The fit must find what the
data determine to within the noise, with standard errors that cover the truth, name what
they do not (the mass each hinge carries alike on its two bodies), and predict a motion it
did not see. The fit is `bundledyn identify CONFIG.toml`'s, of the record given as files, as
a lab would give it (the nominal MJCF, the measurements, the torques, what to fit); the files
are shown to pose exactly the problem the Python call `identify.fit(Parameters(Scene(nominal)),
data, inputs=..., gauge=MeasuredInputs())` poses, so one fit serves both.
"""

import functools
import json
import warnings

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import bundledyn as bd
from bundledyn import identify, viz
from bundledyn._cli import main
from bundledyn._identify_file import run_file

mujoco = pytest.importorskip("mujoco")
# Fits against mujoco.sysid's model and the command: slow; test_identify_rigid.py is the
# everyday identification check.
# One worker for the file in `.ci/run`'s slow part (`--dist loadgroup`): its tests share fits.
pytestmark = [
    pytest.mark.usefixtures("optimized_compilation"),
    pytest.mark.slow,
    pytest.mark.xdist_group("identify_mujoco"),
]

# The chain with motors at its hinges (bundledyn ignores them: the torques are inputs).
CHAIN = (bd.models / "floating_chain.xml").read_text()
# What importing the chain warns of: its motors are not bundledyn's (they are the inputs).
MOTORS = "ignored from the MuJoCo model: 2 actuator"
RATE, T1, NOISE = 100, 4.0, 0.01


def _torque(t, seed):
    rng = np.random.default_rng(seed)
    amplitude, frequency, phase = rng.uniform(0.5, 1.0, (3, 2, 3))
    return np.stack(
        [
            np.sum(
                0.4 * amplitude[i] * np.sin((1 + 3 * frequency[i]) * t[..., None] + 6.3 * phase[i]),
                -1,
            )
            for i in range(2)
        ],
        axis=-1,
    )


def _mujoco_record(seed, t1):
    """MuJoCo's motion from a random moving state under its motors: `(model, ts, qpos, qvel)`."""
    model = mujoco.MjModel.from_xml_string(CHAIN)
    data = mujoco.MjData(model)
    scale = np.array([0.1, 0.1, 0.1, 0.5, 0.5, 0.5, 1.0, 1.0])
    data.qvel[:] = np.random.default_rng(seed).normal(size=model.nv) * scale
    every, n = int(round(1 / (RATE * model.opt.timestep))), int(t1 * RATE) + 1
    qpos, qvel = np.zeros((n, model.nq)), np.zeros((n, model.nv))
    for k in range(n):
        qpos[k], qvel[k] = data.qpos, data.qvel
        for _ in range(every if k < n - 1 else 0):
            data.ctrl[:] = _torque(np.array(data.time), seed)
            mujoco.mj_step(model, data)
    return model, np.arange(n) / RATE, qpos, qvel


def _spread(x):
    return float(np.sqrt(np.mean((x - x.mean(0)) ** 2)))


@functools.cache
def noisy_record():
    """The truth, MuJoCo's record with 1 % noise, and the known torques."""
    model, ts, qpos, qvel = _mujoco_record(0, T1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the motors are not bundledyn's: they are the inputs
        truth = bd.Multibody.from_mjcf(model)
    clean = identify.Measurements.from_mujoco(truth, ts, qpos, qvel, noise=identify.Noise())
    rng = np.random.default_rng(1)
    noise = identify.Noise(
        rotation=NOISE,
        position=NOISE * _spread(np.asarray(clean.pose[:, :3, 3])),
        q=NOISE * _spread(np.asarray(clean.q)),
        angular_velocity=NOISE * _spread(np.asarray(clean.xi[:, :3])),
        linear_velocity=NOISE * _spread(np.asarray(clean.xi[:, 3:])),
        qdot=NOISE * _spread(np.asarray(clean.qdot)),
    )
    n = len(ts)
    turn = bd.lie.so3_exp(noise.rotation * rng.normal(size=(n, 3)))
    pose = clean.pose.at[:, :3, :3].set(clean.pose[:, :3, :3] @ turn)
    twist = np.array([noise.angular_velocity] * 3 + [noise.linear_velocity] * 3)
    data = identify.Measurements(
        jnp.asarray(ts),
        pose=pose.at[:, :3, 3].add(noise.position * rng.normal(size=(n, 3))),
        q=clean.q + noise.q * rng.normal(size=clean.q.shape),
        xi=clean.xi + twist * rng.normal(size=clean.xi.shape),
        qdot=clean.qdot + noise.qdot * rng.normal(size=clean.qdot.shape),
        noise=noise,
    )
    input_times = np.arange(int((T1 + 0.2) * RATE) + 1) / RATE
    inputs = identify.Inputs(
        jnp.asarray(input_times), joint_forces=jnp.asarray(_torque(input_times, 0))
    )
    return truth, data, inputs


NOMINAL_FACTORS = (1.2, 0.8, 1.25)  # each body's pseudo-inertia at the start, over the truth's


def _nominal(truth):
    return truth.with_pseudo_inertias(
        truth.pseudo_inertias() * jnp.array(NOMINAL_FACTORS)[:, None, None]
    )


@pytest.fixture(scope="module")
def experiment(identified):
    """The truth, the noisy record, and the fit from a start 20-25 % off (the one fit of
    this module: the command's, from the files; `test_the_file_poses_the_problem_...`
    shows it is the library call's)."""
    truth, data, _ = noisy_record()
    return truth, data, identified[3]


HINGE_AXES = ((0.0, 0.3, 1.0), (0.2, 1.0, 0.0))  # the chain's MJCF's


def _hinge_regroupings(system, axes=HINGE_AXES):
    """δP of mass on each hinge's axis line, added to the child and taken from the parent
    (the hinges' `axes`: the chain's MJCF's by default)."""
    axes = [np.asarray(a, dtype=float) for a in axes]
    directions = []
    for child, axis, anchor in ((1, axes[0], np.zeros(3)), (2, axes[1], np.zeros(3))):
        u, w = np.append(anchor, 1.0), np.append(axis / np.linalg.norm(axis), 0.0)
        T = np.asarray(system.placement[child])
        for delta in (np.outer(u, u), np.outer(u, w) + np.outer(w, u), np.outer(w, w)):
            D = np.zeros((3, 4, 4))
            D[child], D[child - 1] = delta, -T @ delta @ T.T
            directions.append(D.reshape(-1))
    return np.stack(directions, axis=1)


def test_the_fit_reaches_the_noise_and_names_the_hinge_regroupings(experiment):
    _, _, result = experiment
    assert result.stats["converged"], result.report()
    assert 0.9 < result.identifiability.noise_scale < 1.1
    undetermined = result.identifiability.undetermined
    assert len(undetermined) == 6, undetermined
    for joint, bodies in (("arm", "arm and base"), ("hand", "hand and arm")):
        named = [
            u for u in undetermined if f"axis of the joint of {joint}, shared by {bodies}" in u
        ]
        assert len(named) == 3, undetermined


def test_what_the_data_determine_is_within_one_percent(experiment):
    """Each body's pseudo-inertia, up to the hinges' regroupings, within 1 % of its size."""
    truth, _, result = experiment
    P_true = truth.pseudo_inertias()
    relative = _beside_regroupings(result.scene.system.pseudo_inertias(), P_true, truth)
    assert np.all(relative < 0.01), relative
    start = _beside_regroupings(result.parameters.scene.system.pseudo_inertias(), P_true, truth)
    assert np.all(start > 0.05), start


def test_the_standard_errors_cover_the_truth(experiment):
    """The fit's error on the determined subspace against the reported covariance there: a
    χ² of about one per determined direction. The truth is first moved along the hinges'
    regroupings (linear in the pseudo-inertias) to the representative nearest the fit."""
    truth, _, result = experiment
    P_true = np.asarray(truth.pseudo_inertias())
    A = _hinge_regroupings(truth)
    shift = (
        A
        @ np.linalg.lstsq(
            A, (np.asarray(result.scene.system.pseudo_inertias()) - P_true).reshape(-1), rcond=None
        )[0]
    )
    equivalent = identify.log_cholesky_from_pseudo_inertia(P_true + shift.reshape(P_true.shape))
    scales = result.parameters.scales(result.theta)
    error = np.asarray(result.theta - equivalent.reshape(-1)) / scales
    covariance = result.identifiability.covariance / np.outer(scales, scales)
    w, V = np.linalg.eigh(covariance)
    determined = V[:, w > 1e-12 * w.max()]
    error = determined.T @ error
    chi2 = error @ np.diag(1.0 / w[w > 1e-12 * w.max()]) @ error
    assert result.parameters.size - determined.shape[1] == 6
    assert 0.2 < chi2 / determined.shape[1] < 3.0, (chi2, determined.shape[1])


def _standard_of(P):
    """Khalil's standard parameters of pseudo-inertias `(..., 4, 4)`, from their definition:
    per body XX, XY, XZ, YY, YZ, ZZ (inertia about the frame's origin, from the second
    moments Σ), MX, MY, MZ (first moments), M."""
    S = P[..., :3, :3]
    inertia = [S[..., 1, 1] + S[..., 2, 2], -S[..., 0, 1], -S[..., 0, 2],
               S[..., 0, 0] + S[..., 2, 2], -S[..., 1, 2], S[..., 0, 0] + S[..., 1, 1]]  # fmt: skip
    first = [P[..., 0, 3], P[..., 1, 3], P[..., 2, 3], P[..., 3, 3]]
    return np.stack(inertia + first, axis=-1).reshape(*np.shape(P)[:-3], -1)


def test_every_base_parameter_is_determined_and_its_interval_covers_the_truth(identified):
    """The report's base parameters: 30 - 6 = 24 combinations of the standard parameters,
    none moved by the hinges' regroupings (built here from the geometry of the fitted
    model: the axes as MuJoCo's XML writer wrote them into the nominal file, 6 digits), each
    with a finite standard error. Against the truth's values, no error exceeds 3.5 of its
    standard errors, and in the base parameters' covariance the χ² per base parameter is
    0.3-2.5."""
    folder, _, _, result = identified
    truth = noisy_record()[0]
    base = result.identifiability.base_parameters
    assert len(base) == 24
    coefficients = np.stack([b.coefficients for b in base])
    axes = mujoco.MjModel.from_xml_path(str(folder / "nominal.xml")).jnt_axis[1:]
    regroupings = _hinge_regroupings(truth, axes).T.reshape(6, 3, 4, 4)
    moved = coefficients @ _standard_of(regroupings).T
    size = np.linalg.norm(coefficients, axis=1)[:, None] * np.linalg.norm(
        _standard_of(regroupings), axis=1
    )
    assert np.all(np.abs(moved) < 1e-9 * size), np.max(np.abs(moved) / size)
    values = np.array([b.value for b in base])
    stds = np.array([b.std for b in base])
    assert np.all(np.isfinite(stds) & (stds > 0))
    errors = values - coefficients @ _standard_of(np.asarray(truth.pseudo_inertias()))
    assert np.max(np.abs(errors / stds)) < 3.5, errors / stds
    jacobian = jax.jacfwd(lambda t: identify.standard_parameters(result.parameters, t))(
        result.theta
    )
    gradients = coefficients @ np.asarray(jacobian)
    covariance = gradients @ result.identifiability.covariance @ gradients.T
    chi2 = errors @ np.linalg.solve(covariance, errors)
    assert 0.3 < chi2 / len(base) < 2.5, chi2 / len(base)


def test_a_motion_it_did_not_see_is_predicted_within_the_noise(experiment):
    """A new initial state and new torques: for 2 s the fitted model follows MuJoCo's
    motion at the noise level (RMS errors measured 0.08-1.25 σ per channel; bound 1.5 σ)."""
    truth, data, result = experiment
    model, ts, qpos, qvel = _mujoco_record(7, 2.0)
    states = jax.vmap(lambda p, v: bd.state_from_mujoco(truth, p, v))(qpos, qvel)
    input_times = np.arange(int(2.2 * RATE) + 1) / RATE
    torque = jnp.asarray(_torque(input_times, 7))
    inputs = identify.Inputs(jnp.asarray(input_times), joint_forces=torque)
    start = jax.tree.map(lambda x: x[0], states)
    scene = bd.Scene(result.scene.system, inputs.effects())

    traj = bd.simulate(
        scene, start, 2.0, saveat=diffrax.SaveAt(ts=jnp.asarray(ts)), rtol=1e-10, atol=1e-10
    )
    noise = data.noise
    for predicted, true, sigma in (
        (traj.q, states.q, noise.q),
        (traj.g[:, :3, 3], states.g[:, :3, 3], noise.position),
        (traj.xi[:, :3], states.xi[:, :3], noise.angular_velocity),
        (traj.qdot, states.qdot, noise.qdot),
    ):
        error = np.sqrt(np.mean((np.asarray(predicted) - np.asarray(true)) ** 2)) / sigma
        assert error < 1.5, error


# ------------------------------------------------- the same fit from the command line

CONFIG = """
[model]
path = "nominal.xml"

[data]
path = "record.npz"

[inputs]
path = "torques.npz"

[fit]
gauge = "measured_inputs"

[truth]
path = "truth.xml"

[output]
name = "chain"
"""


def _nominal_mjcf():
    """The chain's MJCF with each body's mass and inertia scaled as the fit's start."""
    spec = mujoco.MjSpec.from_string(CHAIN)
    for name, factor in zip(("base", "arm", "hand"), NOMINAL_FACTORS, strict=True):
        body = spec.body(name)
        body.mass = body.mass * factor
        body.fullinertia = np.asarray(body.fullinertia) * factor
    return spec.to_xml()


@pytest.fixture(scope="module")
def identified(tmp_path_factory, optimized_compilation):
    """The files a lab would give, and what `bundledyn identify` does with them (`run_file`,
    the command without its argument parsing): the folder, the outputs' folder, the loaded
    file and the fit."""
    folder = tmp_path_factory.mktemp("identify")
    _, data, inputs = noisy_record()
    (folder / "truth.xml").write_text(CHAIN)
    (folder / "nominal.xml").write_text(_nominal_mjcf())
    data.save(folder / "record.npz")
    np.savez(folder / "torques.npz", ts=inputs.ts, joint_forces=inputs.joint_forces)
    (folder / "identify.toml").write_text(CONFIG)
    out = folder / "out"
    out.mkdir()
    with pytest.warns(UserWarning, match=MOTORS):
        file = bd.IdentificationFile.load(folder / "identify.toml")
    return folder, out, file, run_file(file, out, progress=False, plots=True)


def test_the_command_fits_and_writes_estimates_report_model_and_pictures(identified):
    folder, out, _, result = identified
    assert result.stats["converged"]  # the command's exit status 0
    names = sorted(p.name for p in out.iterdir())
    assert names == [
        "chain_estimates.json", "chain_fitted.xml", "chain_identification.png", "chain_report.txt",
    ]  # fmt: skip
    png = (out / "chain_identification.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000
    report = (out / "chain_report.txt").read_text()
    assert "gauge: measured inputs (the work of the known forces) fix the mass scale" in report
    assert "The data do not determine:" in report and "not converged" not in report
    # The base parameters, each with its error against the file's [truth].
    assert "What the data determine: 24 base parameters" in report
    rows = [line.split() for line in report.splitlines() if "base.M + 1 arm.M + 1 hand.M" in line]
    assert len(rows) == 1 and abs(float(rows[0][3])) < 3.5  # the total mass's error / σ


def test_the_information_plot_spans_the_determined_values_and_the_noise_line(identified):
    """Its axis runs from a decade below the smallest determined singular value (or the
    noise line) to above the largest, not down to the rounding-level ones."""
    result = identified[3]
    ident = result.identifiability
    values = np.asarray(ident.singular_values)
    shown = np.append(values[values > ident.noise_scale], ident.noise_scale)
    low, high = viz.plot_identification(result).axes[1].get_ylim()
    assert shown.min() / 100 < low < shown.min() and shown.max() < high < 10 * shown.max()


def _beside_regroupings(P, P_reference, system):
    """Each body's part of P - P_reference outside the hinges' regroupings, relative to
    P_reference's size."""
    A = _hinge_regroupings(system)
    difference = (np.asarray(P) - np.asarray(P_reference)).reshape(-1)
    left = difference - A @ np.linalg.lstsq(A, difference, rcond=None)[0]
    left = left.reshape(np.shape(P_reference))
    return np.linalg.norm(left, axis=(1, 2)) / np.linalg.norm(P_reference, axis=(1, 2))


def test_the_file_poses_the_problem_the_library_call_poses(identified):
    """The files give what the library call is given: the nominal bodies to the 6
    significant digits MuJoCo's XML writer keeps (within 1e-6 of each body's size), the
    record and the torques exactly, the gauge, and `fit`'s default windows and options.
    So the command's fit is the library call's from a start 1e-6 away (the two fits, when
    both were run, agreed to 2e-6 of each body's size beside the regroupings)."""
    _, _, file, _ = identified
    truth, data, inputs = noisy_record()
    library = identify.Parameters(bd.Scene(_nominal(truth)))
    P_file = np.asarray(file.parameters.scene.system.pseudo_inertias())
    P_library = np.asarray(library.scene.system.pseudo_inertias())
    size = np.linalg.norm(P_library, axis=(1, 2))
    assert np.all(np.linalg.norm(P_file - P_library, axis=(1, 2)) < 1e-6 * size)
    assert file.parameters.labels() == library.labels()
    for name in ("ts", "pose", "q", "xi", "qdot"):
        np.testing.assert_array_equal(getattr(file.measurements, name), getattr(data, name))
    assert file.measurements.noise == data.noise
    assert file.inputs is not None
    np.testing.assert_array_equal(file.inputs.ts, inputs.ts)
    np.testing.assert_array_equal(file.inputs.joint_forces, inputs.joint_forces)
    assert isinstance(file.gauge, identify.MeasuredInputs)
    assert file.windows == identify.Windows(count=(len(data.ts) - 1) // 20)
    assert file.options == {"warm_start": True, "max_steps": 50}


def test_the_written_estimates_are_the_fits(identified):
    """The JSON holds the fit's bodies, noise scale and blind directions; each estimate
    beside the truth, and no standard error for an undetermined one (each body's mass,
    centre and inertia moves along a hinge's regrouping, so none is determined alone)."""
    _, out, _, result = identified
    truth = noisy_record()[0]
    written = json.loads((out / "chain_estimates.json").read_text())
    np.testing.assert_allclose(
        written["pseudo_inertias"], result.scene.system.pseudo_inertias(), rtol=1e-12, atol=1e-15
    )
    assert written["undetermined"] == list(result.identifiability.undetermined)
    assert written["noise_scale"] == pytest.approx(result.identifiability.noise_scale, rel=1e-12)
    values = result.values_of(bd.Scene(truth))
    for e in written["estimates"]:
        assert e["truth"] == pytest.approx(values[e["name"]], rel=1e-12, abs=1e-15)
        assert (e["std"] is None) == (not e["determined"])
    base = result.identifiability.base_parameters
    assert [b["name"] for b in written["base_parameters"]] == [b.name for b in base]
    true_base = result.base_values_of(bd.Scene(truth))
    for b, fitted, true in zip(written["base_parameters"], base, true_base, strict=True):
        assert (b["value"], b["std"], b["truth"]) == (fitted.value, fitted.std, true)


def test_the_fitted_mjcf_holds_the_fitted_bodies(identified):
    """MuJoCo reads the fitted model back, and its bodies are the fit's pseudo-inertias
    (to the 6 significant digits MuJoCo's XML writer keeps)."""
    _, out, _, _ = identified
    with pytest.warns(UserWarning, match=MOTORS):
        fitted = bd.Multibody.from_mjcf(out / "chain_fitted.xml")
    P = np.asarray(json.loads((out / "chain_estimates.json").read_text())["pseudo_inertias"])
    np.testing.assert_allclose(fitted.pseudo_inertias(), P, rtol=0, atol=2e-6 * np.abs(P).max())


def test_a_file_without_a_gauge_is_refused_with_the_fix(tmp_path, capsys):
    (tmp_path / "model.xml").write_text(CHAIN)
    identify.Measurements(jnp.linspace(0.0, 1.0, 3), q=jnp.zeros((3, 2))).save(tmp_path / "d.npz")
    (tmp_path / "bad.toml").write_text(
        '[model]\npath = "model.xml"\n[data]\npath = "d.npz"\n[fit]\nbodies = ["arm"]\n'
    )
    with pytest.warns(UserWarning, match=MOTORS):
        assert main(["identify", str(tmp_path / "bad.toml"), "--out", str(tmp_path)]) == 2
    message = capsys.readouterr().err
    assert "`fit.gauge`" in message and "known_mass" in message
