"""The report's Table 2.1 study at its scale, beside the report's own numbers.

Runs (or reads, when their folders are there) four ``hmodel surrogate sweep`` runs on a
report-scale Dataset 2 (13.3 million rows, the generator's defaults) with a report-scale
Dataset 1 (791,700 rows) as the second test set:

- the grid: 3, 5, ..., 17 tanh layers of 8 nodes × MAE and MSE × 6 k, 60 k and 600 k training
  rows (min-max normalization), once with the inputs as the model runs them (the forces before
  the increment) and once with the report's published convention (the forces after it);
- the normalizations: Model 1 (3 layers) on 60 k rows with each of the five of §2.3, both
  conventions.

Each run is capped at ``--max-minutes`` of training (early stopping with patience 20 within 200
epochs otherwise), on one thread. Prints the comparison with the report's Fig. 2.7 (Model 1,
60 k rows) and writes ``table21.json``.

Usage: ``python -m benchmarks.table21.table21 [--work DIR] [--jobs 2]``.
"""

from __future__ import annotations

import argparse
import csv
import os
import subprocess
from pathlib import Path

from benchmarks.timing import record, write_table
from hmodel.studies.sweep import beside_report

NORMALIZATIONS = "minmax,zscore,robust,maxabs,unit"


def sweeps(work: Path, max_minutes: float, jobs: int) -> dict[str, Path]:
    """The four sweep folders, run where missing (``jobs`` at a time, one thread each)."""
    d1, d2 = work / "d1", work / "d2"
    for kind, folder in (("1", d1), ("2", d2)):
        if not (folder / "manifest.json").is_file():
            subprocess.run(["hmodel", "data", "generate", kind, "--out", str(folder)], check=True)
    runs = {f"{what}-{inputs}": work / f"{what}-{inputs}" for what in ("grid", "norm")
            for inputs in ("before", "after")}
    common = ["--dataset1", str(d1), "--max-minutes", str(max_minutes), "--device", "cpu"]
    todo = []
    for name, out in runs.items():
        if (out / "sweep.csv").is_file():
            continue
        what, inputs = name.split("-")
        extra = ["--depths", "3", "--sizes", "60000", "--normalization", NORMALIZATIONS] if what == "norm" else []
        todo.append(["hmodel", "surrogate", "sweep", str(d2), "--out", str(out), "--inputs", inputs,
                     *common, *extra])
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    while todo:
        batch, todo = todo[:jobs], todo[jobs:]
        procs = [subprocess.Popen(cmd, env=env) for cmd in batch]
        if any(p.wait() for p in procs):
            raise SystemExit("a sweep failed")
    return runs


def read(path: Path) -> list[dict]:
    with open(path / "sweep.csv") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        for k, v in r.items():
            try:
                r[k] = int(v) if k in ("train_rows", "depth", "epochs") else float(v)
            except ValueError:
                pass
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", type=Path, required=True, help="folder of the four sweeps (read when there)")
    ap.add_argument("--max-minutes", type=float, default=3.0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("table21.json"))
    args = ap.parse_args()
    runs = {k: read(p) for k, p in sweeps(args.work, args.max_minutes, args.jobs).items()}
    grid = runs["grid-before"] + runs["grid-after"]
    fig27, rows = beside_report(grid), []
    for rec in fig27:
        if rec["metric"] in ("r2_force", "r2_angle", "mae_angle"):
            for key in ("ours (forces before)", "ours (forces after, as published)"):
                rows.append((f"Model 1, 60k, {rec['loss']}, {rec['test']}, {rec['metric']}: {key}",
                             rec[key], f"report {rec['report']:.6g}"))
    table = [{"inputs": r["inputs"], "rows": r["train_rows"], "layers": r["depth"], "loss": r["loss"].upper(),
              "R² angle (D2)": r["d2_r2_angle"], "R² force (D2)": r["d2_r2_force"],
              "MAE angle (D2) [rad]": r["d2_mae_angle"], "R² angle (D1)": r["d1_r2_angle"],
              "R² force (D1)": r["d1_r2_force"], "max angle (D2) [rad]": r["d2_max_angle"],
              "epochs": r["epochs"], "seconds": r["seconds"]} for r in grid]
    norms = [{"inputs": r["inputs"], "normalization": r["normalization"], "loss": r["loss"].upper(),
              "R² angle (D2)": r["d2_r2_angle"], "R² force (D2)": r["d2_r2_force"],
              "MAE angle (D2) [rad]": r["d2_mae_angle"], "max angle (D2) [rad]": r["d2_max_angle"],
              "true max angle (D2) [rad]": r["d2_true_max_angle"], "R² angle (D1)": r["d1_r2_angle"],
              "R² force (D1)": r["d1_r2_force"], "epochs": r["epochs"]}
             for r in runs["norm-before"] + runs["norm-after"]]
    write_table(rows, args.out, record(__file__, args, 1, rows, max_minutes=args.max_minutes,
                                       fig_2_7=fig27, table_2_1=table, normalizations=norms),
                value_width=12)


if __name__ == "__main__":
    main()
