r"""Identification files: a whole identification (model, data, inputs, gauge, fit) in TOML.

`bundledyn identify CONFIG.toml` reads one, fits, and writes the fitted model, the
estimates with their intervals, the report and its pictures. Every table and key is
described in `IdentificationFile`'s docstring; mistakes are reported with the file, the
field and the value, as in scene files.
"""

import dataclasses
import json
import pathlib
import tomllib
from typing import cast

import equinox as eqx
import numpy as np

from ._identify._data import Inputs, Measurements, Noise
from ._identify._fit import FitResult, fit
from ._identify._gauge import AbstractGauge, KnownBodies, KnownMass, MeasuredInputs
from ._identify._parameters import Parameters
from ._identify._shooting import Windows
from ._modes import PrescribedBase
from ._scene import Scene
from ._scene_file import SceneFile, SceneFileError, _Table, load_system
from ._systems._base import AbstractInertialSystem
from ._systems._multibody import AbstractMultibody
from ._systems._pseudo_inertia import inertial_from_pseudo_inertia

_NOISE_FIELDS = tuple(f.name for f in dataclasses.fields(Noise))


def _scene(t: _Table, folder: pathlib.Path) -> tuple[Scene, pathlib.Path]:
    """The nominal scene of `[model]` (or `[truth]`) and the model file it came from."""
    path = folder / t.string("path")
    base = t.string("base", "floating", {"floating", "fixed"})
    t.done()
    try:
        if path.suffix.lower() == ".toml":
            scene = SceneFile.load(path).scene
        else:
            scene = Scene(load_system(path))
    except SceneFileError:
        raise
    except ValueError as error:
        raise t.fail("path", str(error)) from None
    if base == "fixed":
        scene = eqx.tree_at(lambda s: s.base, scene, PrescribedBase.fixed())
    return scene, path


def _measurements(t: _Table, folder: pathlib.Path, system) -> Measurements:
    path = folder / t.string("path")
    noise_table = t.table("noise", {})
    noise = Noise(**{k: noise_table.number(k) for k in _NOISE_FIELDS if noise_table.has(k)})
    noise_table.done()
    t.done()
    if not path.is_file():
        raise t.fail("path", "no such file.")
    if path.suffix.lower() == ".npz":
        return Measurements.load(path)
    if path.suffix.lower() == ".csv":
        with t.building("data"):
            return Measurements.from_csv(path, system, noise=noise)
    raise t.fail("path", "must be an .npz file (`Measurements.save`) or a MuJoCo-layout .csv.")


def _inputs(t: _Table, folder: pathlib.Path) -> Inputs | None:
    if not t.has("path"):
        t.done()
        return None
    path = folder / t.string("path")
    interpolation = t.string("interpolation", "cubic", {"cubic", "linear"})
    t.done()
    if not path.is_file():
        raise t.fail("path", "no such file.")
    with np.load(path) as archive:
        arrays = {key: archive[key] for key in archive.files}
    if "ts" not in arrays:
        raise t.fail("path", "the file needs `ts` and `joint_forces` and/or `wrenches`.")
    bodies = tuple(None if b < 0 else int(b) for b in arrays.get("wrench_bodies", ()))
    with t.building("inputs"):
        return Inputs(
            arrays["ts"], joint_forces=arrays.get("joint_forces"),
            wrenches=arrays.get("wrenches"), wrench_bodies=bodies, interpolation=interpolation,
        )  # fmt: skip


def _gauge(t: _Table) -> AbstractGauge:
    kind = t.string("gauge", None, {"measured_inputs", "known_mass", "known_bodies"})
    if kind is None:
        raise t.fail(
            "gauge",
            "required: free motion does not fix the mass scale. Use 'measured_inputs' (known "
            "torques or wrenches), 'known_mass' (with `mass`, and `mass_of` a body) or "
            "'known_bodies' (bodies left out of `bodies`).",
        )
    if kind == "known_mass":
        return KnownMass(t.number("mass"), t.string("mass_of", None))
    return MeasuredInputs() if kind == "measured_inputs" else KnownBodies()


