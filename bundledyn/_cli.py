"""The `bundledyn` command line: `demo`, `run SCENE.toml` and `check MODEL`."""

import argparse
import contextlib
import datetime
import json
import pathlib
import signal
import sys
import threading
import time
from typing import Any


def _pictures_available() -> bool:
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        print("  (no pictures: matplotlib is not installed; pip install 'bundledyn[viz]')")
        return False
    return True


def _solve(scene_file, *, progress=False):
    """Simulate a scene file: `(trajectory, seconds)`; `_Failure` if the solver stopped early."""
    import diffrax

    from ._stiffness import out_of_steps_advice

    start = time.perf_counter()
    traj = scene_file.simulate(progress=progress, throw=False)
    elapsed = time.perf_counter() - start
    if not bool(traj.result == diffrax.RESULTS.successful):
        message = diffrax.RESULTS[traj.result]
        if bool(traj.result == diffrax.RESULTS.max_steps_reached):
            advice = out_of_steps_advice(
                scene_file.scene,
                scene_file.state,
                scene_file.t0,
                scene_file.t1,
                scene_file.options["max_steps"],
            )
            message = f"{message} {advice}".rstrip()
        raise _Failure(f"{scene_file.path}: the solver stopped early: {message}")
    return traj, elapsed


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def _positive(kind):
    """An argparse type: `kind` (int or float) parsed and required to be positive."""

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        if not value > 0:
            raise argparse.ArgumentTypeError(f"must be positive, got {text}")
        return value

    parse.__name__ = f"positive {kind.__name__}"
    return parse


@contextlib.contextmanager
def _terminated_as_exit():
    """SIGTERM raises `SystemExit(143)` while a command runs, so a file being written is
    removed (`atomic_path`) rather than left half-written, as the default handler would."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def terminate(signum, frame):
        raise SystemExit(128 + signum)

    previous = signal.signal(signal.SIGTERM, terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


class _Failure(Exception):
    """A run that went wrong in a way the user can fix; reported in one line, exit code 1."""


def _summary(scene_file, traj, diagnostics, elapsed):
    """Print what was simulated and its diagnostics, each quantity with the frame it is in:
    poses in the scene's frame, energy and spatial momentum in the Galilean frame."""
    import numpy as np

    from ._viz._frame_names import GALILEAN, frame_name

    energy = np.asarray(diagnostics.energy)
    momentum = np.asarray(diagnostics.spatial_momentum)
    scene = scene_file.scene
    print(
        f"  system: {type(scene.system).__name__}, {scene.system.shape_dim} shape coordinates; "
        f"{_count(len(scene.effects), 'effect')}; mode {type(scene.mode).__name__}; "
        f"seen from {frame_name(scene)}"
    )
    print(
        f"  simulated {scene_file.t0:g}..{scene_file.t1:g} s with {type(scene_file.solver).__name__}"
        f": {int(traj.stats['num_steps'])} steps, {elapsed:.1f} s including compilation"
    )
    print(
        f"  energy in {GALILEAN}: E(t1) - E(t0) = {energy[-1] - energy[0]:.2e} "
        f"(E(t0) = {energy[0]:.6g} J)"
    )
    print(
        f"  spatial momentum in {GALILEAN} (about its origin): largest change "
        f"{np.abs(momentum - momentum[0]).max():.2e}"
    )
    print(
        f"  poses in {frame_name(scene)}: rotations orthogonal to "
        f"{float(diagnostics.orthogonality_error.max()):.1e}"
    )
    residual = np.asarray(diagnostics.constraint_residual)
    if residual.shape[-1]:
        print(
            f"  constraints kept ({type(scene.mode).__name__}, {type(scene.system).__name__}): "
            f"largest residual {np.abs(residual).max():.1e}"
        )


def _write_pictures(scene_file, traj, diagnostics, out, stem):
    from . import viz

    written = [out / f"{stem}_motion.png", out / f"{stem}_drift.png"]
    viz.plot_motion(traj, path=written[0])
    viz.plot_drift(traj, path=written[1], diagnostics=diagnostics)
    if scene_file.output["animation"]:
        written.append(
            viz.animate(
                traj,
                out / f"{stem}.gif",
                solids=scene_file.solids,
                frames=scene_file.output["frames"],
            )
        )
    return written


