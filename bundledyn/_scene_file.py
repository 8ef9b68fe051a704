"""Scene files: a whole simulation (system, effects, shape, frame, state, solver) in TOML.

A scene file is what one researcher hands another: `bundledyn run scene.toml` simulates
it, `bundledyn check scene.toml` checks its model. Every table and key is described in
`SceneFile`'s docstring; every mistake is reported with the file, the field and the value.
"""

import contextlib
import dataclasses
import difflib
import pathlib
import tomllib
from typing import Any

import diffrax
import jax.numpy as jnp
import numpy as np

from . import lie
from ._effects import (
    BodywiseGravityGradient,
    Gravity,
    GravityGradient,
    ShapeDamper,
    ShapeSpring,
)
from ._frames import Boosted, FreeFalling
from ._geometry import connection
from ._modes import (
    AbstractPlaneContactMode,
    Prescribed,
    RollingMode,
    RollingWheelMode,
    SkatingMode,
    Wheel,
)
from ._nonholonomic import (
    DiscContact,
    EllipsoidContact,
    PointContact,
    SphereContact,
    TorusContact,
)
from ._paths import models
from ._precision import check_tolerances, warn_in_callers_code
from ._scene import Scene, model_base, model_effects, system_of_parts
from ._simulate import simulate
from ._solids import Box, Capsule, Ellipsoid
from ._solver._lie_euler import LieEuler
from ._solver._rkmk import RKMK4, RKMK54, RKMK87
from ._solver._variational import VariationalMidpoint
from ._state import State
from ._systems._affine_body import AffineBody
from ._systems._joints import Fixed, Prismatic, Revolute, Spherical, Universal
from ._systems._link import Link
from ._systems._mujoco_import import parts_from_mjcf, parts_from_urdf
from ._systems._multibody import Multibody
from ._systems._rigid_body import RigidBody
from ._trajectory import Trajectory
from ._validation import precision_floor

SOLVERS = {
    "RKMK54": (RKMK54, False),
    "RKMK87": (RKMK87, False),
    "RKMK4": (RKMK4, True),
    "LieEuler": (LieEuler, True),
    "VariationalMidpoint": (VariationalMidpoint, True),
    "Tsit5": (diffrax.Tsit5, False),
    "Dopri5": (diffrax.Dopri5, False),
    "Dopri8": (diffrax.Dopri8, False),
    "Kvaerno5": (diffrax.Kvaerno5, False),
}  # name -> (solver class, takes fixed steps)


class SceneFileError(ValueError):
    """A scene or model file that cannot be used, with the file, field and value at fault."""


