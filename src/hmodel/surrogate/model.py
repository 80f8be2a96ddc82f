"""A trained surrogate of the H-cell increment: formulation, scalers and an MLP, used from NumPy.

Prediction runs the network as plain NumPy matrix products on the saved weights: for the small
MLPs of report §2.4 this avoids a framework's per-call overhead, which dominates at these sizes,
and keeps inference free of PyTorch. Training (``hmodel.surrogate.training``) uses PyTorch.
(PyTorch's float32 linear layers were tried for inference and made whole ANN-REV runs slower,
though a single large batch ran faster; see the documentation's notes.) The rows
run in blocks whose activations stay in cache, on one BLAS thread: at these sizes a second
thread saves little, and where another program holds a core the threads of one product wait for
each other (:meth:`Surrogate.forward`); a large batch is split across the cores instead, one
block per task. ``forward(X, single=True)`` runs the layers in
float32, the precision the network was trained in (outputs within ~4e-7 of float64, at half the
memory traffic); the solver uses it for the formulations that ask for it, ``meso`` only
(``single_precision`` in :mod:`hmodel.surrogate.formulations.base`).
Networks with the strain increment among their inputs need float64: the Newton iterations'
finite-difference probes differentiate their output, and float32 round-off made those tangents
noise.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from numba import njit
from threadpoolctl import ThreadpoolController

from ..errors import InputError
from .formulations.base import Formulation
from .scalers import Affine

ACTIVATIONS = ("tanh", "relu", "silu", "gelu", "elu")
#: Rows per block of the forward pass: 512 x 128 float32 activations stay in a core's L2 cache
#: (larger blocks spill out of it and cost more per row).
BLOCK_ROWS = 512
#: Rows from which a forward pass is split across threads (each block on one core): below, the
#: pass is a fraction of a millisecond, less than handing blocks to other threads costs.
SPLIT_ROWS = 16 * BLOCK_ROWS


def _act_inplace(name: str, x: np.ndarray) -> None:
    """x = activation(x), in place (the pre-activations are not needed again); SiLU is
    :meth:`Surrogate.forward`'s own (on halved layers)."""
    if name == "tanh":
        np.tanh(x, out=x)
    elif name == "relu":
        np.maximum(x, 0.0, out=x)
    elif name == "gelu":  # PyTorch's default (erf) form
        from scipy.special import erf
        x *= 0.5 * (1.0 + erf(x * 0.7071067811865476))
    elif name == "elu":
        x[...] = np.where(x > 0, x, np.expm1(np.minimum(x, 0.0)))
    else:
        raise InputError(f"unknown activation {name!r} (known: {', '.join(ACTIVATIONS)})")


@njit(cache=True)
def _outside(X, lo, hi):
    """Rows of X with an input below lo or above hi (one compiled pass over X, where the NumPy
    form makes several passes and temporaries)."""
    out = np.zeros(X.shape[0], dtype=np.bool_)
    for i in range(X.shape[0]):
        for j in range(X.shape[1]):
            if X[i, j] < lo[j] or X[i, j] > hi[j]:
                out[i] = True
                break
    return out


