"""Accuracy of a surrogate (report §2.5): MAE, RMSE, R² and maximum absolute error per output."""

from __future__ import annotations

import numpy as np

METRICS = ("mae", "rmse", "r2", "max_abs")


def regression_metrics(y_true: np.ndarray, y_pred: np.ndarray) -> dict[str, np.ndarray]:
    """Per-column metrics of (n, k) arrays; R² = 1 − SSE/SST (as ``sklearn.metrics.r2_score``
    with ``multioutput="raw_values"``; 1 for a constant column predicted exactly, else 0)."""
    y_true = np.asarray(y_true, float).reshape(len(y_true), -1)
    y_pred = np.asarray(y_pred, float).reshape(len(y_pred), -1)
    err = y_pred - y_true
    sse = np.sum(err ** 2, axis=0)
    sst = np.sum((y_true - y_true.mean(axis=0)) ** 2, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        r2 = np.where(sst > 0, 1.0 - sse / np.where(sst > 0, sst, 1.0), np.where(sse == 0, 1.0, 0.0))
    return {"mae": np.mean(np.abs(err), axis=0), "rmse": np.sqrt(np.mean(err ** 2, axis=0)),
            "r2": r2, "max_abs": np.max(np.abs(err), axis=0)}


def metrics_table(y_true: np.ndarray, y_pred: np.ndarray, names, **labels) -> list[dict]:
    """One row per output: ``labels`` (e.g. dataset), output name and every metric."""
    m = regression_metrics(y_true, y_pred)
    return [{**labels, "output": name, **{k: float(m[k][j]) for k in METRICS}}
            for j, name in enumerate(names)]


def pooled_metrics(y_true: np.ndarray, y_pred: np.ndarray) -> dict[str, float]:
    """The report's §2.5 summary of (n, 4) arrays of (α′, N1′, N2′, T1′): the angle's R², MAE
    and RMSE, the forces' pooled over the three force outputs as the report's printout gives
    them (scikit-learn's defaults: R² averaged over the outputs, MAE and RMSE over all force
    values), and the largest predicted and true angle (the report's sign of a failed
    normalization: a predicted maximum far below the true one)."""
    m = regression_metrics(y_true, y_pred)
    err = np.asarray(y_pred, float)[:, 1:4] - np.asarray(y_true, float)[:, 1:4]
    return {"r2_angle": float(m["r2"][0]), "mae_angle": float(m["mae"][0]),
            "rmse_angle": float(m["rmse"][0]), "r2_force": float(np.mean(m["r2"][1:4])),
            "mae_force": float(np.mean(np.abs(err))), "rmse_force": float(np.sqrt(np.mean(err ** 2))),
            "max_angle": float(np.max(y_pred[:, 0])), "true_max_angle": float(np.max(y_true[:, 0]))}
