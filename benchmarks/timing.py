"""Shared by the benchmark scripts: the best wall time of repeated runs after a warm-up, and the
table and JSON record of measure/value/target rows."""

from __future__ import annotations

import datetime
import json
import os
import platform
import sys
import time
from pathlib import Path


def best_of(fn, repeat: int) -> float:
    """Best of ``repeat`` timed calls of ``fn`` after one untimed call (compilation, caches)."""
    fn()
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def provenance(script: str) -> dict:
    """Where a result comes from, for the head of every benchmark's JSON: the date, the command
    line that ran ``script`` (its ``__file__``), hmodel and Python versions, machine, CPUs."""
    from hmodel import __version__

    return {
        "date": datetime.date.today().isoformat(),
        "command": " ".join(["python", f"benchmarks/{Path(script).name}", *sys.argv[1:]]),
        "hmodel": __version__, "python": platform.python_version(), "machine": platform.machine(),
        "processor": platform.processor(), "cpus": os.cpu_count(),
    }


def record(script: str, repeat: int, rows, **extra) -> dict:
    """The JSON record of one run of ``script``: its :func:`provenance`, ``repeat``, the
    ``extra`` fields, then ``rows`` ((measure, value, target) triples) as ``results``."""
    return {**provenance(script), "repeat": repeat, **extra,
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
