"""The report's Table 2.1 study: hidden layers × loss × training-set size, one command.

All runs share one held-out test set drawn from the dataset; the training sets are nested
(the 6 k rows are part of the 60 k rows, ...), so that sizes differ only by the added rows.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ..data import Dataset
from ..data.sampling import sample_split
from ..errors import InputError
from ..params import Params
from .evaluation import evaluate
from .torch_support import require_torch
from .training import TrainConfig, train

DEPTHS = (3, 5, 7, 9, 11, 13, 15, 17)
SIZES = (6_000, 60_000, 600_000)
LOSSES = ("mae", "mse")


def run_sweep(ds: Dataset, base: TrainConfig, depths: Sequence[int] = DEPTHS,
              losses: Sequence[str] = LOSSES, sizes: Sequence[int] = SIZES, n_test: int = 100_000,
              seed: int = 0, progress: Callable[[float], None] | None = None) -> list[dict]:
    """One row per (size, depth, loss) with the test metrics of every output."""
    if not depths or not losses or not sizes:
        raise InputError("the sweep needs at least one depth, loss and size")
    require_torch()  # before reading the data
    sizes = sorted(sizes)
    train_rows, test_rows = sample_split(ds, sizes[-1], n_test, "random", seed)
    test = ds.read(rows=test_rows)
    pool = np.random.default_rng(seed).permutation(train_rows)
    params = Params.from_dict(ds.manifest["params"])
    out, runs, done = [], len(sizes) * len(depths) * len(losses), 0
    for size in sizes:
        cols = ds.read(rows=np.sort(pool[:size]))
        for depth in depths:
            for loss in losses:
                cfg = replace(base, depth=depth, loss=loss)
                s, hist = train(cols, params, cfg)
                metrics = evaluate(s, test, "dataset 2 test")
                row = {"train_rows": size, "depth": depth, "loss": loss, "width": cfg.width,
                       "activation": cfg.activation, "formulation": cfg.formulation,
                       "epochs": len(hist), "seconds": s.meta["seconds"]}
                for m in metrics:
                    key = m["output"]
                    row[f"r2_{key}"], row[f"mae_{key}"], row[f"max_abs_{key}"] = m["r2"], m["mae"], m["max_abs"]
                out.append(row)
                done += 1
                if progress is not None:
                    progress(done / runs)
    return out


def plot_sweep(rows: list[dict], path: Path) -> None:
    """R² of the angle and the forces against the number of hidden layers (Table 2.1)."""
    outputs = ("alpha_next", "N1_next", "N2_next", "T1_next")
    fig = Figure(figsize=(16, 4.2), layout="constrained")
    axes = fig.subplots(1, 4, sharex=True)
    for ax, o in zip(axes, outputs):
        for size in sorted({r["train_rows"] for r in rows}):
            for loss, ls in (("mse", "-"), ("mae", "--")):
                sel = sorted((r for r in rows if r["train_rows"] == size and r["loss"] == loss),
                             key=lambda r: r["depth"])
                if sel:
                    ax.plot([r["depth"] for r in sel], [1 - r[f"r2_{o}"] for r in sel], ls,
                            marker="o", label=f"{size:,} rows, {loss.upper()}")
        ax.set_yscale("log")
        ax.set_xlabel("hidden layers")
        ax.set_ylabel(f"1 − R² of {o[:-5]}′ (test)")
    axes[0].legend(fontsize=8)
    fig.suptitle("Network depth, loss and training-set size (report Table 2.1)")
    fig.savefig(path, dpi=130)