@dataclasses.dataclass(frozen=True)
class IdentificationFile:
    r"""An identification read from a TOML file: everything `identify.fit` needs, and where
    the results go.

    Tables and fields (paths are relative to the file):

    - `[model]` `path`: the nominal model, MJCF (`.xml`), URDF (`.urdf`) or a scene file
      (`.toml`, whose effects are kept); `base` = `"floating"` (default) or `"fixed"`
      (a base held still: the arm's shape equation alone).
    - `[data]` `path`: the measurements, an `.npz` written by `Measurements.save`, or a
      `.csv` of MuJoCo-layout rows (`t`, `qpos`, `qvel`) with their noise levels in
      `[data.noise]` (`rotation`, `position`, `q`, `angular_velocity`,
      `linear_velocity`, `qdot`; as recorded, the linear velocity MuJoCo's world-frame
      one: `Measurements.from_mujoco`).
    - `[inputs]` (optional) `path`: an `.npz` with `ts` and `joint_forces` `(m, d)` and/or
      `wrenches` `(m, k, 6)` with `wrench_bodies` (`-1` for the section frame);
      `interpolation` (`"cubic"`).
    - `[fit]` `gauge` (required): `"measured_inputs"`, `"known_mass"` (`mass`, and
      `mass_of` a body name for one body's mass) or `"known_bodies"`; `bodies` (names
      of the free bodies, default all), `joint_constants` (`["damping"]`,
      `["stiffness"]`), `window_samples` (20), `warm_start` (true), `max_steps` (50).
    - `[truth]` (optional) `path`, `base`: the true model, when the data are synthetic;
      the report and pictures then show each estimate's error.
    - `[output]` `name` (default the file's stem), `plots` (true).

    **Fields:** `path`, `parameters`, `measurements`, `inputs`, `gauge`, `windows`,
    `options` (the rest of `fit`'s keyword arguments), `model_path`, `truth` (a `Scene`
    or `None`), `output`.
    """

    path: pathlib.Path
    parameters: Parameters
    measurements: Measurements
    inputs: Inputs | None
    gauge: AbstractGauge
    windows: Windows
    options: dict
    model_path: pathlib.Path
    truth: Scene | None
    output: dict

    @classmethod
    def load(cls, path) -> "IdentificationFile":
        """Read and check an identification file; raise `SceneFileError` naming the field."""
        path = pathlib.Path(path)
        try:
            data = tomllib.loads(path.read_text())
        except OSError as error:
            raise SceneFileError(f"{path}: cannot read the file ({error.strerror}).") from None
        except tomllib.TOMLDecodeError as error:
            raise SceneFileError(f"{path}: not valid TOML: {error}.") from None
        root, folder = _Table(path, "", data), path.parent
        scene, model_path = _scene(root.table("model"), folder)
        measurements = _measurements(root.table("data"), folder, scene.system)
        inputs = _inputs(root.table("inputs", {}), folder)
        t = root.table("fit")
        gauge = _gauge(t)
        with t.building("fit"):
            parameters = Parameters(
                scene,
                bodies=t.raw("bodies", None),
                joint_constants=tuple(t.raw("joint_constants", [])),
            )
        samples = int(t.number("window_samples", 20))
        n = int(np.shape(measurements.ts)[0])
        windows = Windows(count=max(1, (n - 1) // max(samples, 1)))
        options = {
            "warm_start": t.boolean("warm_start", True),
            "max_steps": int(t.number("max_steps", 50)),
        }
        t.done()
        truth = _scene(root.table("truth"), folder)[0] if root.has("truth") else None
        out = root.table("output", {})
        output = {"name": out.string("name", path.stem), "plots": out.boolean("plots", True)}
        out.done()
        root.done()
        return cls(
            path, parameters, measurements, inputs, gauge, windows, options, model_path,
            truth, output,
        )  # fmt: skip

    def fit(self, *, progress: bool | None = None) -> FitResult:
        """Run the identification (`bundledyn.identify.fit` with the file's settings;
        `progress` as there)."""
        return fit(
            self.parameters, self.measurements, gauge=self.gauge, inputs=self.inputs,
            windows=self.windows, progress=progress, **self.options,
        )  # fmt: skip


def estimates_json(result: FitResult, truth: Scene | None = None) -> dict:
    """The fit's outcome as JSON-ready data: the base parameters and each body's estimates
    with standard errors (and the truth's values), what is undetermined, the gauge, the
    convergence."""
    ident = result.identifiability
    true_values = None if truth is None else result.values_of(truth)
    true_base = None if truth is None else result.base_values_of(truth)
    estimates = [
        {"name": e.name, "value": e.value, "std": e.std if e.determined else None,
         "determined": e.determined, **({"truth": true_values[e.name]} if true_values else {})}
        for e in ident.estimates
    ]  # fmt: skip
    base = [
        {"name": b.name, "value": b.value, "std": b.std,
         **({"truth": true_base[k]} if true_base is not None else {})}
        for k, b in enumerate(ident.base_parameters)
    ]  # fmt: skip
    return {
        "gauge": result.gauge,
        "base_parameters": base,
        "estimates": estimates,
        "undetermined": list(ident.undetermined),
        "noise_scale": ident.noise_scale,
        "condition_number": ident.condition_number,
        "singular_values": np.asarray(ident.singular_values).tolist(),
        "costs": [float(c) for c in result.costs],
        "stats": {
            k: (v if isinstance(v, bool | int | float) else str(v)) for k, v in result.stats.items()
        },  # fmt: skip
        "pseudo_inertias": np.asarray(
            cast(AbstractInertialSystem, result.scene.system).pseudo_inertias()
        ).tolist(),
    }


def write_mjcf(result: FitResult, model_path: pathlib.Path, path: pathlib.Path) -> pathlib.Path:
    """The MJCF model at `model_path` with the fitted bodies' inertials (mass, centre of mass,
    principal moments and axes), written to `path` by MuJoCo (6 significant digits)."""
    import mujoco

    # MuJoCo's compiled bindings carry no type information: pyright cannot see them.
    spec = mujoco.MjSpec.from_file(str(model_path))  # pyright: ignore[reportAttributeAccessIssue]
    system = cast(AbstractMultibody, result.scene.system)  # an MJCF model is a tree
    masses, centres, inertias = (
        np.asarray(x) for x in inertial_from_pseudo_inertia(system.pseudo_inertias())
    )
    for b in result.parameters.bodies:
        moments, axes = np.linalg.eigh(inertias[b])
        axes[:, 2] *= np.sign(np.linalg.det(axes))
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, axes.reshape(-1))  # pyright: ignore[reportAttributeAccessIssue]
        body = spec.body(system.names[b])
        body.explicitinertial = True
        body.mass, body.ipos, body.iquat, body.inertia = masses[b], centres[b], quat, moments
        body.fullinertia = [np.nan, 0, 0, 0, 0, 0]
    path.write_text(spec.to_xml())
    return path


def write_outputs(
    file: IdentificationFile, result: FitResult, out: pathlib.Path, *, plots: bool
) -> list[pathlib.Path]:
    """Write the fit's estimates (JSON), report (text), fitted model (MJCF, when the model
    is MJCF) and pictures (PNG) into `out`; return the paths."""
    name = file.output["name"]
    written = [out / f"{name}_estimates.json", out / f"{name}_report.txt"]
    written[0].write_text(json.dumps(estimates_json(result, file.truth), indent=1))
    written[1].write_text(result.report(file.truth) + "\n")
    if file.model_path.suffix.lower() == ".xml":
        written.append(write_mjcf(result, file.model_path, out / f"{name}_fitted.xml"))
    if plots and file.output["plots"]:
        from ._viz._identification import plot_identification

        written.append(out / f"{name}_identification.png")
        plot_identification(result, truth=file.truth, path=written[-1])
    return written


def run_file(file: IdentificationFile, out: pathlib.Path, *, progress: bool | None, plots: bool):
    """What `bundledyn identify` does with a loaded file: print what is fitted, fit, print
    the report, write the outputs into the existing folder `out`; the `FitResult`."""
    if not out.is_dir():
        raise SceneFileError(f"{out}: the output folder does not exist.")
    print(f"bundledyn identify {file.path}")
    print(
        f"  {len(file.parameters.bodies)} free bodies, {file.parameters.size} parameters, "
        f"{int(np.shape(file.measurements.ts)[0])} samples, {file.windows.count} windows"
    )
    result = file.fit(progress=progress)
    print(result.report(file.truth))
    for path in write_outputs(file, result, out, plots=plots):
        print(f"  wrote {path}")
    return result


def identify_command(config, out: pathlib.Path, *, progress: bool | None, plots: bool) -> int:
    """`bundledyn identify CONFIG.toml`: `run_file`; exit status 1 if the fit did not converge."""
    result = run_file(IdentificationFile.load(config), out, progress=progress, plots=plots)
    return 0 if result.stats["converged"] else 1
