"""Shared by the benchmark scripts: where a result comes from (:func:`provenance`, at the head of
every JSON file), the best wall time of repeated runs after a warm-up, and the table and JSON
record of measure/value/target rows.

The scripts are grouped by the documentation page they feed (``engine/``, ``surrogates/``,
``dem/``, ...) and run as modules from the repository's root, for instance
``python -m benchmarks.engine.engine``; each writes its JSON file beside itself.
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

#: The repository's root, and the folder of the documentation's figures.
ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "docs" / "figures"

#: Options that name what a script writes, not what it reads (never hashed as inputs).
OUTPUT_OPTIONS = frozenset({"out", "figure"})


def best_of(fn, repeat: int) -> float:
    """Best of ``repeat`` timed calls of ``fn`` after one untimed call (compilation, caches)."""
    fn()
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def best_in_turn(runs: dict, repeat: int) -> dict:
    """The best time of each of ``runs`` (name: a function of no argument), timed in turn
    ``4 * repeat`` times after one untimed call each, so that a load beside the run weighs on
    all alike: {name: seconds}."""
    best = {name: best_of(run, 1) for name, run in runs.items()}
    for _ in range(4 * repeat):
        for name, run in runs.items():
            best[name] = min(best[name], best_of(run, 1))
    return best


def command(script: str) -> str:
    """The command line that runs ``script`` (its ``__file__``) with this process's arguments,
    as a module from the repository's root: ``python -m benchmarks.GROUP.NAME ARGS``."""
    module = Path(script).resolve().relative_to(ROOT).with_suffix("")
    return " ".join(["python", "-m", ".".join(module.parts), *sys.argv[1:]])


def _jsonable(value):
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return str(value)


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def input_files(options: dict) -> dict:
    """The files named by ``options`` (a value, or one member of a ``+``-joined ensemble), other
    than the outputs, with the SHA-256 of their contents: which model or data a run read."""
    found = {}
    for key, value in options.items():
        if key in OUTPUT_OPTIONS:
            continue
        for v in value if isinstance(value, list) else [value]:
            if not isinstance(v, str):
                continue
            for part in v.split("+"):
                path = Path(part)
                if part and path.is_file():
                    found[part] = _sha256(path)
    return found


def _commit() -> str | None:
    try:
        out = subprocess.run(["git", "describe", "--always", "--dirty", "--abbrev=12"], cwd=ROOT, check=False,
                             capture_output=True, text=True, timeout=20)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() or None


def provenance(script: str, args: argparse.Namespace | dict) -> dict:
    """Where a result comes from, for the head of every benchmark's JSON: the date, the command
    line that ran ``script`` (its ``__file__``), every option it ran with (``args``, defaults
    included), the files among them with their SHA-256, the commit, hmodel and Python versions,
    machine and CPUs."""
    from hmodel import __version__

    options = _jsonable(vars(args) if isinstance(args, argparse.Namespace) else dict(args))
    return {
        "date": datetime.date.today().isoformat(),
        "command": command(script), "options": options, "input_files": input_files(options),
        "commit": _commit(), "hmodel": __version__, "python": platform.python_version(),
        "machine": platform.machine(), "processor": platform.processor(), "cpus": os.cpu_count(),
    }


def record(script: str, args: argparse.Namespace | dict, repeat: int, rows, **extra) -> dict:
    """The JSON record of one run of ``script``: its :func:`provenance`, ``repeat``, the
    ``extra`` fields, then ``rows`` ((measure, value, target) triples) as ``results``."""
    return {**provenance(script, args), "repeat": repeat, **extra,
            "results": [{"measure": n, "value": v, "target": t} for n, v, t in rows]}


def write_table(rows, out: Path, rec: dict, value_width: int = 10) -> None:
    """Print ``rows`` ((measure, value, target) triples) as a table and write ``rec`` (see
    ``record``) to ``out`` as JSON."""
    width = max(len(r[0]) for r in rows)
    print(f"{'measure':<{width}}  {'value':>{value_width}}  target")
    for name, value, target in rows:
        print(f"{name:<{width}}  {value:>{value_width}.4g}  {target}")
    out.write_text(json.dumps(rec, indent=2) + "\n")
    print(f"written {out}")