class _Table:
    """One TOML table being read: typed getters that name the field when they fail."""

    def __init__(self, file, prefix, data):
        self.file, self.prefix, self.data, self.used = file, prefix, data, set()
        if not isinstance(data, dict):
            raise SceneFileError(f"{file}: {self.name} must be a table, got {data!r}.")

    @property
    def name(self) -> str:
        """How messages name this table: `[prefix]`, or the file's top level."""
        return f"`[{self.prefix}]`" if self.prefix else "the file's top level"

    def field(self, key):
        return f"{self.prefix}.{key}" if self.prefix else key

    def fail(self, key, message):
        value = self.data.get(key, "<missing>")
        return SceneFileError(f"{self.file}: field `{self.field(key)}` = {value!r}: {message}")

    def has(self, key):
        return key in self.data

    def raw(self, key, default: Any = ...):
        self.used.add(key)
        if key not in self.data:
            if default is ...:
                raise self.fail(key, "this field is required." + self._misspelt(key))
            return default
        return self.data[key]

    def _misspelt(self, key) -> str:
        """A hint naming a key of this table that looks like a misspelling of `key`."""
        close = difflib.get_close_matches(key, [k for k in self.data if k != key], n=1)
        return f" The table has `{self.field(close[0])}`: a misspelling of it?" if close else ""

    def number(self, key, default: Any = ...):
        """A finite number (TOML's `nan` and `inf` are refused)."""
        if not self.has(key) and default is not ...:
            return self.raw(key, default)
        value = self.raw(key)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(key, "must be a number.")
        if not np.isfinite(value):
            raise self.fail(key, "must be a finite number.")
        return float(value)

    def whole(self, key, default: int, minimum: int) -> int:
        """A whole number of at least `minimum`."""
        value = self.number(key, default)
        if value < minimum or value != int(value):
            raise self.fail(key, f"must be a whole number ≥ {minimum}.")
        return int(value)

    def boolean(self, key, default: Any = ...):
        value = self.raw(key, default)
        if not isinstance(value, bool):
            raise self.fail(key, "must be true or false.")
        return value

    def string(self, key, default: Any = ..., choices=None):
        if not self.has(key) and default is not ...:
            return self.raw(key, default)
        value = self.raw(key)
        if not isinstance(value, str):
            raise self.fail(key, "must be a string.")
        if choices is not None and value not in choices:
            raise self.fail(key, f"must be one of {', '.join(sorted(choices))}.")
        return value

    def array(self, key, shape, default: Any = ...):
        """A float array of `shape`."""
        if not self.has(key) and default is not ...:
            return np.asarray(self.raw(key, default), dtype=float)
        value = self.raw(key)
        a = np.asarray(value, dtype=float) if _numeric(value) else None
        if a is None or a.shape != tuple(shape):
            got = "" if a is None else f", got shape {a.shape}"
            raise self.fail(key, f"must be numbers of shape {tuple(shape)}{got}.")
        if not np.all(np.isfinite(a)):
            raise self.fail(key, "must be finite.")
        return a

    def vector_or_scalar(self, key, n, default: Any = ...):
        """A length-`n` vector; a scalar is repeated."""
        value = self.raw(key, default)
        a = np.asarray(value, dtype=float) if _numeric(value) else None
        if a is None or a.shape not in ((), (n,)):
            raise self.fail(key, f"must be a number or a list of {n} numbers.")
        return np.broadcast_to(a, (n,)).copy()

    def table(self, key, default: Any = ...):
        return _Table(self.file, self.field(key), self.raw(key, default))

    def tables(self, key):
        value = self.raw(key, [])
        if not isinstance(value, list):
            raise self.fail(key, "must be an array of tables ([[...]]).")
        return [_Table(self.file, f"{self.field(key)}[{i}]", v) for i, v in enumerate(value)]

    def done(self):
        """Refuse keys nobody read: a typo must not be ignored silently."""
        unknown = sorted(set(self.data) - self.used)
        if unknown:
            known = ", ".join(sorted(self.used)) or "none"
            raise SceneFileError(
                f"{self.file}: unknown field `{self.field(unknown[0])}` (fields read here: {known})."
            )

    @contextlib.contextmanager
    def building(self, what):
        """Turn a constructor's `ValueError` into one that names this table."""
        try:
            yield
        except SceneFileError:
            raise
        except ValueError as error:
            where = f"{self.name} ({what})" if self.prefix else f"the {what}"
            raise SceneFileError(f"{self.file}: {where}: {error}") from None


def _numeric(value):
    try:
        np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return False
    return not isinstance(value, bool | str)


# ------------------------------------------------------------------------------ bodies


def _solid(t: _Table):
    kind = t.string("solid", None, {"box", "ellipsoid", "capsule"})
    if kind is None:
        return None
    with t.building(kind):
        if kind == "box":
            return Box(t.array("size", (3,)))
        if kind == "ellipsoid":
            return Ellipsoid(t.array("radii", (3,)))
        return Capsule(t.number("radius"), t.number("length"))


def _rigid_body(t: _Table):
    """A `RigidBody` from `mass`, `centre` and either `solid` or `inertia`; and its solid."""
    mass = t.number("mass")
    centre = t.array("centre", (3,), (0.0, 0.0, 0.0))
    solid = _solid(t)
    with t.building("rigid body"):
        if solid is not None:
            if t.has("inertia"):
                raise t.fail("inertia", "give either `solid` or `inertia`, not both.")
            return solid.rigid_body(mass, centre), solid
        if not t.has("inertia"):
            raise t.fail("inertia", "give a `solid` (box, ellipsoid, capsule) or an `inertia`.")
        moments = _numeric(t.data["inertia"]) and np.ndim(t.data["inertia"]) == 1
        inertia = t.array("inertia", (3,) if moments else (3, 3))
        return RigidBody(mass, centre, np.diag(inertia) if moments else inertia), None


