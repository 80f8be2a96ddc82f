"""Figures of a database: strain distributions (report Fig. 2.1) and removed rows (Fig. 2.2).

Large datasets are drawn from a seeded random subset of rows (``max_points``); the counts in
the titles are over the whole dataset.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from .filters import rule_columns, rule_masks
from .store import Dataset

_COLS = ["deps1", "deps2", "theta", "start_strain", "l1_next", "l2_next"]


def _subset(ds: Dataset, rules: Sequence[str], max_points: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    n = ds.n_rows
    rows = np.arange(n) if n <= max_points else np.sort(rng.choice(n, max_points, replace=False))
    cols = ds.read(list(dict.fromkeys(_COLS + rule_columns(rules))), rows=rows)
    removed = np.zeros(len(rows), bool)
    for m in rule_masks(cols, rules, float(ds.manifest["params"]["radius"])).values():
        removed |= m
    return cols, removed


def cumulative_strain(cols) -> tuple[np.ndarray, np.ndarray]:
    """Total cell strain after the row's increment: the path's strain plus the increment."""
    e1 = cols["start_strain"] * np.cos(cols["theta"]) + cols["deps1"]
    e2 = cols["start_strain"] * np.sin(cols["theta"]) + cols["deps2"]
    return e1, e2


def plot_strain_distribution(ds: Dataset, path: Path, max_points: int = 200_000) -> None:
    """Fig. 2.1: where the rows lie in the cell-strain plane (Dataset 1: total strains;
    Dataset 2: the increments, and the total strain they lead to)."""
    cols, _ = _subset(ds, (), max_points)
    kind = ds.manifest["kind"]
    fig = Figure(figsize=(10, 4.6), layout="constrained")
    axes = fig.subplots(1, 2)
    a = axes[0]
    hb = a.hexbin(100 * cols["deps1"], 100 * cols["deps2"], gridsize=60, mincnt=1, bins="log", cmap="viridis")
    fig.colorbar(hb, ax=a, label="rows (sampled)")
    a.set_xlabel(r"$\delta\varepsilon_1$ [%]")
    a.set_ylabel(r"$\delta\varepsilon_2$ [%]")
    a.set_title("(a) " + ("total cell strain, Dataset 1" if kind == 1 else "strain increments, Dataset 2"))
    a.set_aspect("equal")
    e1, e2 = cumulative_strain(cols)
    b = axes[1]
    hb = b.hexbin(100 * e1, 100 * e2, gridsize=60, mincnt=1, bins="log", cmap="viridis")
    fig.colorbar(hb, ax=b, label="rows (sampled)")
    b.set_xlabel(r"$\varepsilon_1$ after the row [%]")
    b.set_ylabel(r"$\varepsilon_2$ after the row [%]")
    b.set_title("(b) cumulative cell strain reached")
    b.set_aspect("equal")
    fig.suptitle(f"Dataset {kind}: {ds.n_rows:,} rows (compression positive)")
    fig.savefig(path, dpi=150)


def plot_removed(ds: Dataset, rules: Sequence[str], counts: dict[str, int], path: Path,
                 max_points: int = 200_000) -> None:
    """Fig. 2.2: rows removed by the cleaning rules in red, kept rows in blue."""
    cols, removed = _subset(ds, rules, max_points)
    r2 = 2 * float(ds.manifest["params"]["radius"])
    e1, e2 = cumulative_strain(cols)
    fig = Figure(figsize=(10, 4.6), layout="constrained")
    axes = fig.subplots(1, 2)
    panels = ((axes[0], 100 * e1, 100 * e2, r"$\varepsilon_1$ after the row [%]",
               r"$\varepsilon_2$ after the row [%]"),
              (axes[1], cols["l1_next"] / r2, cols["l2_next"] / r2, r"$l_1'/2r$", r"$l_2'/2r$"))
    for ax, x, y, xl, yl in panels:
        ax.scatter(x[~removed], y[~removed], s=1, c="tab:blue", alpha=0.3, lw=0, label="kept", rasterized=True)
        ax.scatter(x[removed], y[removed], s=1, c="red", alpha=0.5, lw=0, label="removed", rasterized=True)
        ax.set_xlabel(xl)
        ax.set_ylabel(yl)
    axes[1].axvline(1.0, color="k", lw=0.8, ls="--")
    axes[1].axhline(1.0, color="k", lw=0.8, ls="--")
    axes[0].legend(markerscale=10, loc="best")
    text = ", ".join(f"{r}: {counts.get(r, 0):,}" for r in rules) or "no rule"
    fig.suptitle(f"Dataset {ds.manifest['kind']}: {counts.get('total', 0):,} of {ds.n_rows:,} rows "
                 f"removed ({text})")
    fig.savefig(path, dpi=150)

