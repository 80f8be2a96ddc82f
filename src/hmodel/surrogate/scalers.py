"""Normalizations of report §2.3, fitted with scikit-learn and kept as exact affine maps.

Every method is x' = (x − offset) / scale per column: min-max (``MinMaxScaler``), z-score
(``StandardScaler``), robust (``RobustScaler``: median and inter-quartile range), max-abs
(``MaxAbsScaler``) and unit-vector (each column divided by its Euclidean norm over the training
rows; column-wise, so that it can be inverted). Fitted on the training split only; the offset
and scale arrays are saved with the model (no pickled estimator).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from sklearn.preprocessing import MaxAbsScaler, MinMaxScaler, RobustScaler, StandardScaler

from ..errors import InputError

METHODS = ("minmax", "zscore", "robust", "maxabs", "unit")


@dataclass(frozen=True)
class Affine:
    """x' = (x - offset) / scale, column-wise."""

    method: str
    offset: np.ndarray
    scale: np.ndarray

    def transform(self, X: np.ndarray) -> np.ndarray:
        return (X - self.offset) / self.scale

    def inverse(self, Z: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Z * scale + offset; into ``out`` (which may be Z) when given."""
        out = np.multiply(Z, self.scale, out=out)
        out += self.offset
        return out


def fit_scaler(method: str, X: np.ndarray) -> Affine:
    """Fit ``method`` on the rows X (n, d)."""
    X = np.asarray(X, float)
    if method == "minmax":
        s = MinMaxScaler().fit(X)
        offset, scale = s.data_min_, s.data_range_
    elif method == "zscore":
        s = StandardScaler().fit(X)
        offset, scale = s.mean_, s.scale_
    elif method == "robust":
        s = RobustScaler().fit(X)
        offset, scale = s.center_, s.scale_
    elif method == "maxabs":
        s = MaxAbsScaler().fit(X)
        offset, scale = np.zeros(X.shape[1]), s.scale_
    elif method == "unit":
        offset, scale = np.zeros(X.shape[1]), np.linalg.norm(X, axis=0)
    else:
        raise InputError(f"unknown normalization {method!r} (known: {', '.join(METHODS)})")
    scale = np.where(np.asarray(scale) > 0, scale, 1.0)  # constant columns pass unchanged
    return Affine(method, np.asarray(offset, float).copy(), np.asarray(scale, float).copy())