def _write_trajectory(scene_file, traj, diagnostics, path, elapsed):
    import jax
    import numpy as np

    from . import __version__
    from ._files import atomic_path

    metadata = {
        "bundledyn": __version__,
        "jax": jax.__version__,
        "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "scene_file": str(scene_file.path),
        "solver": type(scene_file.solver).__name__,
        "options": scene_file.options,
        "stats": {k: np.asarray(v).tolist() for k, v in traj.stats.items()},
        "seconds": elapsed,
    }
    with atomic_path(path) as tmp:
        np.savez(
            tmp,
            ts=traj.ts,
            g=traj.g,
            q=traj.q,
            xi=traj.xi,
            qdot=traj.qdot,
            U=traj.U,
            energy=diagnostics.energy,
            spatial_momentum=diagnostics.spatial_momentum,
            constraint_residual=diagnostics.constraint_residual,
            scene=np.array(scene_file.text),
            metadata=np.array(json.dumps(metadata)),
        )
    return path


def run(args) -> int:
    """Simulate a scene file and write its trajectory and pictures."""
    import bundledyn as bd

    out = pathlib.Path(args.out)
    if not out.is_dir():
        raise _Failure(f"{out}: the output folder does not exist.")
    if pathlib.Path(args.scene).suffix.lower() in (".xml", ".urdf"):
        raise bd.SceneFileError(
            f"{args.scene}: `bundledyn run` takes a scene file (.toml) that names the model, "
            f'e.g. [system] type = "mjcf", path = "{pathlib.Path(args.scene).name}", and '
            "[time] t1 = 1.0 (docs/how-to/scene-files.md); `bundledyn check` and "
            "`bundledyn stress` take a model file as it is."
        )
    if args.chunk_size is not None and args.batch is None:
        raise _Failure("--chunk-size divides a batch: give the batch's file with --batch.")
    if bd.is_gyroscope_file(args.scene):
        if args.batch is not None:
            raise _Failure(
                f"{args.scene}: --batch takes initial states (g, q, xi, qdot) of a scene "
                "file; a gyroscope chain's file states its own."
            )
        return _run_gyroscopes(bd.GyroscopeChainFile.load(args.scene), out, args)
    scene_file = bd.SceneFile.load(args.scene)
    if args.batch is not None:
        return _run_batch(scene_file, args, out)
    print(f"bundledyn run {scene_file.path}")
    traj, elapsed = _solve(scene_file, progress=args.progress)
    diagnostics = traj.diagnostics()
    _summary(scene_file, traj, diagnostics, elapsed)
    path = out / scene_file.output["trajectory"]
    written = [_write_trajectory(scene_file, traj, diagnostics, path, elapsed)]
    if scene_file.output["plots"] and not args.no_pictures and _pictures_available():
        written += _write_pictures(scene_file, traj, diagnostics, out, path.stem)
    for p in written:
        print(f"  wrote {p}")
    return 0


_STATE_FIELDS = ("g", "q", "xi", "qdot")


def _batch_fields(scene_file, path):
    """A batch's initial states as `(g, q, xi, qdot)`, one member per row: the arrays an
    `.npz` file holds under those names, the scene file's `[initial]` for those it lacks."""
    import jax.numpy as jnp
    import numpy as np

    try:
        with np.load(path) as data:
            given = {name: np.asarray(data[name]) for name in data.files}
    except (OSError, ValueError) as error:
        raise _Failure(f"{path}: cannot read the batch of initial states ({error}).") from None
    unknown = sorted(set(given) - set(_STATE_FIELDS))
    if unknown or not given:
        raise _Failure(
            f"{path}: a batch of initial states holds arrays named {', '.join(_STATE_FIELDS)} "
            f"(one member per row; the others from the scene file's [initial]), got "
            f"{sorted(given) or 'none'}."
        )
    size = next(iter(given.values())).shape[:1]
    fields = []
    for name in _STATE_FIELDS:
        one = getattr(scene_file.state, name)
        x = jnp.asarray(given[name], one.dtype) if name in given else None
        expected = (*size, *one.shape)
        if x is not None and x.shape != expected:
            raise _Failure(
                f"{path}: `{name}` has shape {x.shape}; one member's is {one.shape} in this "
                f"scene, so {size[0] if size else 'N'} members need {expected}."
            )
        fields.append(jnp.broadcast_to(one, expected) if x is None else x)
    return tuple(fields)