@njit(cache=True)
def _scaled_back(raw, bias, scale, offset, out):
    """out[:, :m] = (raw + bias) * scale + offset in float64, of float32 products raw (n, m)."""
    for i in range(raw.shape[0]):
        for j in range(raw.shape[1]):
            out[i, j] = (raw[i, j] + bias[j]) * scale[j] + offset[j]


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
    #: Sample of the training rows' normalized inputs (m, n_inputs) for the trust score
    #: (:mod:`hmodel.surrogate.trust`); None: no trust score.
    trust_reference: np.ndarray | None = None

    @cached_property
    def trust_tree(self):
        """k-d tree of the trust reference (built once per model)."""
        from scipy.spatial import cKDTree

        return cKDTree(self.trust_reference)

    def outside(self, X: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Rows of X (n, 8) outside the training domain by more than ``margin`` of each input's
        range (all False when the range is unknown)."""
        if self.input_range is None:
            return np.zeros(len(X), bool)
        lo, hi = self.input_range
        pad = margin * (hi - lo)
        return _outside(np.asarray(X, float), lo - pad, hi + pad)

    @cached_property
    def _layers32(self) -> list[tuple[np.ndarray, np.ndarray]]:
        return self._layers(np.float32)

    @cached_property
    def _layers64(self) -> list[tuple[np.ndarray, np.ndarray]]:
        return self._layers(np.float64)

    def _layers(self, dtype) -> list[tuple[np.ndarray, np.ndarray]]:
        """(W^T, b) per layer, contiguous for the row-major products. With SiLU the hidden
        layers are halved (exactly, a power of two), so that silu(x) = h (1 + tanh h) with
        h = x/2: two passes over the activations fewer."""
        half = 0.5 if self.architecture.activation == "silu" else 1.0
        last = len(self.weights) - 1
        return [(np.ascontiguousarray(W.T * (half if k < last else 1.0), dtype),
                 np.asarray(b * (half if k < last else 1.0), dtype)) for k, (W, b) in enumerate(self.weights)]

    def __getstate__(self) -> dict:
        """A copy in another process finds that process's BLAS libraries itself."""
        return {k: v for k, v in self.__dict__.items() if k != "_blas"}

    @cached_property
    def _blas(self) -> ThreadpoolController:
        """The BLAS libraries of this process (threadpoolctl), whose thread count
        :meth:`forward` sets around its products."""
        return ThreadpoolController().select(user_api="blas")

    def forward(self, X: np.ndarray, single: bool = False, spare: int = 0) -> np.ndarray:
        """Network targets Y (n, n_outputs) for inputs X (n, n_inputs) in physical units; the
        layers in float32 with ``single`` (see the module docstring); with ``spare``, that many
        more columns (uninitialized) after the outputs, for the caller.

        Every product runs on one BLAS thread. From :data:`SPLIT_ROWS` rows, the blocks of
        :data:`BLOCK_ROWS` rows are shared among as many threads as BLAS was allowed (its
        setting on entry: ``OPENBLAS_NUM_THREADS``, a caller's ``threadpool_limits``), each
        taking the next block when done: a thread on a core that another program holds takes
        fewer, where BLAS's own threads would split each product evenly and wait for the slowest.
        The rows' results do not depend on the split (the blocks are the same)."""
        X = np.asarray(X, float)
        blas = self._blas
        threads = max((lib.num_threads for lib in blas.lib_controllers), default=1)
        with blas.limit(limits=1):
            if len(X) < SPLIT_ROWS or threads < 2:
                return self._forward(X, single, spare)
            result = np.empty((len(X), len(self.weights[-1][1]) + spare))
            with ThreadPoolExecutor(threads) as pool:  # each block writes its rows of the result
                list(pool.map(lambda i: self._forward(X[i:i + BLOCK_ROWS], single, spare,
                                                      result[i:i + BLOCK_ROWS]),
                              range(0, len(X), BLOCK_ROWS)))
            return result

    def _forward(self, X: np.ndarray, single: bool, spare: int, result: np.ndarray | None = None) -> np.ndarray:
        """:meth:`forward` in the calling thread, into ``result`` (n, n_outputs + spare) when
        given. Every product is written into one of two block buffers and the output scaled in
        place: fresh arrays of this size are new pages from the OS each time, which costs more
        than the products at large batches."""
        *hidden, (W_out, b_out) = self._layers32 if single else self._layers64
        z = self.x_scaler.transform(X).astype(W_out.dtype, copy=False)
        out = np.empty((len(z), len(b_out)), z.dtype)
        width = max((W.shape[1] for W, _ in hidden), default=0)
        buffers = np.empty((3, min(BLOCK_ROWS, len(z)), width), z.dtype)
        silu = self.architecture.activation == "silu"
        for i in range(0, len(z), BLOCK_ROWS):
            h = z[i:i + BLOCK_ROWS]
            for k, (W, b) in enumerate(hidden):
                h = np.matmul(h, W, out=buffers[k % 2, :len(h), :W.shape[1]])
                h += b
                if silu:  # h = x/2 (halved layers): silu(x) = h (1 + tanh h); no overflow,
                    # and one vectorized tanh is cheaper than expit
                    t = np.tanh(h, out=buffers[2, :len(h), :W.shape[1]])
                    t += 1.0
                    h *= t
                else:
                    _act_inplace(self.architecture.activation, h)
            np.matmul(h, W_out, out=out[i:i + BLOCK_ROWS])
        if single:  # bias and scaling in float64, one compiled pass instead of four NumPy
            # passes over the outputs
            wide = np.empty((len(z), len(b_out) + spare)) if result is None else result
            _scaled_back(out, self.weights[-1][1], self.y_scaler.scale, self.y_scaler.offset, wide)
            return wide
        out += b_out
        out = self.y_scaler.inverse(out, out=out)
        if spare or result is not None:
            wide = np.empty((len(z), len(b_out) + spare)) if result is None else result
            wide[:, :len(b_out)] = out
            return wide
        return out

    def predict(self, columns: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """State after the increment (alpha_next, N1_next, N2_next, T1_next) from database-style
        columns of the state before and the strain."""
        f = self.formulation
        return f.decode(columns, self.forward(f.inputs(columns)))