_JOINTS = {"revolute", "prismatic", "universal", "spherical", "fixed"}


def _joint(t: _Table):
    kind = t.string("joint", choices=_JOINTS)
    anchor = t.array("anchor", (3,), (0.0, 0.0, 0.0))
    with t.building(f"{kind} joint"):
        if kind == "revolute":
            return Revolute(t.array("axis", (3,)), anchor)
        if kind == "prismatic":
            return Prismatic(t.array("axis", (3,)))
        if kind == "universal":
            axes = t.array("axes", (2, 3))
            return Universal(axes[0], axes[1], anchor)
        if kind == "spherical":
            return Spherical(anchor)
        return Fixed()


def _placement(t: _Table):
    T = np.eye(4)
    T[:3, :3] = np.asarray(lie.so3_exp(jnp.asarray(t.array("rotation", (3,), (0.0, 0.0, 0.0)))))
    T[:3, 3] = t.array("offset", (3,), (0.0, 0.0, 0.0))
    return T


def _multibody(t: _Table):
    bodies = t.tables("bodies")
    if not bodies:
        raise t.fail("bodies", "a multibody needs at least one [[system.bodies]] table.")
    names, links, solids = [], [], []
    base = None  # the first body's (there is one)
    for i, b in enumerate(bodies):
        name = b.string("name", f"body{i}")
        if name in names:
            raise b.fail("name", "body names must be unique.")
        body, solid = _rigid_body(b)
        if i == 0:
            base = body
        else:
            parent = b.raw("parent", names[-1])
            if parent not in names:
                raise b.fail("parent", f"must name an earlier body ({', '.join(names)}).")
            with b.building("link"):
                links.append(Link(body, _joint(b), names.index(parent), _placement(b)))
        b.done()
        names.append(name)
        solids.append(solid)
    with t.building("multibody"):
        system = Multibody(base, links, names=names)
    return system, (tuple(solids) if all(s is not None for s in solids) else None)


def _affine_body(t: _Table):
    mass = t.number("mass")
    if t.has("radii"):
        radii = t.array("radii", (3,))
        with t.building("affine body"):
            solid = Ellipsoid(radii)
        return AffineBody(mass, mass / 5.0 * np.diag(radii**2)), (solid,)
    with t.building("affine body"):
        return AffineBody(mass, t.array("second_moment", (3, 3))), None


def _model(t: _Table, kind, folder):
    """An imported model's system, no solids, the effects it asks for (its springs and
    dampers, `passive = true`, and gravity, `gravity = "model"`) and its base as MuJoCo
    has it (`model_base`: held where the model welds its root to the world)."""
    if t.has("path") == t.has("model"):
        raise t.fail("path", "give exactly one of `path` (a file) or `model` (a shipped model).")
    if t.has("model"):
        source = models / t.string("model")
        if not source.is_file():
            shipped = ", ".join(sorted(p.name for p in models.iterdir()))
            raise t.fail("model", f"no shipped model of that name (shipped: {shipped}).")
    else:
        source = (folder / t.string("path")).resolve()
        if not source.is_file():
            raise t.fail("path", f"no such file: {source}.")
    passive = t.boolean("passive", False)
    gravity = t.string("gravity", "none", {"none", "model"}) == "model"
    read = parts_from_urdf if kind == "urdf" else parts_from_mjcf
    with t.building(kind):
        parts = read(source, passive=passive)
        system = system_of_parts(parts)
    effects = tuple(model_effects(parts, passive=passive, gravity=gravity))
    return system, None, effects, model_base(parts)


def _system(t: _Table, folder):
    kind = t.string("type", choices={"rigid_body", "multibody", "affine_body", "mjcf", "urdf"})
    if kind == "rigid_body":
        system, solid = _rigid_body(t)
        built = system, (None if solid is None else (solid,)), (), None
    elif kind == "multibody":
        system, solids = _multibody(t)
        built = system, solids, (), None
    elif kind == "affine_body":
        system, solids = _affine_body(t)
        built = system, solids, (), None
    else:
        built = _model(t, kind, folder)
    t.done()
    return built


