"""Surrogate training speed and accuracy: 600 k rows of Dataset 2 on this machine's CPU.

Generates the report-scale Dataset 2 (or uses ``--data DIR``), draws 600 k training and 100 k
held-out test rows (random, seed 0), trains the configuration of the shipped model and the
report's (Model 1: 8 nodes, 3 tanh layers, min-max, MSE), and reports wall time, epochs and
MAE / RMSE / R² / max |error| on the test rows, for the state after and the increments.

Usage: ``python -m benchmarks.surrogates.surrogate [--data DIR] [--train N] [--minutes M]``; prints a
table and writes ``surrogate.json`` beside this script.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import tempfile
import time
from pathlib import Path

from benchmarks.timing import provenance
from hmodel import Params
from hmodel.data import Dataset, DatasetSpec, generate
from hmodel.data.sampling import sample_split
from hmodel.surrogate.evaluation import evaluate
from hmodel.surrogate.training import TrainConfig, train

SHIPPED = dict(formulation="increment", normalization="zscore", width=64, depth=4,
               activation="silu", batch_size=2048, lr=3e-3, epochs=2000, patience=30)
REPORT = dict(formulation="report", normalization="minmax", width=8, depth=3, activation="tanh",
              batch_size=1024, lr=3e-3, epochs=2000, patience=30)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path)
    ap.add_argument("--train", type=int, default=600_000)
    ap.add_argument("--test", type=int, default=100_000)
    ap.add_argument("--minutes", type=float, default=9.0)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("surrogate.json"))
    args = ap.parse_args()
    tmp = None
    if args.data is None:
        tmp = Path(tempfile.mkdtemp(prefix="hmodel-bench-"))
        ds = generate(DatasetSpec(kind=2), Params(), tmp / "d2", workers=os.cpu_count() or 1)
    else:
        ds = Dataset.open(args.data)
    try:
        tr, te = sample_split(ds, args.train, args.test, "random", seed=0)
        train_cols, test_cols = ds.read(rows=tr), ds.read(rows=te)
        results = []
        for name, cfg in (("shipped configuration", SHIPPED), ("report Model 1", REPORT)):
            t = time.perf_counter()
            s, hist = train(train_cols, Params.from_dict(ds.manifest["params"]),
                            TrainConfig(**cfg, max_minutes=args.minutes))
            seconds = time.perf_counter() - t
            results.append({"model": name, "config": cfg, "train_rows": args.train,
                            "seconds": seconds, "epochs": len(hist),
                            "metrics": evaluate(s, test_cols, "dataset 2 held-out")})
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    print(f"{'model':<22} {'quantity':<12} {'output':<11} {'R2':>10} {'MAE':>10} {'max|err|':>10}")
    for r in results:
        print(f"{r['model']} — {r['epochs']} epochs, {r['seconds']:.0f} s")
        for m in r["metrics"]:
            print(f"{'':<22} {m['quantity']:<12} {m['output']:<11} {m['r2']:>10.6f} {m['mae']:>10.3g} "
                  f"{m['max_abs']:>10.3g}")
    args.out.write_text(json.dumps({**provenance(__file__, args),
                                    "results": results}, indent=1) + "\n")
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
