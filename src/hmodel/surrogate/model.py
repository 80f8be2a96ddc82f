"""A trained surrogate of the H-cell increment: formulation, scalers and an MLP, used from NumPy.

Prediction runs the network as plain NumPy matrix products (float64) on the saved weights:
for the small MLPs of report §2.4 this is faster than calling a framework per batch and keeps
inference free of PyTorch. Training (``hmodel.surrogate.training``) uses PyTorch.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from .formulations import Formulation
from .scalers import Affine

ACTIVATIONS = ("tanh", "relu", "silu", "gelu", "elu")


def _act(name: str, x: np.ndarray) -> np.ndarray:
    if name == "tanh":
        return np.tanh(x)
    if name == "relu":
        return np.maximum(x, 0.0)
    if name == "silu":  # x sigmoid(x) = x (1 + tanh(x/2))/2: no overflow, in place (3x faster than expit)
        t = np.multiply(x, 0.5)
        np.tanh(t, out=t)
        t *= 0.5
        t += 0.5
        t *= x
        return t
    if name == "gelu":  # PyTorch's default (erf) form
        from scipy.special import erf
        return 0.5 * x * (1.0 + erf(x / np.sqrt(2.0)))
    if name == "elu":
        return np.where(x > 0, x, np.expm1(np.minimum(x, 0.0)))
    raise InputError(f"unknown activation {name!r} (known: {', '.join(ACTIVATIONS)})")


@dataclass(frozen=True)
class Architecture:
    """MLP: ``depth`` hidden layers of ``width`` nodes with ``activation`` (report default: 8, tanh)."""

    width: int = 8
    depth: int = 3
    activation: str = "tanh"

    def __post_init__(self) -> None:
        if not (isinstance(self.width, int) and self.width >= 1):
            raise InputError(f"width must be a positive integer, got {self.width!r}")
        if not (isinstance(self.depth, int) and self.depth >= 1):
            raise InputError(f"depth must be a positive integer, got {self.depth!r}")
        if self.activation not in ACTIVATIONS:
            raise InputError(f"unknown activation {self.activation!r} (known: {', '.join(ACTIVATIONS)})")


@dataclass
class Surrogate:
    """Everything needed to predict: weights (W, b) per layer, scalers, formulation, metadata."""

    formulation: Formulation
    architecture: Architecture
    x_scaler: Affine
    y_scaler: Affine
    weights: list[tuple[np.ndarray, np.ndarray]]
    meta: dict = field(default_factory=dict)
    #: Range of every input over the training rows (the training domain), (2, n_inputs).
    input_range: np.ndarray | None = None

    def outside(self, X: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Rows of X (n, 8) outside the training domain by more than ``margin`` of each input's
        range (all False when the range is unknown)."""
        if self.input_range is None:
            return np.zeros(len(X), bool)
        lo, hi = self.input_range
        pad = margin * (hi - lo)
        return np.any((X < lo - pad) | (X > hi + pad), axis=1)

    def forward(self, X: np.ndarray) -> np.ndarray:
        """Network targets Y (n, 4) for inputs X (n, 8) in physical units."""
        z = self.x_scaler.transform(np.asarray(X, float))
        for W, b in self.weights[:-1]:
            z = _act(self.architecture.activation, z @ W.T + b)
        W, b = self.weights[-1]
        return self.y_scaler.inverse(z @ W.T + b)

    def predict(self, columns: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """State after the increment (alpha_next, N1_next, N2_next, T1_next) from database-style
        columns of the state before and the strain."""
        f = self.formulation
        return f.decode(columns, self.forward(f.inputs(columns)))
