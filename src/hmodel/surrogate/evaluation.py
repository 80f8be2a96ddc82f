"""Evaluation of a surrogate (report §2.5): metrics tables and parity plots (Figs. 2.4-2.6).

Metrics are given on the predicted state after the increment (α′, N1′, N2′, T1′) and on the
increments (α′ − α, N1′ − N1, ...), where a network cannot look good by copying its input.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .formulations import OUTPUTS  # noqa: E402
from .metrics import metrics_table  # noqa: E402
from .model import Surrogate  # noqa: E402

BEFORE = ("alpha", "N1", "N2", "T1")
UNITS = {"alpha_next": "rad", "N1_next": "N", "N2_next": "N", "T1_next": "N"}


def truth_and_prediction(s: Surrogate, cols: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    pred = s.predict(cols)
    return (np.column_stack([cols[k] for k in OUTPUTS]), np.column_stack([pred[k] for k in OUTPUTS]))


def evaluate(s: Surrogate, cols: dict[str, np.ndarray], label: str) -> list[dict]:
    """Metric rows for the state after and for the increments, labelled with ``label``."""
    y, p = truth_and_prediction(s, cols)
    before = np.column_stack([cols[k] for k in BEFORE])
    rows = metrics_table(y, p, OUTPUTS, data=label, quantity="state after")
    rows += metrics_table(y - before, p - before, [f"d{k[:-5]}" for k in OUTPUTS], data=label,
                          quantity="increment")
    return rows


def parity_plot(s: Surrogate, cols: dict[str, np.ndarray], path: Path, title: str,
                max_points: int = 100_000, seed: int = 0) -> None:
    """Predicted against true, per output: the state after (top) and the increments (bottom)."""
    y, p = truth_and_prediction(s, cols)
    before = np.column_stack([cols[k] for k in BEFORE])
    n = len(y)
    idx = np.arange(n) if n <= max_points else np.random.default_rng(seed).choice(n, max_points, replace=False)
    fig, axes = plt.subplots(2, 4, figsize=(15, 7.5), constrained_layout=True)
    for row, (yt, yp, what) in enumerate(((y, p, "after"), (y - before, p - before, "increment"))):
        m = metrics_table(yt, yp, OUTPUTS)
        for j, name in enumerate(OUTPUTS):
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
    plt.close(fig)
