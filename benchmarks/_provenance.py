"""What produced a set of results: the code (bundledyn's version, the git commit and
whether the tree differed from it), when, on what machine, with which packages.

Every results JSON carries `provenance()` under "provenance" and `environment(...)` under
"environment"; every results markdown opens with `_report.provenance_lines`.
"""

import datetime
import hashlib
import importlib.metadata as md
import os
import pathlib
import platform
import subprocess

from benchmarks._output import ROOT

# What a result depends on: a change here (but not in the results) makes a run "dirty".
CODE = ("bundledyn", "benchmarks", "pyproject.toml", ":(exclude)benchmarks/results")


def _git(*args):
    try:
        done = subprocess.run(
            ["git", *args], cwd=ROOT, capture_output=True, text=True, check=True, timeout=60
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip()


def _version(package):
    try:
        return md.version(package)
    except md.PackageNotFoundError:
        return None


def now():
    return datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")


def machine():
    """The CPU's model name and the cores this process may run on."""
    cpu = platform.processor() or platform.machine()
    try:
        lines = pathlib.Path("/proc/cpuinfo").read_text().splitlines()
        cpu = next(line.split(":", 1)[1].strip() for line in lines if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    cores = len(os.sched_getaffinity(0))
    return f"{cpu}, {cores} core{'' if cores == 1 else 's'}"


def code_hash():
    """A SHA-1 of the committed code (`CODE`'s files at `HEAD`, by their blob hashes): equal
    between two commits exactly where neither the package, the benchmarks nor
    pyproject.toml changed; None outside a checkout."""
    listing = _git("ls-tree", "-r", "HEAD", "--", *(path for path in CODE if ":" not in path))
    if listing is None:
        return None
    excluded = tuple(f"\t{path.split(')', 1)[1]}/" for path in CODE if path.startswith(":("))
    kept = [line for line in listing.splitlines() if not any(e in line for e in excluded)]
    return hashlib.sha1("\n".join(kept).encode()).hexdigest()


def provenance():
    """`{"bundledyn", "commit", "code", "dirty", "date", "machine"}`: bundledyn's version,
    `git rev-parse HEAD` (None outside a checkout), `code_hash()`, whether tracked files
    of the code differ from that commit (`CODE`: the package, the benchmarks,
    pyproject.toml), and when and where."""
    commit = _git("rev-parse", "HEAD")
    changes = _git("status", "--porcelain", "--untracked-files=no", "--", *CODE)
    return {
        "bundledyn": _version("bundledyn"),
        "commit": commit,
        "code": code_hash(),
        "dirty": None if commit is None or changes is None else bool(changes),
        "date": now(),
        "machine": machine(),
    }


def environment(packages):
    """The run's surroundings: date, machine, load average, Python, `XLA_FLAGS` and the
    versions of `packages` (None where not installed)."""
    return {
        "date": now(),
        "machine": machine(),
        "loadavg": os.getloadavg(),
        "python": platform.python_version(),
        "xla_flags": os.environ.get("XLA_FLAGS", ""),
        "versions": {package: _version(package) for package in packages},
    }


def report_header(packages, quick, **fields):
    """What every results JSON opens with: `provenance`, `environment` (of `packages`),
    `quick`, then the run's own `fields`."""
    return {
        "provenance": provenance(),
        "environment": environment(packages),
        "quick": quick,
        **fields,
    }
