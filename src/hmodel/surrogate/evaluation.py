"""Evaluation of a surrogate (report §2.5): metrics tables and parity plots (Figs. 2.4-2.6).

Metrics are given on the predicted state after the increment (α′, N1′, N2′, T1′) and on the
increments (α′ − α, N1′ − N1, ...), where a network cannot look good by copying its input.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from .metrics import metrics_table
from .model import Surrogate

UNITS = {"alpha_next": "rad", "N1_next": "N", "N2_next": "N", "T1_next": "N", "Vs_nn_next": "N m",
         "Vs_tt_next": "N m", "Vs_nt_next": "N m"}


def outputs_of(s: Surrogate) -> tuple[str, ...]:
    """The predicted state columns (``*_next``): the four of the report, and the meso-stress
    of the ``meso`` formulation."""
    return s.formulation.outputs


def truth_and_prediction(s: Surrogate, cols: dict[str, np.ndarray]
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """True and predicted state after, and the state before, (n, outputs) each."""
    cols = s.formulation.augment(cols)
    pred = s.predict(cols)
    out = outputs_of(s)
    return tuple(np.column_stack([src[k] for k in out]) for src in (cols, pred)) + (
        np.column_stack([cols[k[:-5]] for k in out]),)


def evaluate(s: Surrogate, cols: dict[str, np.ndarray], label: str) -> list[dict]:
    """Metric rows for the state after and for the increments, labelled with ``label``."""
    y, p, before = truth_and_prediction(s, cols)
    out = outputs_of(s)
    rows = metrics_table(y, p, out, data=label, quantity="state after")
    rows += metrics_table(y - before, p - before, [f"d{k[:-5]}" for k in out], data=label,
                          quantity="increment")
    return rows


def parity_plot(s: Surrogate, cols: dict[str, np.ndarray], path: Path, title: str,
                max_points: int = 100_000, seed: int = 0) -> None:
    """Predicted against true, per output: the state after (top) and the increments (bottom)."""
    y, p, before = truth_and_prediction(s, cols)
    out = outputs_of(s)
    n = len(y)
    idx = np.arange(n) if n <= max_points else np.random.default_rng(seed).choice(n, max_points, replace=False)
    fig = Figure(figsize=(3.75 * len(out), 7.5), layout="constrained")
    axes = fig.subplots(2, len(out), squeeze=False)
    for row, (yt, yp, what) in enumerate(((y, p, "after"), (y - before, p - before, "increment"))):
        m = metrics_table(yt, yp, out)
        for j, name in enumerate(out):
            ax = axes[row, j]
            a, b = yt[idx, j], yp[idx, j]
            ax.scatter(a, b, s=1, alpha=0.3, lw=0, rasterized=True)
            lo, hi = float(min(a.min(), b.min())), float(max(a.max(), b.max()))
            ax.plot([lo, hi], [lo, hi], "k--", lw=0.8)
            sym = name[:-5] + "′" if what == "after" else "Δ" + name[:-5]
            ax.set_xlabel(f"true {sym} [{UNITS[name]}]")
            ax.set_ylabel(f"predicted {sym} [{UNITS[name]}]")
            ax.set_title(f"R² = {m[j]['r2']:.6f}, max |err| = {m[j]['max_abs']:.3g}", fontsize=9)
    fig.suptitle(title)
    fig.savefig(path, dpi=130)
