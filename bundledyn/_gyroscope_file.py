r"""Scene files of chains of Lagrange gyroscopes in tensor coordinates (seed 000, §4): read,
check, solve, and the first integrals along the solution."""

import dataclasses
import pathlib
import tomllib
from typing import Any, NamedTuple

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from . import lie
from ._scene_file import (
    SceneFileError,
    _Table,
    read_output,
    read_solver,
    read_time,
    tolerances_in_precision,
)
from ._tensorial import (
    LagrangeGyroscopeChain,
    TensorCoordinates,
    TensorialRKMK4,
    TensorialRKMK54,
    TensorialRKMK87,
    TensorialSystem,
    TensorialTerm,
    TensorVelocities,
    rates_of,
)
from ._tensorial._coordinates import angular_velocity

__all__ = ["GyroscopeChainFile", "is_gyroscope_file"]

FORMULATIONS = ("rotations", "axes", "universal")
SOLVERS = {
    "TensorialRKMK87": (TensorialRKMK87, False),
    "TensorialRKMK54": (TensorialRKMK54, False),
    "TensorialRKMK4": (TensorialRKMK4, True),
}  # name -> (solver class, takes fixed steps)
_AXIS = np.array([0.0, 0.0, 1.0])


def is_gyroscope_file(path) -> bool:
    """Whether the TOML file at `path` describes a gyroscope chain (it has `[gyroscopes]`).

    **Arguments:**

    - `path`: a scene file.

    **Returns:**

    True for a chain's file (`GyroscopeChainFile`), False otherwise (a scene, or a file that
    cannot be read as TOML: `SceneFile.load` then says why).
    """
    try:
        return "gyroscopes" in tomllib.loads(pathlib.Path(path).read_text())
    except (OSError, tomllib.TOMLDecodeError):
        return False


class Bodies(NamedTuple):
    """The bodies along a solution: rotations `(t, n, 3, 3)`, angular velocities `(t, n, 3)`."""

    rotations: Any
    angular_velocities: Any


def _relative_ball_joints(t: _Table, n):
    """`[initial]` of a chain on ball joints: each body's rotation vector and angular velocity
    relative to its parent (in its own axes, as MuJoCo's ball joints have them) -> (Z, ω)."""
    turns = t.array("rotations", (n, 3))
    rates = t.array("rates", (n, 3), np.zeros((n, 3)))
    Z, omega = [np.eye(3)], [np.zeros(3)]
    for turn, rate in zip(turns, rates, strict=True):
        Z.append(Z[-1] @ np.asarray(lie.so3_exp(jnp.asarray(turn))))
        omega.append(omega[-1] + Z[-1] @ rate)
    return np.stack(Z[1:]), np.stack(omega[1:])


def _universal_joints(t: _Table, n):
    """`[initial]` of a chain on universal joints: body 1's rotation vector and angular velocity
    (its own axes), and each joint's two angles and their rates (about the parent's y, then
    the child's x) -> (Z, ω)."""
    first = np.asarray(lie.so3_exp(jnp.asarray(t.array("rotation", (3,)))))
    Z, omega = [first], [first @ t.array("rate", (3,), np.zeros(3))]
    angles = t.array("angles", (n - 1, 2))
    angle_rates = t.array("angle_rates", (n - 1, 2), np.zeros((n - 1, 2)))
    for (about_y, about_x), (rate_y, rate_x) in zip(angles, angle_rates, strict=True):
        turn_y = np.asarray(lie.rotation_y(about_y))
        relative = turn_y @ np.asarray(lie.rotation_x(about_x))
        relative_omega = rate_y * np.array([0.0, 1.0, 0.0]) + rate_x * turn_y[:, 0]
        omega.append(omega[-1] + Z[-1] @ relative_omega)
        Z.append(Z[-1] @ relative)
    return np.stack(Z), np.stack(omega)


