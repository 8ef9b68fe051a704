"""The package's dependencies: every third-party import is declared in pyproject.toml, and
the private diffrax internals that `StoredStepsAdjoint` runs are as its diffrax pin says."""

import ast
import dataclasses
import importlib.metadata
import inspect
import json
import pathlib
import re
import subprocess
import sys
import tomllib

import diffrax
import jax.numpy as jnp
import pytest
from packaging.requirements import Requirement

import bundledyn
from bundledyn._solver._adjoint import StoredStepsAdjoint

PACKAGE = pathlib.Path(bundledyn.__file__).parent
PROJECT = tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text())["project"]
# Extras for working on the package, not features of it: no import of the package may
# need them.
DEVELOPMENT_EXTRAS = {"test", "bench", "docs"}


def _normalized(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _names(requirements) -> set[str]:
    return {_normalized(Requirement(r).name) for r in requirements}


REQUIRED = _names(PROJECT["dependencies"])
OPTIONAL = {
    name: _names(requirements)
    for name, requirements in PROJECT["optional-dependencies"].items()
    if name not in DEVELOPMENT_EXTRAS
}


def _third_party_imports() -> dict[str, list[str]]:
    """Each third-party top-level module the package imports, with where (`file:line`)."""
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split(".")[0]
                if top not in sys.stdlib_module_names and top != "bundledyn":
                    where = f"{path.relative_to(PACKAGE.parent)}:{node.lineno}"
                    found.setdefault(top, []).append(where)
    return found


IMPORTS = _third_party_imports()
DISTRIBUTIONS = importlib.metadata.packages_distributions()


def _distributions(module: str) -> set[str]:
    """The distributions that install `module` (its own name where none is installed)."""
    return {_normalized(d) for d in DISTRIBUTIONS.get(module, [module])}


def test_the_walker_sees_the_imports():
    """The checks below would pass vacuously if the walker missed imports."""
    assert {"jax", "diffrax", "optimistix", "jaxlib", "mujoco", "matplotlib"} <= set(IMPORTS)
    assert any(w.startswith("bundledyn/_identify/_fit.py") for w in IMPORTS["optax"])  # lazy


def test_every_third_party_import_is_declared():
    """Each module the package imports comes from `[project] dependencies` or a feature
    extra (`[project.optional-dependencies]` less the development ones)."""
    declared = REQUIRED.union(*OPTIONAL.values())
    missing = [
        f"{module} ({', '.join(sorted(_distributions(module)))}), imported at {where[0]}"
        for module, where in sorted(IMPORTS.items())
        if not _distributions(module) & declared
    ]
    assert not missing, f"declare these in pyproject.toml's [project] dependencies: {missing}"


def test_every_dependency_is_imported():
    """No stale declaration: each required distribution gives a module the package imports."""
    imported = set().union(*(_distributions(m) for m in IMPORTS))
    assert not REQUIRED - imported, f"declared but not imported: {REQUIRED - imported}"


def test_optional_imports_are_only_in_extras_when_optional():
    """What `import bundledyn` loads of the package's imports is required, not an extra's:
    an extra's module is imported lazily (in a function, or by an optional submodule such
    as `bundledyn.viz`)."""
    loaded = subprocess.run(
        [sys.executable, "-c", "import sys, json, bundledyn; print(json.dumps(list(sys.modules)))"],
        capture_output=True,
        text=True,
        check=True,
        timeout=300,
    )
    loaded = {name.split(".")[0] for name in json.loads(loaded.stdout.splitlines()[-1])}
    needed = [
        f"{module}, imported at {IMPORTS[module][0]}"
        for module in sorted(loaded & set(IMPORTS))
        if not _distributions(module) & REQUIRED
    ]
    assert not needed, (
        f"`import bundledyn` imports these, which only an extra declares: {needed}; declare "
        "them in [project] dependencies or import them where they are used"
    )


# The private diffrax internals of `_solver/_adjoint.py`, as the diffrax pin has them.


def _pin() -> str:
    (pin,) = [r for r in PROJECT["dependencies"] if Requirement(r).name == "diffrax"]
    return pin


def _moved(what: str) -> str:
    return (
        f"diffrax {diffrax.__version__}: {what}. bundledyn/_solver/_adjoint.py "
        f"(`StoredStepsAdjoint`) relies on it, and pyproject.toml pins {_pin()!r}: install a "
        "diffrax within the pin, or update _adjoint.py to the new internals and move the pin."
    )


def test_the_installed_diffrax_is_within_the_pin():
    version = importlib.metadata.version("diffrax")
    assert Requirement(_pin()).specifier.contains(version), _moved(
        f"the installed version {version} is outside the pin"
    )


def test_diffrax_while_loops():
    """`_inner_loop`/`_outer_loop` take `kind="lax"` (the adjoint's forward loop)."""
    try:
        from diffrax._adjoint import _inner_loop, _outer_loop
    except ImportError as error:
        pytest.fail(_moved(f"`diffrax._adjoint._inner_loop`/`_outer_loop` are gone ({error})"))
    for name, while_loop in (("_inner_loop", _inner_loop), ("_outer_loop", _outer_loop)):
        kind = inspect.signature(while_loop).parameters.get("kind")
        assert kind is not None and kind.kind is inspect.Parameter.KEYWORD_ONLY, _moved(
            f"`diffrax._adjoint.{name}` takes no keyword `kind`"
        )
        try:
            out = while_loop(lambda c: c < 3, lambda c: c + 1, jnp.array(0), kind="lax")
        except Exception as error:
            pytest.fail(_moved(f"`{name}(cond, body, init, kind='lax')` raised {error!r}"))
        assert int(out) == 3, _moved(f"`{name}(..., kind='lax')` is no while loop")


def test_diffrax_save_state():
    """The adjoint builds `SaveState(saveat_ts_index=, ts=, ys=, save_index=)` (the record of
    the steps) and reads `ts`, `ys`, `save_index` of diffrax's own."""
    try:
        from diffrax._integrate import SaveState
    except ImportError as error:
        pytest.fail(_moved(f"`diffrax._integrate.SaveState` is gone ({error})"))
    fields = tuple(f.name for f in dataclasses.fields(SaveState))
    assert fields == ("saveat_ts_index", "ts", "ys", "save_index"), _moved(
        f"`SaveState`'s fields are {fields}"
    )
    SaveState(saveat_ts_index=0, ts=jnp.zeros(2), ys=jnp.zeros((2, 3)), save_index=0)


def test_diffrax_loop_and_state():
    """The adjoint calls diffrax's `loop` with `AbstractAdjoint.loop`'s keywords (less
    `throw` and the passed solver and controller states) and the two while loops, names
    each in its reverse pass, and reads these fields of the loop's `State`."""
    try:
        from diffrax._integrate import State, loop
    except ImportError as error:
        pytest.fail(_moved(f"`diffrax._integrate.loop`/`State` are gone ({error})"))
    adjoint_keywords = {
        "args", "terms", "solver", "stepsize_controller", "event", "saveat", "t0", "t1",
        "dt0", "max_steps", "throw", "init_state", "passed_solver_state",
        "passed_controller_state", "progress_meter",
    }  # fmt: skip
    loop_keywords = adjoint_keywords - {"throw", "passed_solver_state", "passed_controller_state"}
    loop_keywords |= {"inner_while_loop", "outer_while_loop"}
    found = set(inspect.signature(diffrax.AbstractAdjoint.loop).parameters) - {"self"}
    assert found == adjoint_keywords, _moved(f"`AbstractAdjoint.loop` takes {sorted(found)}")
    found = set(inspect.signature(loop).parameters)
    assert found == loop_keywords, _moved(f"`diffrax._integrate.loop` takes {sorted(found)}")
    assert StoredStepsAdjoint()._loop is loop, _moved("`AbstractAdjoint._loop` is another loop")
    used = {
        "y", "tprev", "tnext", "solver_state", "controller_state", "save_state",
        "num_accepted_steps", "event_mask",
    }  # fmt: skip
    fields = {f.name for f in dataclasses.fields(State)}
    assert used <= fields, _moved(f"its loop's `State` lacks {sorted(used - fields)}")
