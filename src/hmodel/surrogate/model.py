"""A trained surrogate of the H-cell increment: formulation, scalers and an MLP.

Prediction runs the network on the saved weights. In float64 (``forward(X)``) the layers are
plain NumPy matrix products, faster than a framework call for the small MLPs of report §2.4,
in blocks whose activations stay in cache. ``forward(X, single=True)`` runs the layers in
float32, the precision the network was trained in (outputs within ~4e-7 of float64, measured),
through PyTorch's linear layers: for the meso networks of the DEM cells (64-96 wide, thousands
of cells per call) 0.74 against 0.87 ms (64x3) and 1.31 against 1.41 ms (96x3) per 2,304 rows
on one thread, against NumPy's float32 products (measured). The solver uses it for ``meso``
models only (see ``SurrogateSolver._network``). Networks with the strain increment among their
inputs need float64: the Newton iterations' finite-difference probes differentiate their
output, and float32 round-off made those tangents noise.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..errors import InputError
from .formulations import Formulation
from .scalers import Affine

ACTIVATIONS = ("tanh", "relu", "silu", "gelu", "elu")
#: Rows per block of the float64 forward pass: 512 x 128 activations stay in a core's L2 cache
#: (one block of 2304 rows ran 2x slower per row, measured in float32).
BLOCK_ROWS = 512


def _act_inplace(name: str, x: np.ndarray) -> None:
    """x = activation(x), in place (the pre-activations are not needed again)."""
    if name == "tanh":
        np.tanh(x, out=x)
    elif name == "relu":
        np.maximum(x, 0.0, out=x)
    elif name == "silu":  # x sigmoid(x) = x (1 + tanh(x/2))/2: no overflow (3x faster than expit)
        t = np.multiply(x, 0.5)
        np.tanh(t, out=t)
        t *= 0.5
        t += 0.5
        x *= t
    elif name == "gelu":  # PyTorch's default (erf) form
        from scipy.special import erf
        x *= 0.5 * (1.0 + erf(x * 0.7071067811865476))
    elif name == "elu":
        x[...] = np.where(x > 0, x, np.expm1(np.minimum(x, 0.0)))
    else:
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

    @cached_property
    def _torch_layers(self) -> list:
        """(W, b) per layer as float32 torch tensors, for :meth:`forward` with ``single``."""
        import torch
        return [(torch.from_numpy(np.ascontiguousarray(W, np.float32)),
                 torch.from_numpy(np.ascontiguousarray(b, np.float32))) for W, b in self.weights]

    def forward(self, X: np.ndarray, single: bool = False) -> np.ndarray:
        """Network targets Y (n, n_outputs) for inputs X (n, n_inputs) in physical units; the
        layers in float32 with ``single`` (see the module docstring)."""
        z = self.x_scaler.transform(np.asarray(X, float))
        out = self._forward32(z) if single else self._forward64(z)
        return self.y_scaler.inverse(out, out=out)

    def _forward32(self, z: np.ndarray) -> np.ndarray:
        import torch
        F = torch.nn.functional
        *hidden, last = self._torch_layers
        name = self.architecture.activation
        if name not in ACTIVATIONS:
            raise InputError(f"unknown activation {name!r} (known: {', '.join(ACTIVATIONS)})")
        act = {"tanh": torch.tanh_, "relu": torch.relu_, "silu": lambda h: F.silu(h, inplace=True),
               "gelu": F.gelu, "elu": lambda h: F.elu(h, inplace=True)}[name]  # gelu: erf form
        with torch.inference_mode():
            h = torch.from_numpy(z.astype(np.float32))
            for W, b in hidden:
                h = act(F.linear(h, W, b))
            return F.linear(h, *last).numpy().astype(float)

    def _forward64(self, z: np.ndarray) -> np.ndarray:
        """Every product is written into one of two block buffers: fresh arrays of this size
        are new pages from the OS each time (at 9,216 rows 0.62 against 0.95 us per row,
        measured)."""
        *hidden, (W_out, b_out) = [(W.T, b) for W, b in self.weights]
        out = np.empty((len(z), len(b_out)))
        width = max((W.shape[1] for W, _ in hidden), default=0)
        buffers = np.empty((2, min(BLOCK_ROWS, len(z)), width))
        for i in range(0, len(z), BLOCK_ROWS):
            h = z[i:i + BLOCK_ROWS]
            for k, (W, b) in enumerate(hidden):
                h = np.matmul(h, W, out=buffers[k % 2, :len(h), :W.shape[1]])
                h += b
                _act_inplace(self.architecture.activation, h)
            np.matmul(h, W_out, out=out[i:i + BLOCK_ROWS])
        out += b_out
        return out

    def predict(self, columns: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """State after the increment (alpha_next, N1_next, N2_next, T1_next) from database-style
        columns of the state before and the strain."""
        f = self.formulation
        return f.decode(columns, self.forward(f.inputs(columns)))