def _run_batch(scene_file, args, out) -> int:
    """Simulate a scene file from every initial state of a batch, spread over the devices
    (`vmap_over_devices`); print what lockstep cost and the energy's drift, write the
    members' trajectories."""
    import diffrax
    import jax
    import numpy as np

    import bundledyn as bd

    fields = _batch_fields(scene_file, args.batch)
    size = fields[0].shape[0]
    print(f"bundledyn run {scene_file.path} --batch {args.batch}")

    def member(g, q, xi, qdot):
        traj = scene_file.simulate(state=bd.State(g, q, xi, qdot), throw=False)
        diagnostics = traj.diagnostics()
        ok = traj.result == diffrax.RESULTS.successful
        return (traj.ts, traj.g, traj.q, traj.xi, traj.qdot, diagnostics.energy,
                diagnostics.spatial_momentum, traj.stats["num_steps"], ok)  # fmt: skip

    batch = bd.vmap_over_devices(
        member, chunk_size=args.chunk_size, progress=args.chunk_size is not None
    )
    start = time.perf_counter()
    ts, g, q, xi, qdot, energy, momentum, steps, ok = jax.block_until_ready(batch(*fields))
    elapsed = time.perf_counter() - start
    failed = np.flatnonzero(~np.asarray(ok))
    if failed.size:
        raise _Failure(
            f"{scene_file.path}: the solver stopped early for {_count(failed.size, 'member')} "
            f"of the batch (rows {failed[:10].tolist()}); run one alone for the reason."
        )
    steps, energy = np.asarray(steps), np.asarray(energy)
    lockstep = batch.lockstep(steps)
    print(
        f"  {_count(size, 'member')} on {_count(batch.mesh.devices.size, 'device')}"
        + (f", {args.chunk_size} at a time" if args.chunk_size else "")
        + f": {steps.min()}-{steps.max()} steps (median {np.median(steps):g}) of "
        f"{type(scene_file.solver).__name__}, {elapsed:.1f} s including compilation; "
        f"lockstep ran {lockstep.overhead:.2f}x the steps the members needed"
    )
    drift = np.abs(energy[:, -1] - energy[:, 0])
    print(
        f"  energy: largest E(t1) - E(t0) over the members {drift.max():.2e} (row {drift.argmax()})"
    )
    path = out / f"{pathlib.Path(scene_file.output['trajectory']).stem}_batch.npz"
    _write_batch(path, scene_file, elapsed, lockstep.overhead,
                 ts=ts[0], g=g, q=q, xi=xi, qdot=qdot, energy=energy,
                 spatial_momentum=momentum, num_steps=steps)  # fmt: skip
    print(f"  wrote {path}")
    return 0


def _write_batch(path, scene_file, elapsed, overhead, **arrays):
    import numpy as np

    from . import __version__
    from ._files import atomic_path

    metadata = {
        "bundledyn": __version__,
        "scene_file": str(scene_file.path),
        "solver": type(scene_file.solver).__name__,
        "options": scene_file.options,
        "seconds": elapsed,
        "lockstep_overhead": overhead,
    }
    saved: dict[str, Any] = {k: np.asarray(v) for k, v in arrays.items()}
    saved |= {"scene": np.array(scene_file.text), "metadata": np.array(json.dumps(metadata))}
    with atomic_path(path) as tmp:
        np.savez(tmp, **saved)


