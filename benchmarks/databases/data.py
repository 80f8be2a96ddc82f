"""Database speed: report-scale Dataset 2 (and Dataset 1), rows per second and peak memory.

Runs ``hmodel.data.generate`` with the default (report-scale) options into a temporary folder,
with 1 and 2 local worker processes, and measures the wall time, the rows per second, the
peak resident memory of the parent and of the worker processes (``ru_maxrss``), and the size
on disk. Also times drawing 60 k + 10 k rows by each sampling method from Dataset 2.

Usage: ``python -m benchmarks.databases.data [--quick] [--out PATH]`` (``--quick``: 1/10 of the directions).
Prints a table and writes ``data.json`` beside this script.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

_CHILD = """
import json, resource, sys, time
from hmodel import Params
from hmodel.data import DatasetSpec, generate
spec = DatasetSpec(**json.loads(sys.argv[1]))
t = time.perf_counter()
ds = generate(spec, Params(), sys.argv[2], workers=int(sys.argv[3]))
dt = time.perf_counter() - t
print(json.dumps({"rows": ds.n_rows, "seconds": dt,
                  "parent_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "workers_rss_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024}))
"""

_SAMPLE = """
import json, sys, time
from hmodel.data import Dataset
from hmodel.data.sampling import sample_split
ds = Dataset.open(sys.argv[1])
out = {}
for method in ("random", "grid", "lhs"):
    t = time.perf_counter()
    sample_split(ds, 60000, 10000, method, seed=0)
    out[method] = time.perf_counter() - t
print(json.dumps(out))
"""


def run(code: str, *args: str) -> dict:
    # A fresh interpreter per measurement, so that ru_maxrss is this run's peak only.
    res = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, check=True)
    return json.loads(res.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("data.json"))
    args = ap.parse_args()
    rows = []
    tmp = Path(tempfile.mkdtemp(prefix="hmodel-bench-"))
    try:
        for kind in (2, 1):
            spec = {"kind": kind, **({"n_directions": 10} if args.quick else {})}
            for workers in (1, 2):
                folder = tmp / f"d{kind}-w{workers}"
                r = run(_CHILD, json.dumps(spec), str(folder), str(workers))
                size = sum(p.stat().st_size for p in folder.iterdir()) / 2**20
                rows.append({"dataset": kind, "workers": workers, **r, "rows_per_s": r["rows"] / r["seconds"],
                             "disk_mb": size})
                if not (kind == 2 and workers == 2):
                    shutil.rmtree(folder)
        sampling = run(_SAMPLE, str(tmp / "d2-w2"))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"{'dataset':>7} {'workers':>7} {'rows':>12} {'time [s]':>9} {'rows/s':>11} "
          f"{'parent MB':>9} {'worker MB':>9} {'disk MB':>8}")
    for r in rows:
        print(f"{r['dataset']:>7} {r['workers']:>7} {r['rows']:>12,} {r['seconds']:>9.1f} "
              f"{r['rows_per_s']:>11,.0f} {r['parent_rss_mb']:>9.0f} {r['workers_rss_mb']:>9.0f} "
              f"{r['disk_mb']:>8.0f}")
    print("sampling 60k + 10k rows from Dataset 2 [s]: " +
          ", ".join(f"{m} {t:.1f}" for m, t in sampling.items()))
    record = {"python": platform.python_version(), "cpus": os.cpu_count(), "quick": args.quick,
              "generation": rows, "sampling_seconds": sampling,
              "target": "Dataset 2 at report scale in <= 300 s, peak memory <= 4 GB"}
    args.out.write_text(json.dumps(record, indent=2) + "\n")
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
