"""The report's Table 2.1 study: hidden layers × loss × training-set size (and the §2.3
normalizations, and the input convention), one command.

All runs share one held-out test set drawn from the dataset; the training sets are nested
(the 6 k rows are part of the 60 k rows, ...), so that sizes differ only by the added rows.
Each run is also scored as the report scores its Model 1 (§2.5, the text of its Fig. 2.7): R²,
MAE and RMSE of the angle and of the three forces pooled, on the held-out Dataset 2 rows and on
any other test rows given (the report's Dataset 1).

The report's published code feeds the forces *after* the increment to the network (three of
its four answers); ``inputs=("after",)`` trains that convention, so that the size of the leak
is measured beside the corrected one (``before``, the state before the increment).
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
from ..surrogate.evaluation import evaluate, truth_and_prediction
from ..surrogate.metrics import pooled_metrics
from ..surrogate.torch_support import require_torch
from ..surrogate.training import TrainConfig, train

DEPTHS = (3, 5, 7, 9, 11, 13, 15, 17)
SIZES = (6_000, 60_000, 600_000)
LOSSES = ("mae", "mse")
#: Input conventions: ``before`` (the forces before the increment, as the model runs) and
#: ``after`` (the report's published code, forces after the increment: the answer leak).
INPUTS = {"before": "report", "after": "report-leak"}
#: What makes a sweep row (a finished run is recognized by these on resume).
KEYS = ("inputs", "normalization", "train_rows", "depth", "loss")


def run_sweep(ds: Dataset, base: TrainConfig, depths: Sequence[int] = DEPTHS,
              losses: Sequence[str] = LOSSES, sizes: Sequence[int] = SIZES, n_test: int = 100_000,
              seed: int = 0, progress: Callable[[float], None] | None = None,
              normalizations: Sequence[str] | None = None, inputs: Sequence[str] = ("before",),
              tests: dict[str, dict[str, np.ndarray]] | None = None, done: Sequence[dict] = (),
              on_row: Callable[[dict], None] | None = None) -> list[dict]:
    """One row per (inputs, normalization, size, depth, loss) with the test metrics.

    Every row has the metrics of every output on the held-out Dataset 2 rows (``r2_alpha_next``,
    ...) and, for those and for each of ``tests`` (label -> columns, e.g. Dataset 1 rows), the
    report's pooled summary (:func:`~hmodel.surrogate.metrics.pooled_metrics`) under
    ``LABEL_...`` (``d2_...`` for the held-out rows). ``inputs`` ``after`` trains the
    ``report-leak`` formulation (the base formulation must be ``report``). Rows of ``done``
    (an interrupted sweep's) are kept and their runs skipped; ``on_row`` sees each new row.
    """
    normalizations = list(normalizations or [base.normalization])
    if not depths or not losses or not sizes or not normalizations or not inputs:
        raise InputError("the sweep needs at least one depth, loss, size, normalization and input convention")
    for name in inputs:
        if name not in INPUTS:
            raise InputError(f"unknown input convention {name!r} (known: {', '.join(INPUTS)})")
    if "after" in inputs and base.formulation != "report":
        raise InputError("the published input convention (--inputs after) is the report formulation's; "
                         f"this sweep trains {base.formulation!r}")
    for name in normalizations:
        replace(base, normalization=name)  # unknown names fail before any training
    require_torch()  # before reading the data
    sizes = sorted(sizes)
    train_rows, test_rows = sample_split(ds, sizes[-1], n_test, "random", seed)
    tests = {"d2": ds.read(rows=test_rows), **(tests or {})}
    pool = np.random.default_rng(seed).permutation(train_rows)
    params = Params.from_dict(ds.manifest["params"])
    finished = {tuple(r[k] for k in KEYS): r for r in done}
    plan = [(i, z, size, depth, loss) for i in inputs for z in normalizations for size in sizes
            for depth in depths for loss in losses]
    out, cols, cols_size = [], None, None
    for n, key in enumerate(plan):
        if key in finished:
            out.append(finished[key])
        else:
            convention, z, size, depth, loss = key
            if cols_size != size:
                cols, cols_size = ds.read(rows=np.sort(pool[:size])), size
            formulation = INPUTS[convention] if base.formulation == "report" else base.formulation
            cfg = replace(base, depth=depth, loss=loss, normalization=z, formulation=formulation)
            s, hist = train(cols, params, cfg)
            row = dict(zip(KEYS, key)) | {"width": cfg.width, "activation": cfg.activation,
                                          "formulation": cfg.formulation, "epochs": len(hist),
                                          "seconds": s.meta["seconds"]}
            for m in evaluate(s, tests["d2"], "dataset 2 test"):
                if m["quantity"] == "state after":
                    key_ = m["output"]
                    row[f"r2_{key_}"], row[f"mae_{key_}"], row[f"max_abs_{key_}"] = m["r2"], m["mae"], m["max_abs"]
            for label, test in tests.items():
                y, p, _ = truth_and_prediction(s, test)
                row |= {f"{label}_{k}": v for k, v in pooled_metrics(y[:, :4], p[:, :4]).items()}
            out.append(row)
            if on_row is not None:
                on_row(row)
        if progress is not None:
            progress((n + 1) / len(plan))
    return out


#: The report's Fig. 2.7 (Model 1: 3 layers, 60 k rows of Dataset 2; (a) MAE loss, (b) MSE loss),
#: its printout's numbers by (loss, test set: d1 Dataset 1, d2 Dataset 2).
REPORT_FIG_2_7 = {
    ("mae", "d1"): {"r2_force": 0.9936103, "r2_angle": 0.9978329, "rmse_force": 2053983.4027934917,
                    "rmse_angle": 0.012878974260744575, "mae_force": 1027287.5057290787,
                    "mae_angle": 0.008618506962517676, "max_angle": 1.5815281059447595},
    ("mae", "d2"): {"r2_force": 0.9982584, "r2_angle": 0.99747574, "rmse_force": 1099740.6071886998,
                    "rmse_angle": 0.013810898698387737, "mae_force": 269311.5010334855,
                    "mae_angle": 0.0025588723417527006, "max_angle": 1.5631415415492529},
    ("mse", "d1"): {"r2_force": 0.99906445, "r2_angle": 0.99820596, "rmse_force": 785949.4258878548,
                    "rmse_angle": 0.011717967977173588, "mae_force": 547470.3972178464,
                    "mae_angle": 0.008653581617502928, "max_angle": 1.5899907085333709},
    ("mse", "d2"): {"r2_force": 0.9996026, "r2_angle": 0.99910367, "rmse_force": 525325.7164393435,
                    "rmse_angle": 0.008229814778000335, "mae_force": 364731.42883928766,
                    "mae_angle": 0.004217218558574834, "max_angle": 2.054645643857},
}


def beside_report(rows: list[dict]) -> list[dict]:
    """The report's Fig. 2.7 numbers beside ours: one record per (loss, test set, metric) with
    the report's value and those of our Model 1 (3 layers, 60 k rows) in both input
    conventions, where the sweep ``rows`` have them (missing: NaN)."""
    ours = {(r["inputs"], r["loss"]): r for r in rows if int(r["depth"]) == 3 and int(r["train_rows"]) == 60_000}
    out = []
    for (loss, test), theirs in REPORT_FIG_2_7.items():
        for m, value in theirs.items():
            rec = {"loss": loss.upper(), "test": {"d1": "Dataset 1", "d2": "Dataset 2"}[test], "metric": m,
                   "report": value}
            for inputs, key in (("before", "ours (forces before)"), ("after", "ours (forces after, as published)")):
                rec[key] = float(ours[(inputs, loss)].get(f"{test}_{m}", np.nan)) if (inputs, loss) in ours else np.nan
            out.append(rec)
    return out


def plot_sweep(rows: list[dict], path: Path) -> None:
    """R² of the angle and the forces against the number of hidden layers (Table 2.1)."""
    outputs = ("alpha_next", "N1_next", "N2_next", "T1_next")
    fig = Figure(figsize=(16, 4.2), layout="constrained")
    axes = fig.subplots(1, 4, sharex=True)
    conventions = sorted({r.get("inputs", "before") for r in rows})
    scalings = sorted({r.get("normalization", "") for r in rows})
    for ax, o in zip(axes, outputs):
        for size in sorted({r["train_rows"] for r in rows}):
            for loss, ls in (("mse", "-"), ("mae", "--")):
                for inputs in conventions:
                    for z in scalings:
                        sel = sorted((r for r in rows if r["train_rows"] == size and r["loss"] == loss
                                      and r.get("inputs", "before") == inputs and r.get("normalization", "") == z),
                                     key=lambda r: r["depth"])
                        if sel:
                            tag = (f", forces {inputs}" if len(conventions) > 1 else "") + (
                                f", {z}" if len(scalings) > 1 else "")
                            ax.plot([r["depth"] for r in sel], [1 - r[f"r2_{o}"] for r in sel], ls,
                                    marker="o" if inputs == "before" else "x",
                                    label=f"{size:,} rows, {loss.upper()}{tag}")
        ax.set_yscale("log")
        ax.set_xlabel("hidden layers")
        ax.set_ylabel(f"1 − R² of {o[:-5]}′ (test)")
    axes[0].legend(fontsize=8)
    fig.suptitle("Network depth, loss and training-set size (report Table 2.1)")
    fig.savefig(path, dpi=130)