def _run_gyroscopes(chain_file, out, args) -> int:
    """Integrate a gyroscope chain's file, print its first integrals, write them and a plot."""
    import diffrax
    import jax
    import numpy as np

    from . import __version__
    from ._files import atomic_path

    print(f"bundledyn run {chain_file.path}")
    start = time.perf_counter()
    solution = chain_file.solve(throw=False)
    jax.block_until_ready(solution.ys)
    elapsed = time.perf_counter() - start
    if not bool(solution.result == diffrax.RESULTS.successful):
        raise _Failure(
            f"{chain_file.path}: the solver stopped early: {diffrax.RESULTS[solution.result]}"
        )
    found = {k: np.asarray(v) for k, v in chain_file.first_integrals(solution).items()}
    energy, vertical = found["energy"], found["vertical_momentum"]
    print(
        f"  {chain_file.chain.size} Lagrange gyroscopes in {chain_file.formulation}, "
        f"{chain_file.t0:g} → {chain_file.t1:g} s: {int(solution.stats['num_steps'])} steps "
        f"of {type(chain_file.solver).__name__} in {elapsed:.1f} s (compiling included)"
    )
    print(f"  energy {energy[0]:.6g} J, largest drift {np.abs(energy - energy[0]).max():.1e}")
    print(
        f"  vertical angular momentum about the pivot {vertical[0]:.6g}, largest drift "
        f"{np.abs(vertical - vertical[0]).max():.1e}"
    )
    print(f"  rotations orthogonal to {found['orthogonality'].max():.1e}")
    path = out / chain_file.output["trajectory"]
    metadata = {
        "bundledyn": __version__,
        "seconds": elapsed,
        "solver": type(chain_file.solver).__name__,
    }
    with atomic_path(path) as tmp:
        np.savez(
            tmp,
            ts=np.asarray(solution.ts),
            rotations=found["rotations"],
            angular_velocities=found["angular_velocities"],
            energy=energy,
            vertical_momentum=vertical,
            scene=np.array(chain_file.text),
            metadata=np.array(json.dumps(metadata)),
        )
    written = [path]
    if chain_file.output["plots"] and not args.no_pictures and _pictures_available():
        written.append(
            _plot_first_integrals(
                np.asarray(solution.ts), energy, vertical, out / f"{path.stem}_drift.png"
            )
        )
    for p in written:
        print(f"  wrote {p}")
    return 0


def _plot_first_integrals(ts, energy, vertical, path):
    """The drifts of the energy and of the vertical angular momentum against time."""
    import numpy as np

    from . import viz

    fig = viz.new_figure(6.0, 3.0)
    ax = fig.add_subplot()
    for values, label in ((energy, "energy (J)"), (vertical, "vertical angular momentum")):
        ax.semilogy(ts, np.abs(values - values[0]) + 1e-300, label=label)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("|drift|")
    ax.legend()
    return viz.save_figure(fig, path)


def check(args) -> int:
    """Print the Galilean-invariance report of a model; exit 1 if it fails."""
    import jax

    import bundledyn as bd

    system = bd.load_system(args.model)
    report = bd.checks.galilean_invariance(
        system, jax.random.key(args.seed), n=args.samples, tolerance=args.tolerance
    )
    print(f"bundledyn check {args.model}")
    print(report)
    return 0 if report.passed else 1


def stress(args) -> int:
    """Run the stress battery (on a model when one is given); exit 1 if a case fails."""
    import bundledyn as bd

    if args.model is None:
        report = bd.stress.battery(quick=args.quick)
    else:
        report = bd.stress.model_battery(bd.load_scene(args.model, passive=True), args.model)
    print(f"bundledyn stress {args.model or ''}".rstrip())
    print(report)
    return 0 if report.passed else 1


