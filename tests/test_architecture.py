"""The package's structure: imports flow one way (architecture §4.1), between modules and between
folders, and the type checker passes."""

import ast
import json
import pathlib
import subprocess

import pytest

import bundledyn

PACKAGE = pathlib.Path(bundledyn.__file__).parent

# The layers of architecture §4.1 (docs/devdocs/architecture.md), lowest first: a module may
# import its own layer and those before it.
LAYERS = (
    (
        "lie",
        {"_lie", "lie", "_linalg", "_implicit", "_validation", "_xla_flags", "_files", "_paths"},
    ),
    ("systems", {"_systems", "_solids", "_state", "_precision"}),
    ("geometry", {"_geometry", "_holonomy"}),
    ("dynamics", {"_dynamics", "_dynamics_vjp", "_nonholonomic"}),
    ("scene", {"_effects", "_coupled_effects", "_tendons", "_frames", "_modes", "_scene"}),
    ("term", {"_term", "_reverse_term"}),
    ("integrators", {"_solver"}),
    ("tensorial", {"_tensorial"}),
    ("simulate", {"_simulate", "_stiffness", "_trajectory", "_batches"}),
    (
        "identification, checks and stress",
        {"_checks", "checks", "_identify", "identify", "_stress", "stress"},
    ),
    (
        "front",
        {
            "_gyroscope_file",
            "_viz",
            "viz",
            "_scene_file",
            "_identify_file",
            "_cli",
            "__main__",
            "__init__",
        },
    ),
)


def _module_name(path: pathlib.Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _resolve(module: str, is_package: bool, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = module.split(".")
    base = base if is_package else base[:-1]
    base = base[: len(base) - node.level + 1]
    return ".".join(base + ([node.module] if node.module else []))


def _imports(path: pathlib.Path, modules: set[str]) -> set[str]:
    """The package's modules that `path` imports anywhere in it (function bodies included)."""
    module = _module_name(path)
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            target = _resolve(module, path.name == "__init__.py", node)
            for alias in node.names:  # `from . import lie` imports a module
                sub = f"{target}.{alias.name}"
                found.add(sub if sub in modules else target)
    return {m for m in found if m in modules and m != module}


@pytest.fixture(scope="module")
def graph():
    paths = sorted(PACKAGE.rglob("*.py"))
    modules = {_module_name(p) for p in paths}
    return {_module_name(p): _imports(p, modules) for p in paths}


def _layer(module: str) -> int:
    top = module.split(".")[1] if "." in module else "__init__"
    for rank, (_, names) in enumerate(LAYERS):
        if top in names:
            return rank
    raise AssertionError(f"{module} is in no layer of architecture §4.1: add it to LAYERS")


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import loops of `graph`: its strongly connected components of more than one node
    (Tarjan's algorithm), each sorted."""
    index, low, stack, on_stack, cycles = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    return cycles


def _folder_graphs(graph: dict[str, set[str]]) -> dict[str, dict[str, set[str]]]:
    """For each folder (package) of the module graph, the graph of its entries: each module
    directly in it, and each subfolder as one node (importing any module of a subfolder runs
    the subfolder's `__init__`, so a subfolder is imported as a whole). An entry imports
    another where a module inside the one imports a module inside the other. The folder's
    own `__init__` is no entry: it imports its entries to gather them.

    A loop between the entries of a folder is a loop between folders even where the modules
    form none: `_systems/_mujoco_state.py` importing `_state.py`, which imports
    `_systems/_validation.py`, is the loop `_systems` -> `_state` -> `_systems`.
    """
    folders = {m.rsplit(".", 1)[0] for m in graph if "." in m}

    def entry(folder, module):
        head = module[len(folder) + 1 :].split(".")[0]
        return f"{folder}.{head}"

    out = {}
    for folder in sorted(folders):
        inside = [m for m in graph if m.startswith(folder + ".")]
        entries = {entry(folder, m): set() for m in inside}
        for a in inside:
            for b in graph[a]:
                if b.startswith(folder + ".") and entry(folder, a) != entry(folder, b):
                    entries[entry(folder, a)].add(entry(folder, b))
        out[folder] = entries
    return out


def _folder_loops(graph: dict[str, set[str]]) -> list[str]:
    """Each loop between a folder's entries, with the module imports that close it."""

    def inside(module, e):
        return module == e or module.startswith(e + ".")

    loops = []
    for folder, entries in _folder_graphs(graph).items():
        for loop in _cycles(entries):
            imports = sorted(
                f"{a} imports {b}"
                for a, targets in graph.items()
                for b in targets
                for ea in loop
                for eb in loop
                if ea != eb and inside(a, ea) and inside(b, eb)
            )
            loops.append(f"in {folder}: {' <-> '.join(loop)} ({'; '.join(imports)})")
    return loops


def test_no_import_cycles(graph):
    """No loop between modules: each strongly connected component is a single module."""
    cycles = _cycles(graph)
    assert not cycles, cycles


def test_no_import_cycles_between_folders(graph):
    """No loop between folders (`_folder_graphs`): every folder's entries import one way,
    so importing any module of a subfolder never comes back to the module importing it."""
    loops = _folder_loops(graph)
    assert not loops, loops


def test_a_loop_through_a_folder_is_found():
    """The loop that `_validation.py` ended (`State` used a check in `_systems`, whose
    `_mujoco_state.py` imports `State`): no module loop, one folder loop."""
    graph = {
        "bundledyn": {"bundledyn._state", "bundledyn._systems"},
        "bundledyn._state": {"bundledyn._systems._validation"},
        "bundledyn._systems": {"bundledyn._systems._mujoco_state"},
        "bundledyn._systems._mujoco_state": {"bundledyn._state"},
        "bundledyn._systems._validation": set(),
    }
    assert not _cycles(graph)
    assert _folder_loops(graph) == [
        "in bundledyn: bundledyn._state <-> bundledyn._systems "
        "(bundledyn._state imports bundledyn._systems._validation; "
        "bundledyn._systems._mujoco_state imports bundledyn._state)"
    ]


def test_no_import_from_a_higher_layer(graph):
    upward = [
        f"{a} ({LAYERS[_layer(a)][0]}) imports {b} ({LAYERS[_layer(b)][0]})"
        for a, targets in graph.items()
        for b in targets
        if _layer(b) > _layer(a)
    ]
    assert not upward, upward


def test_the_walker_sees_lazy_and_relative_imports(graph):
    """The checks above would pass vacuously if the walker missed imports."""
    assert "bundledyn._term" in graph["bundledyn._solver._chart"]
    assert "bundledyn.lie" in graph["bundledyn._systems._multibody"]
    assert "bundledyn" in graph["bundledyn._cli"]  # imported inside its functions
    assert "bundledyn._scene" in graph["bundledyn._term"]


@pytest.mark.slow  # half a minute of type checking, not of the package's behaviour
def test_pyright_passes():
    """pyright in standard mode (`[tool.pyright]` in pyproject.toml) on the package."""
    result = subprocess.run(
        ["pyright", "--outputjson"], cwd=PACKAGE.parent, capture_output=True, text=True, timeout=600
    )
    report = json.loads(result.stdout)
    messages = [
        f"{d['file']}:{d['range']['start']['line'] + 1}: {d['message']}"
        for d in report["generalDiagnostics"]
    ]
    assert report["summary"]["errorCount"] == 0, messages[:20]
    assert report["summary"]["warningCount"] == 0, messages[:20]
