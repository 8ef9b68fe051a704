"""Where a benchmark writes its results: `benchmarks/results/` for a full run, never for a
quick one (a temporary folder unless `--out` says where)."""

import argparse
import json
import pathlib
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"


def parser(description, quick):
    """An argument parser with the options every benchmark has: `--quick` (what `quick`
    says it runs), `--out` and `--report-only`."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument(
        "--quick",
        action="store_true",
        help=f"{quick}; writes to a temporary folder (or --out), never to benchmarks/results",
    )
    parser.add_argument(
        "--out", type=pathlib.Path, help="results folder (default benchmarks/results)"
    )
    parser.add_argument(
        "--report-only", action="store_true", help="redraw the report from the results JSON"
    )
    return parser


def stem(name, quick):
    """The results files' name without suffix: `name`, or `name_quick` for a quick run."""
    return f"{name}_quick" if quick else name


def folder(out, quick, name, report_only=False):
    """The folder a run reads and writes: `out` where given, else `RESULTS` for a full run
    and a new temporary folder for a quick one. A quick run never writes into `RESULTS`
    (the committed results), and redrawing a quick run's report needs `out`."""
    if out is None and not quick:
        return RESULTS
    if out is None and report_only:
        raise SystemExit("--report-only --quick redraws a quick run's files: pass its --out")
    if out is None:
        out = pathlib.Path(tempfile.mkdtemp(prefix=f"{name}_quick_"))
    elif quick and out.resolve() == RESULTS.resolve():
        raise SystemExit(f"--quick never writes into {RESULTS}: pass another --out")
    if quick:
        print(f"quick run: results go to {out}", flush=True)
    return out


def write(out, name, report, text):
    """`name.json` (the report) and `name.md` (its markdown `text`) in `out`."""
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{name}.json").write_text(json.dumps(report, indent=1, default=float) + "\n")
    (out / f"{name}.md").write_text(text)
    print(f"wrote {out / name}.{{json,md}}", flush=True)


def _no_figure(report, out):
    pass


def destination(args, name, markdown, draw=_no_figure):
    """`(out, stem)` where a run writes; `None` after redrawing `stem.md` (and, by
    `draw(report, out)`, its figures) from `stem.json` with `markdown` when
    `args.report_only` asks for only that."""
    out = folder(args.out, args.quick, name, args.report_only)
    name = stem(name, args.quick)
    if not args.report_only:
        return out, name
    report = json.loads((out / f"{name}.json").read_text())
    draw(report, out)
    (out / f"{name}.md").write_text(markdown(report))
    return None


def run(args, name, markdown, measure, ready=lambda: True, draw=_no_figure) -> int:
    """A benchmark's run from its parsed `args`: redraw `name.md` alone (`--report-only`),
    or, once `ready()` says the peers are there, `measure()` the report, `draw(report,
    out)` its figures (which may name them in the report), print its markdown and write
    both files. The exit status: 0, or 1 when not `ready()`."""
    where = destination(args, name, markdown, draw)
    if where is None:
        return 0
    if not ready():
        return 1
    out, stem_name = where
    report = measure()
    out.mkdir(parents=True, exist_ok=True)
    draw(report, out)
    text = markdown(report)
    print(text)
    write(out, stem_name, report, text)
    return 0