@dataclasses.dataclass(frozen=True)
class GyroscopeChainFile:
    r"""A chain of Lagrange gyroscopes read from a TOML scene file, in one of the seed's formulations.

    Tables and fields:

    - `[gyroscopes]`: the chain (`LagrangeGyroscopeChain`): `masses`, `lengths`, `centres`,
      `transverse_inertias`, `axial_inertias` (one number per body), `gravity` (9.81);
      `formulation` = `"rotations"` (the bodies' rotation tensors, default), `"axes"` (axes
      and spin angles, with `reference`, the fixed vector of (42)) or `"universal"` (the
      same bodies on universal joints, in $Z_1$ and relative axes).
    - `[initial]`: on ball joints, `rotations` and `rates` ($n\times3$: each body's rotation
      vector and angular velocity relative to its parent, in its own axes); on universal
      joints, `rotation` and `rate` (body 1's) and `angles`, `angle_rates` ($(n-1)\times2$:
      about the parent's $y$, then the child's $x$).
    - `[time]` `t1` (required), `t0` (0), `saves` (101).
    - `[solver]` `method` (`TensorialRKMK87` default, `TensorialRKMK54`, `TensorialRKMK4`,
      which needs `dt0`), `rtol`, `atol` (1e-10), `max_steps` (100000), checked as in
      scene files (`SceneFile`).
    - `[output]` `trajectory` (a `.npz` file name, written into the run's output folder;
      default the file's name), `plots` (true).

    **Fields:** `path`, `text`, `chain`, `formulation`, `reference`, `system`, `y0`, `t0`,
    `t1`, `saves`, `solver`, `options`, `output`.
    """

    path: pathlib.Path
    text: str
    chain: LagrangeGyroscopeChain
    formulation: str
    reference: Any
    system: TensorialSystem
    y0: tuple
    t0: float
    t1: float
    saves: int
    solver: Any
    options: dict
    output: dict

    @classmethod
    def load(cls, path) -> "GyroscopeChainFile":
        """Read and check the file; raise `SceneFileError` naming the field at fault."""
        path = pathlib.Path(path)
        text = path.read_text()
        try:
            root = _Table(path, "", tomllib.loads(text))
        except tomllib.TOMLDecodeError as error:
            raise SceneFileError(f"{path}: not valid TOML: {error}.") from None
        t = root.table("gyroscopes")
        n = len(t.raw("masses")) if isinstance(t.data.get("masses"), list) else 0
        if n < 1 or (t.data.get("formulation") == "universal" and n < 2):
            raise t.fail("masses", "must list one mass per body (two or more on universal joints).")
        fields = ("masses", "lengths", "centres", "transverse_inertias", "axial_inertias")
        with t.building("LagrangeGyroscopeChain"):
            chain = LagrangeGyroscopeChain(
                *(t.array(name, (n,)) for name in fields), gravity=t.number("gravity", 9.81)
            )
        formulation = t.string("formulation", "rotations", set(FORMULATIONS))
        reference = t.array("reference", (3,), np.array([0.9, 0.3, 0.2]))
        reference = jnp.asarray(reference / np.linalg.norm(reference))
        t.done()

        initial = root.table("initial")
        universal = formulation == "universal"
        Z, omega = (_universal_joints if universal else _relative_ball_joints)(initial, n)
        initial.done()
        Z, omega = jnp.asarray(Z), jnp.asarray(omega)
        if universal:
            system, y0 = chain.in_universal_joints(), chain.universal_joint_state(Z, omega)
        else:
            scalars = jnp.zeros(0)
            X = _rotations(Z)
            V = TensorVelocities(scalars, jnp.zeros((0, 3)), omega)
            system, y0 = chain.in_rotations(), (X, V)
            if formulation == "axes":
                system, y0 = chain.in_axes(reference), chain.axes_state(X, V, reference)

        t0, t1, saves = read_time(root.table("time"))

        solver, options = read_solver(
            root.table("solver", {}),
            SOLVERS,
            method="TensorialRKMK87",
            tolerance=1e-10,
            max_steps=100_000,
        )
        out = root.table("output", {})
        output = read_output(out, path.stem)
        out.done()
        root.done()
        return cls(
            path, text, chain, formulation, reference, system, y0, t0, t1, saves, solver,
            options, output,
        )  # fmt: skip

    def solve(self, *, throw: bool = True) -> diffrax.Solution:
        """Integrate the chain with the file's solver, saving `saves` times."""
        fixed = isinstance(self.solver, TensorialRKMK4)
        dtype = jax.tree.leaves(self.y0)[0].dtype
        options = tolerances_in_precision(self.options, dtype, self.path)
        controller = (
            diffrax.ConstantStepSize()
            if fixed
            else diffrax.PIDController(rtol=options["rtol"], atol=options["atol"])
        )
        ts = jnp.linspace(self.t0, self.t1, self.saves)
        return _solve(
            TensorialTerm(self.system), self.solver, self.y0, ts, controller,
            self.options["dt0"], self.options["max_steps"], throw,
        )  # fmt: skip

    def bodies(self, X, V) -> Bodies:
        r"""The bodies' rotations and absolute angular velocities at the solution's saved states."""
        if self.formulation == "rotations":
            return Bodies(X.rotations, V.rotations)
        if self.formulation == "axes":
            Z = lie.rotation_from_unit_vector_and_angle(X.unit_vectors, X.scalars, self.reference)
            rates = jax.vmap(rates_of)(X, V)
            omega = lie.angular_velocity_from_unit_vector_and_angle(
                X.unit_vectors, X.scalars, rates.unit_vectors, rates.scalars, self.reference
            )
            return Bodies(Z, omega)

        def one(X, V):
            Z, Zdot = jax.jvp(self.chain.universal_joint_rotations, (X,), (rates_of(X, V),))
            return Z, angular_velocity(Z, Zdot)

        return Bodies(*jax.vmap(one)(X, V))

    def first_integrals(self, solution) -> dict:
        """The energy and the vertical angular momentum about the pivot at every saved time,
        with how far the rotations left SO(3): `{"energy", "vertical_momentum", "orthogonality"}`."""
        X, V = solution.ys
        energy = jax.vmap(self.system.energy)(X, V, solution.ts)
        Z, omega = self.bodies(X, V)
        axes = Z @ _AXIS
        momentum = jax.vmap(self.chain.angular_momentum)(axes, jnp.cross(omega, axes), omega)
        gram = jnp.swapaxes(Z, -1, -2) @ Z - jnp.broadcast_to(jnp.eye(3), Z.shape)
        return {
            "energy": energy,
            "vertical_momentum": momentum[:, 2],
            "orthogonality": jnp.max(jnp.abs(gram), axis=(-1, -2, -3)),
            "rotations": Z,
            "angular_velocities": omega,
        }


def _rotations(Z):
    return TensorCoordinates(jnp.zeros(0, Z.dtype), jnp.zeros((0, 3), Z.dtype), Z)


@eqx.filter_jit
def _solve(term, solver, y0, ts, controller, dt0, max_steps, throw):
    return diffrax.diffeqsolve(
        term, solver, ts[0], ts[-1], dt0, y0,
        saveat=diffrax.SaveAt(ts=ts), stepsize_controller=controller,
        max_steps=max_steps, throw=throw,
    )  # fmt: skip
