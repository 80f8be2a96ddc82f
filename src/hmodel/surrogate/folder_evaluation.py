"""A model's metrics on data folders, as ``hmodel surrogate evaluate`` reports them: a sample
folder's test rows, rows of a dataset folder, or the learned 3D cell on a dataset of bi-hexagon
rows (:mod:`hmodel.surrogate.evaluation` computes the metrics and plots)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ..data import Dataset
from .evaluation import evaluate, evaluate_bihex, parity_plot
from .model import Surrogate
from .solver import SurrogateSolver
from .training_rows import read_rows


def evaluate_folder(s: Surrogate, folder: "str | Path", rows: int | None = 100_000, seed: int = 0
                    ) -> tuple[list[dict], Callable[[Path, str], None] | None]:
    """Metric rows of model ``s`` on a data folder, and the writer ``(path, model_name)`` of its
    parity plot. A sample folder gives its test rows; a dataset folder ``rows`` random rows of it
    (:func:`~hmodel.surrogate.training_rows.read_rows`); a dataset of bi-hexagon rows
    (``hmodel data generate --dim 3``) the learned 3D cell's metrics (:func:`evaluate_bihex`,
    ``rows`` random rows or all where fewer), and no parity plot (None)."""
    folder = Path(folder)
    if _dim(folder) == 3:
        return _evaluate_3d(s, folder, rows, seed), None
    cols, info = read_rows(folder, "test", rows, seed)
    label = f"{folder.name} (dataset {info['provenance']['kind']})"

    def parity(path: Path, model_name: str) -> None:
        parity_plot(s, cols, path, f"{model_name}: {label}, {len(cols['deps1']):,} rows")

    return evaluate(s, cols, label), parity


def _dim(folder: Path) -> int:
    """3 for a dataset folder of bi-hexagon rows (``hmodel data generate --dim 3``), else 2."""
    try:
        m = json.loads((folder / "manifest.json").read_text())
    except (OSError, ValueError):
        return 2
    return int((m.get("options") or {}).get("dim", 2)) if m.get("format") == "hmodel-cell-dataset" else 2


def _evaluate_3d(s: Surrogate, folder: Path, rows: int | None, seed: int) -> list[dict]:
    """Metric rows of the learned 3D cell of model ``s`` (``BiHexSolver(hexagon=SurrogateSolver(s))``)
    on ``rows`` random rows (all where fewer) of a 3D dataset, against its closed-form rows."""
    ds = Dataset.open(folder)
    pick = None
    if rows is not None and rows < ds.n_rows:
        pick = np.sort(np.random.default_rng(seed).choice(ds.n_rows, rows, replace=False))
    label = f"{folder.name} (3D dataset {ds.manifest['kind']})"
    return evaluate_bihex(SurrogateSolver(s), ds.read(rows=pick), ds.params, label, ds.spec.substeps)