def load_system(path):
    """A system from a model file: MJCF (`.xml`), URDF (`.urdf`) or a scene file (`.toml`).

    **Arguments:**

    - `path`: the file.

    **Returns:**

    The `AbstractSystem`.

    Raises `SceneFileError` (a `ValueError`) naming the file and the problem.
    """
    return load_scene(path).system


def load_scene(path, *, passive: bool = False) -> Scene:
    """A scene from a model file: MJCF (`.xml`) or URDF (`.urdf`), or a scene file's scene
    (`.toml`, with its effects, shape mode and frame).

    **Arguments:**

    - `path`: the file.
    - `passive`: for MJCF and URDF, add the model's springs and dampers
      (`Scene.from_mjcf`'s `passive`).

    **Returns:**

    The `Scene`.

    Raises `SceneFileError` (a `ValueError`) naming the file and the problem.
    """
    path = pathlib.Path(path)
    if not path.is_file():
        raise SceneFileError(f"{path}: no such file.")
    suffix = path.suffix.lower()
    if suffix == ".toml":
        return SceneFile.load(path).scene
    if suffix not in (".xml", ".urdf"):
        raise SceneFileError(f"{path}: unknown model format {suffix!r}; use .xml, .urdf or .toml.")
    table = _Table(path, "", {"path": path.name, "passive": passive})
    system, _, effects, base = _model(table, "mjcf" if suffix == ".xml" else "urdf", path.parent)
    return Scene(system, list(effects), base=base)


# ------------------------------------------------------------------------------- scene


def _effect(t: _Table, d):
    kind = t.string("type", choices={"gravity", "gravity_gradient", "shape_spring", "shape_damper"})
    with t.building(kind):
        if kind == "gravity":
            effect = Gravity(
                t.number("g", 9.81),
                t.array("direction", (3,), (0.0, 0.0, -1.0)),
                gravitational_mass=t.number("gravitational_mass", None),
                centre_offset=t.array("centre_offset", (3,)) if t.has("centre_offset") else None,
            )
        elif kind == "gravity_gradient":
            central = BodywiseGravityGradient if t.boolean("per_body", False) else GravityGradient
            effect = central(t.number("mu"), t.array("centre", (3,), (0.0, 0.0, 0.0)))
        elif kind == "shape_spring":
            effect = ShapeSpring(
                t.vector_or_scalar("stiffness", d), t.vector_or_scalar("rest", d, 0.0)
            )
        else:
            effect = ShapeDamper(t.vector_or_scalar("damping", d))
    t.done()
    return effect


def _prescribed(t: _Table, d):
    r"""$q_k(t) = o_k + a_k \sin(2\pi f_k t + \varphi_k)$, each field a scalar or a d-vector."""
    amplitude = jnp.asarray(t.vector_or_scalar("amplitude", d))
    frequency = jnp.asarray(t.vector_or_scalar("frequency", d))
    phase = jnp.asarray(t.vector_or_scalar("phase", d, 0.0))
    offset = jnp.asarray(t.vector_or_scalar("offset", d, 0.0))

    def q_of_t(time):
        return offset + amplitude * jnp.sin(2.0 * jnp.pi * frequency * time + phase)

    return Prescribed(q_of_t)


def _frame(t: _Table):
    kind = t.string("type", "galilean", {"galilean", "boosted", "free_falling"})
    with t.building(kind):
        if kind == "boosted":
            frame = Boosted(t.array("velocity", (3,)))
        elif kind == "free_falling":
            frame = FreeFalling(t.number("g", 9.81), t.array("direction", (3,), (0.0, 0.0, -1.0)))
        else:
            frame = None
    t.done()
    return frame


_SURFACES = {
    "sphere": (SphereContact, ("radius",), ("centre",)),
    "disc": (DiscContact, ("radius",), ("axis", "centre")),
    "torus": (TorusContact, ("radius", "tube_radius"), ("axis", "centre")),
    "ellipsoid": (EllipsoidContact, (), ("semi_axes", "centre")),
    "point": (PointContact, (), ("point",)),
}
_REQUIRED_VECTORS = {"ellipsoid": ("semi_axes",), "point": ("point",)}
# Each contact table: its mode, the surfaces it takes, and its mode's own vectors.
_CONTACTS = {
    "rolling": (RollingMode, ("sphere", "disc", "torus", "ellipsoid"), ()),
    "skating": (SkatingMode, ("point", "disc"), ("blade_axis",)),
}


