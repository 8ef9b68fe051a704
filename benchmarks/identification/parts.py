"""The identification benchmark in parts: one results file per data set
(`identification_parts/<case>.json`), run a few cases at a time, and merged into
`identification.{json,md}` once every part measured the same code.

The whole family takes hours on two cores (mujoco.sysid's 200 iterations on the larger
trees), more than one sitting. A part records the code it measured
(`provenance["code"]`, `_provenance.code_hash`: the tracked files of the package, the
benchmarks and `pyproject.toml`, results aside), so parts run from different commits merge
only where that code is the same, and a part of other code is run again, never mixed in.
"""

import json
import pathlib

from benchmarks._provenance import code_hash

FOLDER = "identification_parts"
# The settings every merged part must share: the numbers its fits are compared over.
SETTINGS = ("quick", "seeds", "levels", "sysid_iters", "devices", "sysid_threads")


def path(out: pathlib.Path, name: str) -> pathlib.Path:
    """Where case `name`'s part is kept in the results folder `out`."""
    return out / FOLDER / f"{name}.json"


def write(out: pathlib.Path, name: str, part: dict) -> None:
    """Keep case `name`'s `part` (a report of that case alone) in `out`'s parts folder, its
    `seconds` the case's."""
    file = path(out, name)
    file.parent.mkdir(parents=True, exist_ok=True)
    part = part | {"seconds": part["cases"][name]["seconds"]}
    file.write_text(json.dumps(part, indent=1, default=float) + "\n")
    print(f"wrote {file}", flush=True)


def current(out: pathlib.Path, name: str, settings: dict) -> bool:
    """Whether case `name` has a part of this checkout's code, clean, with `settings`."""
    file = path(out, name)
    if not file.exists():
        return False
    part = json.loads(file.read_text())
    same = all(part.get(key) == settings.get(key) for key in SETTINGS)
    return same and _measured(part) == code_hash()


def _measured(part):
    """The code hash a part measured, None if its tree differed from its commit."""
    provenance = part["provenance"]
    return None if provenance.get("dirty") else provenance.get("code")


def merged(out: pathlib.Path, order: list[str]) -> dict:
    """The report of every part in `out`'s parts folder, cases in `order` (then any other),
    or `SystemExit` naming the parts that measured other code or other settings.

    Its provenance and environment are the newest part's; `parts` lists each part's commit,
    date, load and seconds, and `seconds` is their sum."""
    files = sorted((out / FOLDER).glob("*.json"))
    if not files:
        raise SystemExit(f"no parts in {out / FOLDER}: run with --part first")
    parts = {file.stem: json.loads(file.read_text()) for file in files}
    code = code_hash()
    stale = sorted(name for name, part in parts.items() if _measured(part) != code)
    if stale:
        raise SystemExit(
            f"parts {stale} measured other code than this checkout's (or a changed tree): "
            "run them again with --part"
        )
    newest = max(parts.values(), key=lambda part: part["provenance"]["date"])
    differing = sorted(
        name
        for name, part in parts.items()
        if any(part.get(key) != newest.get(key) for key in SETTINGS)
    )
    if differing:
        raise SystemExit(f"parts {differing} were run with other settings ({SETTINGS})")
    names = [name for name in order if name in parts] + sorted(set(parts) - set(order))
    report = {key: value for key, value in newest.items() if key not in ("cases", "seconds")}
    report["cases"] = {name: parts[name]["cases"][name] for name in names}
    report["parts"] = [
        {
            "case": name,
            "commit": parts[name]["provenance"]["commit"],
            "date": parts[name]["provenance"]["date"],
            "loadavg": parts[name]["environment"]["loadavg"],
            "seconds": parts[name]["seconds"],
        }
        for name in names
    ]
    report["seconds"] = sum(parts[name]["seconds"] for name in names)
    return report
