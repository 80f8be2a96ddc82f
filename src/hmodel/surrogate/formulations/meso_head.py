"""The ``meso`` formulation's response head (:mod:`hmodel.surrogate.formulations.meso`).

The network maps the summary state before (forces over F = kn 2r, lengths over 2r) to an
incrementally multi-linear response: for a cell strain increment de, with e = de/m0, m0 = 1e-3,

    X = (alpha, l1/2r, l2/2r, N1/F, N2/F, T1/F, Vs_nn/F2r, Vs_tt/F2r)
    dz = A(X) e + sum_k <n_k(X) . e - c_k(X)^2> B_k(X),   k = 1..K (``mechanisms``, default 4),

<x> = max(x, 0): the network outputs the tangent A and, for each mechanism, a loading direction
n_k, a threshold c_k^2 >= 0 and a flow B_k. This is the form of a rate-independent cell's
increment to first order: linear within a contact regime (every contact sticking, sliding or
open), and continuous with a kink where the increment crosses into another regime: a contact
starts to slide on the line n_k . e = c_k^2 of the Coulomb trial (eq. 1.3), through e = 0 for a
contact already on the cone, beyond it for one inside (the increment must first use up the
margin), with one mechanism per independent kink. The form gives exactly no change for no
strain (no bias to accumulate over the thousands of increments of a path); the network sees the
state only, so the REV's Newton iterations and their finite-difference probes reuse one
evaluation per state.

Learned fields z: alpha, N1, N2, T1 and, for richer cells, Vs_nn and Vs_tt (for H-cells Vs is
eq. 1.12 of the others); Vs_nt is not learned (eq. 1.12 has no nt term). Every function here
takes NumPy arrays or torch tensors alike (the same head in the REV and in training).
"""

from __future__ import annotations

import numpy as np

from ..torch_support import require_torch


class MesoHead:
    """The response head of a ``meso`` network with ``self.mechanisms`` mechanisms, whose
    learned fields are :attr:`learned`."""

    mechanisms: int
    richer: bool
    radius: float
    force_scale: float
    m0 = 1e-3  #: strain scale of the inputs and targets

    @property
    def learned(self) -> tuple[str, ...]:
        """Fields whose increments the network gives: the hexagon's shape and contact forces,
        and for richer cells V sigma (nn, tt)."""
        return ("alpha", "N1", "N2", "T1") + (("Vs_nn", "Vs_tt") if self.richer else ())

    @property
    def input_names(self) -> tuple[str, ...]:
        return ("alpha", "l1/2r", "l2/2r", "N1/F", "N2/F", "T1/F", "Vs_nn/F2r", "Vs_tt/F2r")

    @property
    def n_outputs(self) -> int:
        """A (row-major, len(learned) x 2), then (n_k, c_k, B_k) per mechanism."""
        L = len(self.learned)
        return 2 * L + self.mechanisms * (L + 3)

    def features(self, v: np.ndarray, F=None, d=None) -> np.ndarray:
        """X (n, 8) from summary states v (n, 11), forces over F = kn 2r and lengths over d = 2r:
        this cell's, or each row's (arrays (n,): the cells of several materials)."""
        d = 2 * self.radius if d is None else d
        F = self.force_scale if F is None else F
        return stack([v[:, 2], v[:, 6] / d, v[:, 7] / d, v[:, 3] / F, v[:, 4] / F, v[:, 5] / F,
                      v[:, 8] / (F * d), v[:, 9] / (F * d)])

    def _scales(self) -> np.ndarray:
        F, d = self.force_scale, 2 * self.radius
        return np.array([1.0, F, F, F] + [F * d] * (len(self.learned) - 4))

    def _learned_values(self, v: np.ndarray) -> np.ndarray:
        """The learned fields (n, len(learned)) of summary states v (n, 11)."""
        return stack([v[:, 2], v[:, 3], v[:, 4], v[:, 5]] + ([v[:, 8], v[:, 9]] if self.richer else []))

    def aux(self, c: dict[str, np.ndarray]) -> np.ndarray:
        """e = de/m0 (n, 2), which the head applies the response to."""
        return np.column_stack([c["deps1"], c["deps2"]]) / self.m0

    def head(self, out, e, target=None):
        """dz/m0 = A e + sum_k <n_k . e - c_k^2> B_k from network outputs (n, n_outputs); NumPy
        or torch."""
        return self.apply(self.response(out), e)

    def response(self, out):
        """The response of network outputs (n, n_outputs): tangent A (n, L, 2) and, per
        mechanism, n_k (n, K, 2), c_k^2 (n, K) and B_k (n, K, L); NumPy or torch."""
        L = len(self.learned)
        mech = out[:, 2 * L:].reshape(-1, self.mechanisms, L + 3)
        return out[:, :2 * L].reshape(-1, L, 2), mech[:, :, :2], mech[:, :, 2] ** 2, mech[:, :, 3:]

    @staticmethod
    def apply(response, e):
        """dz/m0 of a :meth:`response` for strains e = de/m0 (n, 2); NumPy or torch."""
        A, n, c2, B = response
        e1, e2 = e[:, 0:1], e[:, 1:2]
        load = n[:, :, 0] * e1 + n[:, :, 1] * e2 - c2
        einsum = np.einsum if isinstance(load, np.ndarray) else require_torch().einsum  # no broadcast temporary
        return A[:, :, 0] * e1 + A[:, :, 1] * e2 + einsum("nk,nkl->nl", positive(load), B)

    @staticmethod
    def mean_response(responses: list) -> tuple:
        """The response whose increment is the mean of the members' (an ensemble; NumPy): the
        mean tangent, and every member's mechanisms with its flow divided by their number."""
        if len(responses) == 1:
            return responses[0]
        A, n, c2, B = zip(*responses)
        return (sum(A) / len(A), np.concatenate(n, axis=1), np.concatenate(c2, axis=1),
                np.concatenate(B, axis=1) / len(B))

    def increment(self, out: np.ndarray, e1: np.ndarray, e2: np.ndarray) -> np.ndarray:
        """dz/m0 from network outputs and cell strains."""
        return self.head(out, np.column_stack([e1, e2]) / self.m0)


def array_ops(a):
    """where, minimum, maximum, sin, cos of NumPy or torch, after the type of ``a``."""
    if isinstance(a, np.ndarray):
        return np.where, np.minimum, np.maximum, np.sin, np.cos
    torch = require_torch()
    return torch.where, torch.minimum, torch.maximum, torch.sin, torch.cos


def positive(x):
    """<x> = max(x, 0) of NumPy arrays or torch tensors."""
    return 0.5 * (x + abs(x))


def like(const: np.ndarray, a):
    """``const`` as an array of ``a``'s kind (a torch tensor of its dtype and device)."""
    if isinstance(a, np.ndarray):
        return const
    torch = require_torch()
    return torch.as_tensor(const, dtype=a.dtype, device=a.device)


def stack(cols: list):
    """Columns side by side (NumPy or torch)."""
    if isinstance(cols[0], np.ndarray):
        return np.column_stack(cols)
    torch = require_torch()
    return torch.stack(cols, dim=1)