def _surface(t: _Table, kinds):
    """A contact surface from a table's `surface` (one of `kinds`) and its numbers."""
    kind = t.string("surface", choices=set(kinds))
    make, numbers, vectors = _SURFACES[kind]
    arguments = {key: t.number(key) for key in numbers}
    for key in vectors:
        if key in _REQUIRED_VECTORS.get(kind, ()) or t.has(key):
            arguments[key] = t.array(key, (3,))
    with t.building("surface"):
        return make(**arguments)


def _wheels(t: _Table, kinds) -> list[Wheel]:
    """A rolling table's wheels: its one `wheel` (a body's name) on its surface, or its
    `[[rolling.wheels]]`, each a `body` and a surface."""
    if t.has("wheel"):
        return [Wheel(t.string("wheel"), _surface(t, kinds))]
    wheels = []
    for table in t.tables("wheels"):
        with table.building("body"):
            wheels.append(Wheel(table.string("body"), _surface(table, kinds)))
        table.done()
    return wheels


def _contact(t: _Table, name: str) -> AbstractPlaneContactMode | RollingWheelMode:
    """The `[rolling]` or `[skating]` table: a body's contact surface on a plane, or a
    tree's rolling wheels."""
    make_mode, kinds, own = _CONTACTS[name]
    plane: dict[str, Any] = {key: t.array(key, (3,)) for key in own if t.has(key)}
    plane["normal"] = t.array("normal", (3,), (0.0, 0.0, 1.0))
    plane["offset"] = t.number("offset", 0.0)
    if name == "rolling" and (t.has("wheel") or t.has("wheels")):
        wheels = _wheels(t, kinds)
        independent = t.raw("independent", None)
        if independent is not None and not (
            isinstance(independent, list) and all(type(i) is int for i in independent)
        ):
            raise t.fail("independent", "must be a list of whole numbers, indices into v.")
        with t.building("wheels"):
            mode = RollingWheelMode(wheels, independent=independent, **plane)
    else:
        surface = _surface(t, kinds)
        with t.building("surface"):
            mode = make_mode(surface, **plane)
    t.done()
    return mode


def _pose(t: _Table):
    """`[initial]`'s pose: its `rotation` (a rotation vector) and `position`."""
    g = np.eye(4)
    g[:3, :3] = np.asarray(lie.so3_exp(jnp.asarray(t.array("rotation", (3,), (0.0, 0.0, 0.0)))))
    g[:3, 3] = t.array("position", (3,), (0.0, 0.0, 0.0))
    return g


def _wheel_state(t: _Table, mode: RollingWheelMode, system):
    """`[initial]` of a tree rolling on wheels: the pose (placed on the plane), the shape
    `q`, and the velocities `omega`, `velocity` (the section's, body frame) and `qdot`, of
    which the mode's characteristics are kept and the others solved from the rolling."""
    if t.has("xi"):
        raise t.fail("xi", "a rolling tree's twist is `omega` and `velocity`.")
    g = _pose(t)
    d = system.shape_dim
    q, qdot = t.vector_or_scalar("q", d, 0.0), t.vector_or_scalar("qdot", d, 0.0)
    omega = t.array("omega", (3,), (0.0, 0.0, 0.0))
    velocity = t.array("velocity", (3,), (0.0, 0.0, 0.0))
    t.done()
    independent = mode.characteristics(d)
    return mode.state(
        system, g, q, np.concatenate([omega, velocity, qdot])[np.asarray(independent)]
    )


def _contact_state(t: _Table, mode: AbstractPlaneContactMode):
    """`[initial]` of a scene on a plane contact: the pose (placed on the plane), `omega` and,
    on a blade, the speed `sliding` along it."""
    for key in ("q", "qdot", "xi"):
        if t.has(key):
            raise t.fail(
                key, "a body on a plane contact has no shape, and its twist follows from `omega`."
            )
    g = _pose(t)
    omega = t.array("omega", (3,), (0.0, 0.0, 0.0))
    sliding = None
    if isinstance(mode, SkatingMode):
        sliding = np.array([t.number("sliding", 0.0)])
    t.done()
    return mode.state(g, omega, sliding)


