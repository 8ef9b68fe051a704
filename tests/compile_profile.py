"""A pytest plugin that says where each test file's time goes: JAX tracing, lowering, XLA
compiling (per program), and the rest (running, Python).

Run from the repository root, with `tests` importable as plugins are:

    PYTHONPATH=tests python -m pytest -q -p compile_profile [pytest's usual arguments]

Each worker writes `.pytest_cache/compile-profile/<worker>.json` (`COMPILE_PROFILE_DIR`
to put it elsewhere): per file, the seconds and counts of JAX's monitoring events and the wall time
of its tests; and each compiled program's file, name and seconds. `python
tests/compile_profile.py [DIR]` prints the files' totals, longest first, with their
longest-compiling programs.

The plugin is loaded before the conftest, and JAX reads its environment when first
imported: so it sets the conftest's compilation variables itself before it imports JAX,
or the profile would be of an optimised run with JAX's default cache.
"""

import collections
import json
import os
import pathlib
import sys
import time

os.environ.setdefault("JAX_DISABLE_MOST_OPTIMIZATIONS", "1")
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0")

import pytest  # noqa: E402
from jax import monitoring  # noqa: E402
from jax._src.interpreters import pxla  # noqa: E402

_EVENTS = {
    "/jax/core/compile/jaxpr_trace_duration": "trace",
    "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower",
    "/jax/core/compile/backend_compile_duration": "compile",
}
_files = collections.defaultdict(collections.Counter)
_programs = []
_here = {"file": "<collection>"}
_FOLDER = ".pytest_cache/compile-profile"


def _listen(event, duration, **_):
    if event in _EVENTS:
        _files[_here["file"]][_EVENTS[event]] += duration
        _files[_here["file"]][_EVENTS[event] + " count"] += 1


monitoring.register_event_duration_secs_listener(_listen)

# `_cached_compilation` is where a lowered program is compiled (or read from the cache); the
# monitoring event does not carry the program's name.
_compile = pxla._cached_compilation


def _named_compile(computation, name, *args, **kwargs):
    start = time.perf_counter()
    try:
        return _compile(computation, name, *args, **kwargs)
    finally:
        _programs.append((_here["file"], name, time.perf_counter() - start))


pxla._cached_compilation = _named_compile


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    # Where the test runs: under xdist, a worker (the controller only reports).
    _here["file"], start = item.path.name, time.perf_counter()
    yield
    _files[_here["file"]]["wall"] += time.perf_counter() - start


def pytest_sessionfinish(session):
    folder = pathlib.Path(os.environ.get("COMPILE_PROFILE_DIR", _FOLDER))
    folder.mkdir(parents=True, exist_ok=True)
    worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
    report = {"files": {k: dict(v) for k, v in _files.items()}, "programs": _programs}
    (folder / f"{worker}.json").write_text(json.dumps(report))


def summary(folder: pathlib.Path, longest: int = 3) -> str:
    """The workers' reports in `folder` added up: a line per file, longest first."""
    files = collections.defaultdict(collections.Counter)
    programs = collections.defaultdict(collections.Counter)
    for path in folder.glob("*.json"):
        report = json.loads(path.read_text())
        for name, counts in report["files"].items():
            files[name].update(counts)
        for file, program, seconds in report["programs"]:
            programs[file][program] += seconds
    total = collections.Counter()
    lines = []
    for name, c in sorted(files.items(), key=lambda item: -item[1]["wall"]):
        total.update(c)
        top = ", ".join(f"{p} {s:.0f}" for p, s in programs[name].most_common(longest))
        lines.append(
            f"{name:34} wall {c['wall']:6.1f}  compile {c['compile']:6.1f} "
            f"({c['compile count']:4.0f})  trace {c['trace']:5.1f}  lower {c['lower']:5.1f}  {top}"
        )
    rest = total["wall"] - total["compile"] - total["trace"] - total["lower"]
    lines.append(
        f"{'all':34} wall {total['wall']:6.1f}  compile {total['compile']:6.1f}  "
        f"trace {total['trace']:5.1f}  lower {total['lower']:5.1f}  rest {rest:6.1f}"
    )
    return "\n".join(lines)


if __name__ == "__main__":
    print(summary(pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else _FOLDER)))
