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


#: The outputs of a 3D (bi-hexagon) row compared by :func:`evaluate_bihex`: both hexagons'.
OUTPUTS_3D = ("alpha_next", "N1_next", "N2_next", "T1_next",
              "alpha_b_next", "N1_b_next", "N2_b_next", "T1_b_next")
#: The bi-hexagon's meso-stress components (V σ in the cell frame, N m) of :func:`evaluate_bihex`.
MESO_3D = ("Vs_nn_next", "Vs_t1t1_next", "Vs_t2t2_next")


def bihex_rows(cols: dict[str, np.ndarray], params) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The bi-hexagon states before and after (n, 16) and length increments (n, 3) of 3D
    dataset rows (:data:`hmodel.data.schema.COLUMNS_3D`): δl_k = −l_k0 δε_k on the initial
    lengths of each row's α0 (l30 = l20)."""
    from ..cell.bihex import BIHEX_FIELDS
    from ..cell.state import initial_lengths

    names = BIHEX_FIELDS  # the dataset's column names are the state's field names
    before = np.column_stack([cols[n] for n in names])
    after = np.column_stack([cols[f"{n}_next"] for n in names])
    l10, l20 = initial_lengths(params.radius, np.asarray(cols["alpha0"], float))
    dl = -np.column_stack([l10 * cols["deps1"], l20 * cols["deps2"], l20 * cols["deps3"]])
    return before, after, dl


def evaluate_bihex(solver, cols: dict[str, np.ndarray], params, label: str, substeps: int = 1) -> list[dict]:
    """The learned 3D cell on 3D dataset rows: ``BiHexSolver(hexagon=solver)`` (``solver`` a 2D
    H-cell solver, e.g. a :class:`~hmodel.surrogate.solver.SurrogateSolver`) steps each row's
    bi-hexagon by its increment in ``substeps`` equal sub-steps (as the rows were made), and its
    next state (both hexagons' α′, N1′, N2′, T1′: the state after and the increments, as
    :func:`evaluate`) and meso-stress (V σ_nn, V σ_t1t1, V σ_t2t2 of the next state, N m) are
    compared with the rows' closed-form ones. Metric rows as :func:`evaluate`."""
    from ..cell import CellState
    from ..cell.bihex import BIHEX_FIELDS, BiHexSolver

    cell = BiHexSolver(hexagon=solver)
    before, after, dl = bihex_rows(cols, params)
    state = CellState(np.ascontiguousarray(before))
    for _ in range(substeps):
        state, _ = cell.step(params, state, *(dl / substeps).T)
    pred = state.values
    idx = [BIHEX_FIELDS.index(o[:-5]) for o in OUTPUTS_3D]
    rows = metrics_table(after[:, idx], pred[:, idx], OUTPUTS_3D, data=label, quantity="state after")
    rows += metrics_table(after[:, idx] - before[:, idx], pred[:, idx] - before[:, idx],
                          [f"d{k[:-5]}" for k in OUTPUTS_3D], data=label, quantity="increment")
    true_meso = cell.meso(params, CellState(np.ascontiguousarray(after)))[0][:, :3]
    pred_meso = cell.meso(params, CellState(np.ascontiguousarray(pred)))[0][:, :3]
    rows += metrics_table(true_meso, pred_meso, MESO_3D, data=label, quantity="meso-stress")
    return rows