def _state(t: _Table, system, shape, t0):
    d = system.shape_dim
    g = _pose(t)
    if shape is not None:
        for key in ("q", "qdot"):
            if t.has(key):
                raise t.fail(key, "the shape is prescribed: [shape] gives q and qdot.")
        q, qdot = (np.asarray(x) for x in shape.at(jnp.asarray(t0)))
    else:
        q = t.vector_or_scalar("q", d, 0.0)
        qdot = t.vector_or_scalar("qdot", d, 0.0)
    if t.raw("xi", None) == "zero_momentum":
        xi = -np.asarray(connection(system, jnp.asarray(q))) @ qdot if d else np.zeros(6)
    else:
        xi = t.array("xi", (6,), np.zeros(6))
    t.done()
    return State(g, q, xi, qdot)


def read_time(time: _Table) -> tuple[float, float, int]:
    """`[time]`: `(t0, t1, saves)`, `t1` required and later than `t0` (0), `saves` (101) a
    whole number ≥ 2."""
    t0, t1 = time.number("t0", 0.0), time.number("t1")
    saves = time.whole("saves", 101, minimum=2)
    if t1 <= t0:
        raise time.fail("t1", f"must be later than t0 = {t0}.")
    time.done()
    return t0, t1, saves


def read_solver(
    table: _Table, solvers: dict, *, method: str, tolerance: float | None, max_steps: int
):
    """`[solver]`: `(solver, options)`, the method one of `solvers` (name -> (class, takes
    fixed steps)); `rtol` in (0, 1) and `atol` ≥ 0 (defaults `tolerance`; `None`: the
    working precision's, `simulate`'s default) that float64 can meet; `dt0` (required by
    fixed-step methods) > 0; `max_steps` a whole number ≥ 1."""
    name = table.string("method", method, set(solvers))
    make, fixed = solvers[name]
    rtol, atol = table.number("rtol", tolerance), table.number("atol", tolerance)
    if rtol is not None and not 0.0 < rtol < 1.0:
        raise table.fail("rtol", "must be between 0 and 1 (a relative error, e.g. 1e-8).")
    if atol is not None and atol < 0.0:
        raise table.fail("atol", "must be ≥ 0.")
    try:
        check_tolerances(1e-8 if rtol is None else rtol, 1e-8 if atol is None else atol, np.float64)
    except ValueError as error:
        raise table.fail("rtol", str(error)) from None
    dt0 = table.number("dt0", None) if fixed or table.has("dt0") else None
    if fixed and dt0 is None:
        raise table.fail("dt0", f"{name} takes fixed steps: give the step `dt0`.")
    if dt0 is not None and dt0 <= 0.0:
        raise table.fail("dt0", "must be positive.")
    options = {
        "rtol": rtol,
        "atol": atol,
        "dt0": dt0,
        "max_steps": table.whole("max_steps", max_steps, minimum=1),
    }
    table.done()
    return make(), options


def read_output(table: _Table, stem: str) -> dict:
    """`[output]`'s `trajectory` (a bare `.npz` file name, written into the run's output
    folder; default `stem.npz`) and `plots` (true); the caller reads its other fields."""
    trajectory = table.string("trajectory", f"{stem}.npz")
    if pathlib.PurePath(trajectory).name != trajectory or not trajectory.endswith(".npz"):
        raise table.fail(
            "trajectory",
            "must be a file name ending in .npz, without folders (the run writes it into "
            "its output folder, `--out`).",
        )
    return {"trajectory": trajectory, "plots": table.boolean("plots", True)}