def demo(args) -> int:
    """A falling cat turns itself over at zero angular momentum: simulated, checked, drawn."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    import bundledyn as bd
    from bundledyn import lie

    from ._viz._frame_names import GALILEAN, frame_name

    scene_file = bd.SceneFile.load(bd.scenes / "falling_cat.toml")
    cat, shape = scene_file.scene.system, scene_file.scene.shape
    if not isinstance(shape, bd.Prescribed):
        raise _Failure(f"{scene_file.path}: the demo's scene must prescribe the cat's bending.")
    bend = shape.q_of_t
    print("bundledyn demo: a falling cat turns itself over with zero angular momentum")
    print(f"  scene file: {scene_file.path}")
    traj, elapsed = _solve(scene_file)
    diagnostics = traj.diagnostics()
    _summary(scene_file, traj, diagnostics, elapsed)
    rotation = np.asarray(lie.so3_log(traj.g[-1, :3, :3]))
    angle = np.linalg.norm(rotation)
    frame = frame_name(scene_file.scene)
    print(
        f"  net rotation after one shape loop: {np.degrees(angle):.2f} deg about "
        f"{np.round(rotation / angle, 3) + 0.0} in {frame}"
    )
    period = scene_file.t1 - scene_file.t0
    holonomy = bd.horizontal_lift(cat, lambda s: bend(scene_file.t0 + s * period), steps=128)
    print(
        "  check: the holonomy of the shape loop (xi = -A qdot integrated on its own) equals "
        f"the final pose in {frame} to "
        f"{np.abs(np.asarray(holonomy) - np.asarray(traj.g[-1])).max():.1e}"
    )
    reduced = jax.vmap(lambda q, qd: 0.5 * qd @ bd.shape_metric(cat, q) @ qd)(traj.q, traj.qdot)
    print(
        "  check: kinetic energy equals the reduced energy J(qdot, qdot)/2 of zero momentum "
        f"to {float(jnp.max(jnp.abs(diagnostics.energy - reduced))):.1e}"
    )
    print(
        f"  check: largest component of the spatial momentum in {GALILEAN}: "
        f"{np.abs(diagnostics.spatial_momentum).max():.1e}"
    )
    report = bd.checks.galilean_invariance(cat, jax.random.key(0), n=64)
    print("  " + str(report).replace("\n", "\n  "))
    if not args.no_pictures and _pictures_available():
        out = pathlib.Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        for p in _write_pictures(scene_file, traj, diagnostics, out, "falling_cat"):
            print(f"  wrote {p}")
    return 0


def identify(args) -> int:
    """Fit a model's parameters as an identification file says; write the results."""
    from ._identify_file import identify_command

    return identify_command(
        args.config, pathlib.Path(args.out), progress=True if args.progress else None,
        plots=not args.no_pictures and _pictures_available(),
    )  # fmt: skip


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="bundledyn",
        description="Dynamics on principal SE(3) bundles (Chevallier's equations) in JAX.",
    )
    commands = parser.add_subparsers(dest="command", required=True)
    p = commands.add_parser("demo", help="simulate, check and draw a falling-cat reorientation")
    p.add_argument("--out", default="bundledyn-demo", help="folder for the pictures")
    p.add_argument("--no-pictures", action="store_true", help="print the summary only")
    p.set_defaults(run=demo)
    p = commands.add_parser("run", help="simulate a scene file (TOML), write trajectory and plots")
    p.add_argument("scene", help="the scene file")
    p.add_argument("--out", default=".", help="existing folder for the outputs (default: here)")
    p.add_argument("--progress", action="store_true", help="show diffrax's progress meter")
    p.add_argument("--no-pictures", action="store_true", help="write the trajectory only")
    p.add_argument(
        "--batch",
        help="an .npz of initial states (arrays g, q, xi, qdot, one member per row; the "
        "others from the file's [initial]): every member is simulated, spread over the "
        "devices, into <trajectory>_batch.npz",
    )
    p.add_argument(
        "--chunk-size",
        type=_positive(int),
        help="with --batch: members at a time, with progress per chunk",
    )
    p.set_defaults(run=run)
    p = commands.add_parser("check", help="Galilean-invariance report of a model")
    p.add_argument("model", help="an MJCF (.xml), URDF (.urdf) or scene (.toml) file")
    p.add_argument(
        "--samples", type=_positive(int), default=256, help="sampled shapes (default 256)"
    )
    p.add_argument(
        "--tolerance", type=_positive(float), default=1e-10, help="largest residual (1e-10)"
    )
    p.add_argument("--seed", type=int, default=0, help="random seed of the shapes")
    p.set_defaults(run=check)
    p = commands.add_parser("stress", help="hard cases, each against its bound")
    p.add_argument(
        "model", nargs="?", help="an MJCF, URDF or scene file (default: the shipped cases)"
    )
    p.add_argument("--quick", action="store_true", help="the suite's cheaper settings")
    p.set_defaults(run=stress)
    p = commands.add_parser(
        "identify", help="fit masses, centres and inertias to measured motion (TOML config)"
    )
    p.add_argument("config", help="the identification file (TOML)")
    p.add_argument("--out", default=".", help="existing folder for the outputs (default: here)")
    p.add_argument(
        "--progress",
        action="store_true",
        help="show each accepted step (default: on a terminal, for fits over a few seconds)",
    )
    p.add_argument("--no-pictures", action="store_true", help="write no pictures")
    p.set_defaults(run=identify)
    args = parser.parse_args(argv)
    import bundledyn as bd

    bd.use_cpu_xla_flags()
    bd.enable_x64()
    try:
        with _terminated_as_exit():
            return args.run(args)
    except bd.SceneFileError as error:
        print(f"bundledyn: error: {error}", file=sys.stderr)
        return 2
    except (_Failure, ImportError, ValueError) as error:
        print(f"bundledyn: error: {error}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