@dataclasses.dataclass(frozen=True)
class SceneFile:
    r"""A simulation read from a TOML scene file: everything `simulate` needs, and the outputs.

    Tables and fields (vectors are TOML lists; a shape vector may be one number, repeated):

    - `[system]` `type` = `"rigid_body"` (`mass`, `centre`, and `solid` = `"box"`
      (`size`), `"ellipsoid"` (`radii`) or `"capsule"` (`radius`, `length`), or `inertia`:
      3 moments or 3×3), `"multibody"` (`[[system.bodies]]`: the first is the floating base;
      each next one has `name`, `parent` (a body name, default the previous body), `joint` =
      `"revolute"` (`axis`, `anchor`), `"prismatic"` (`axis`), `"universal"` (`axes` 2×3,
      `anchor`), `"spherical"` (`anchor`) or `"fixed"`, its placement in the parent at q = 0
      (`offset`, `rotation` vector), and a rigid body's fields), `"affine_body"` (`mass`,
      `radii` of a solid ellipsoid or `second_moment`), `"mjcf"` or `"urdf"` (`path`
      relative to the scene file, or `model` = a file in `bundledyn.models`;
      `passive = true` adds the model's linear springs and dampers (of joints and fixed
      tendons) and `gravity = "model"` its gravity, as `Scene.from_mjcf` and
      `Scene.from_urdf` do).
    - `[[effects]]` `type` = `"gravity"` (`g`, `direction`, `gravitational_mass`,
      `centre_offset`), `"gravity_gradient"` (`mu`, `centre`, `per_body`: `BodywiseGravityGradient`),
      `"shape_spring"` (`stiffness`, `rest`) or `"shape_damper"` (`damping`).
    - `[shape]` `mode` = `"free"` (default) or `"prescribed"`:
      $q(t) = o + a\sin(2\pi f t + \varphi)$ from `offset`, `amplitude`, `frequency`, `phase`.
    - `[rolling]`: the rigid body rolls without slipping on a plane (`RollingMode`):
      `surface` = `"sphere"` (`radius`, `centre`), `"disc"` (`radius`, `axis`, `centre`),
      `"torus"` (`radius`, `tube_radius`, `axis`, `centre`) or `"ellipsoid"` (`semi_axes`,
      `centre`); the plane's `normal` (default up) and `offset`. Its `[initial]` takes
      `position`, `rotation` and the body angular velocity `omega` (the body is placed on
      the plane, its twist the rolling one); not with `[shape]`. With `wheel` (a body's
      name), that body of a tree rolls (`RollingWheelMode` with one `Wheel`); with
      `[[rolling.wheels]]` (each a `body` and its surface) and `independent`, several do.
      Their `[initial]` takes `position`, `rotation`, the shape `q`, and `omega`,
      `velocity` (the section's, body frame) and `qdot`, of which the velocities the
      rolling leaves free are kept and the others solved for.
    - `[skating]`: the rigid body skates on a blade on a plane (`SkatingMode`): `surface` =
      `"point"` (`point`) or `"disc"` (a rockered blade: `radius`, `axis`, `centre`), the
      blade plane's normal `blade_axis` (default $(0, 1, 0)$), the plane's `normal` and
      `offset`. Its `[initial]` takes `position`, `rotation`, `omega` and the contact point's
      speed along the blade, `sliding`.
    - `[frame]` `type` = `"galilean"` (default), `"boosted"` (`velocity`) or
      `"free_falling"` (`g`, `direction`).
    - `[initial]` `position`, `rotation` (rotation vector), `q`, `qdot`, and `xi` (6 numbers,
      angular first) or `"zero_momentum"` for $\xi = -A(q)\dot q$.
    - `[time]` `t1` (required), `t0` (0), `saves` (saved times, evenly spaced; 101).
    - `[solver]` `method` (`RKMK87` default, `RKMK54`, `RKMK4`, `LieEuler`,
      `VariationalMidpoint`, `Tsit5`, `Dopri5`, `Dopri8`, `Kvaerno5`), `rtol` (between 0
      and 1) and `atol` (≥ 0), by default `simulate`'s; `dt0` (positive; required by the
      fixed-step methods), `max_steps` (a whole number ≥ 1).
    - `[output]` `trajectory` (a `.npz` file name, written into the run's output folder;
      default the scene's name), `plots` (true), `animation` (false), `frames` (≥ 2; 60).

    Every number must be finite; a required field that is missing is named, with the
    table's key that looks like a misspelling of it.

    **Fields:** `path`, `text` (the file as read), `scene`, `state`, `t0`, `t1`, `saves`,
    `solver`, `options` (keyword arguments of `simulate`), `solids` (one per body, or
    `None`), `output` (a dict of the `[output]` settings).
    """

    path: pathlib.Path
    text: str
    scene: Scene
    state: State
    t0: float
    t1: float
    saves: int
    solver: Any
    options: dict
    solids: tuple | None
    output: dict

    @classmethod
    def load(cls, path) -> "SceneFile":
        """Read and check a scene file; raise `SceneFileError` naming the field at fault."""
        path = pathlib.Path(path)
        try:
            text = path.read_text()
        except OSError as error:
            raise SceneFileError(f"{path}: cannot read the file ({error.strerror}).") from None
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as error:
            raise SceneFileError(f"{path}: not valid TOML: {error}.") from None
        root = _Table(path, "", data)
        system, solids, model_effects, base = _system(root.table("system"), path.parent)
        d = system.shape_dim
        effects = model_effects + tuple(_effect(t, d) for t in root.tables("effects"))

        shape_table = root.table("shape", {})
        mode = shape_table.string("mode", "free", {"free", "prescribed"})
        shape = _prescribed(shape_table, d) if mode == "prescribed" else None
        shape_table.done()
        frame = _frame(root.table("frame", {}))
        contacts = [name for name in _CONTACTS if root.has(name)]
        if len(contacts) > 1:
            raise root.fail(
                contacts[1], "a body rolls or skates: give one of [rolling], [skating]."
            )
        contact = _contact(root.table(contacts[0]), contacts[0]) if contacts else None
        if contact is not None and base is not None:
            raise root.fail(
                contacts[0],
                "the model welds its root to the world (the root body has no joint): a "
                "body that rolls or skates needs a <freejoint/> on its root.",
            )
        with root.building("scene"):
            scene = Scene(system, effects, shape, frame, base=base, mode=contact)

        t0, t1, saves = read_time(root.table("time"))
        initial = root.table("initial", {})
        if contact is None:
            state = _state(initial, system, shape, t0)
        elif isinstance(contact, RollingWheelMode):
            state = _wheel_state(initial, contact, system)
        else:
            state = _contact_state(initial, contact)

        solver, options = read_solver(
            root.table("solver", {}), SOLVERS, method="RKMK87", tolerance=None, max_steps=16384
        )
        out = root.table("output", {})
        output = read_output(out, path.stem) | {
            "animation": out.boolean("animation", False),
            "frames": out.whole("frames", 60, minimum=2),
        }
        out.done()
        root.done()
        return cls(path, text, scene, state, t0, t1, saves, solver, options, solids, output)

    def simulate(
        self, *, state: State | None = None, progress: bool = False, throw: bool = True
    ) -> Trajectory:
        """Run the scene: `simulate` with the file's solver and options, saving `saves` times.

        **Arguments:**

        - `state`: the initial state; default, the file's `[initial]` (`SceneFile.state`).
          Another (one member of a batch, under `jax.vmap`) is solved with the same
          solver, options and saved times.
        - `progress`: show diffrax's progress meter.
        - `throw`: raise if the solve fails (else read `Trajectory.result`).
        """
        ts = jnp.linspace(self.t0, self.t1, self.saves)
        return simulate(
            self.scene,
            self.state if state is None else state,
            self.t1,
            t0=self.t0,
            solver=self.solver,
            saveat=diffrax.SaveAt(ts=ts),
            progress=progress,
            throw=throw,
            **tolerances_in_precision(self.options, self.state.g.dtype, self.path),
        )


def tolerances_in_precision(options: dict, dtype, path) -> dict:
    """A file's solver `options` with `rtol` and `atol` raised, warning, to 100 rounding
    errors of `dtype` where they are below it (where `simulate` would refuse or warn): a
    file written for float64 (rtol 1e-10) then runs in float32 at the accuracy float32
    allows, rather than being refused."""
    floor = precision_floor(dtype, 0.0, 100.0)
    raised = {
        name: floor
        for name in ("rtol", "atol")
        if options[name] is not None and options[name] < floor
    }
    if raised:
        given = ", ".join(f"solver.{name} = {options[name]:g}" for name in raised)
        warn_in_callers_code(
            f"{path}: {given} cannot be met in {jnp.dtype(dtype).name}; solving at {floor:.1e}. "
            "Call `bundledyn.enable_x64()` before loading the file for the file's own "
            "tolerances (the command line does)."
        )
    return options | raised
