"""The strain-input formulations: networks of the increment that see the strain increment with
the state (report §2.3).

- ``report`` (report §2.3): X = (δε1, δε2, α, l1, l2, N1, N2, T1), Y = (α′, N1′, N2′, T1′).
- ``report-leak``: the input convention of the report's published code, whose force inputs are
  the forces *after* the increment (N1′, N2′, T1′), three of the four answers. Kept to measure
  how much that leak flatters the report's accuracy tables (:mod:`hmodel.studies.sweep`); it
  cannot step cells, since it needs the answer to make its inputs.
- ``increment``: dimensionless inputs (lengths over 2r, forces over kn·2r) and targets that are
  the *increments* α′ − α, (N1′ − N1)/(kn·2r), (N2′ − N2)/(kn·2r), the mobilized friction
  s = T1′/(tan φg N1′) in [−1, 1], and a fifth output, the logit of "a contact opens"
  (Fig. 1.5), learned as a classification (binary cross-entropy); the force targets of opened
  rows are left out of the regression loss. Predictions are mapped back with
  N′ = max(N + ΔN, 0), all forces zero where the logit is positive, and
  T1′ = clip(s, −1, 1)·tan φg·N1′, so that |T1′| ≤ tan φg N1′ holds by construction (eq. 1.3),
  whatever the network outputs. The logit serves the offline predictions
  (:meth:`hmodel.surrogate.model.Surrogate.predict`, the metrics); as a cell solver, a cell
  opens by eq. 1.7's rule on the continued force increments instead.

The other formulations: ``compliance`` (:mod:`hmodel.surrogate.formulations.compliance`) and
``meso`` (:mod:`hmodel.surrogate.formulations.meso`); what every formulation declares:
:mod:`hmodel.surrogate.formulations.base`.
"""

from __future__ import annotations

import math
from abc import abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ...errors import InputError
from ...params import Params
from .base import OUTPUTS, Formulation, Increment, Networks

REPORT_INPUTS = ("deps1", "deps2", "alpha", "l1", "l2", "N1", "N2", "T1")
LEAK_REFUSED = ("a report-leak model takes the forces after the increment as inputs, so it cannot "
                "step cells; train --formulation report to run one")


@dataclass(frozen=True)
class StrainFormulation(Formulation):
    """A network of the increment that sees the strain increment with the state (report §2.3),
    for a material (force scale kn·2r, tan φg, grain radius): ``report`` and ``increment``.

    The solver cuts an increment larger than the trained ones (the range of the δε inputs)
    into equal sub-steps. The network's answer for a zero increment is subtracted from its
    answer, so that a cell without strain keeps its state and the network's bias does not
    accumulate over the thousands of increments of a path. The network predicts α′, N1′, N2′,
    T1′; the lengths follow the strain, and d1, d2 follow from α′ and the lengths by eq. 1.2
    (d1 = l2 / (2 sin α), d2 = l1 − 2 d1 cos α), so that the state stays geometrically consistent.
    """

    force_scale: float
    tan_phi: float
    radius: float
    name: ClassVar[str]
    #: Index of the output trained by classification (None: all regression).
    logit_column: ClassVar[int | None]

    def to_dict(self) -> dict:
        return {"name": self.name, "force_scale": self.force_scale, "tan_phi": self.tan_phi,
                "radius": self.radius}

    def mobilized_friction(self, n1: np.ndarray, t1: np.ndarray) -> np.ndarray:
        """s = T1 / (tan φg N1), 0 where the contact carries no normal force."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(n1 > 0, t1 / (self.tan_phi * np.where(n1 > 0, n1, 1.0)), 0.0)

    def max_increment(self, input_range: np.ndarray | None) -> float:
        """The bound of the δε1, δε2 inputs over the training rows (inf when unknown)."""
        return math.inf if input_range is None else float(np.abs(input_range[:, :2]).max())

    def step_cells(self, net: Networks, params: Params, v, e1, e2, dl) -> Increment:
        cols = {"deps1": e1, "deps2": e2, "d1": v[:, 0], "d2": v[:, 1], "alpha": v[:, 2],
                "N1": v[:, 3], "N2": v[:, 4], "T1": v[:, 5], "l1": v[:, 6], "l2": v[:, 7]}
        X = self.inputs(cols)
        pred = self._predict(net, cols, X)
        a = pred["alpha_next"]
        l1, l2 = v[:, 6] + dl[:, 0], v[:, 7] + dl[:, 1]
        b1 = l2 / (2.0 * np.sin(a))  # eq. 1.2
        b2 = l1 - 2.0 * b1 * np.cos(a)
        new = np.column_stack([b1, b2, a, pred["N1_next"], pred["N2_next"], pred["T1_next"], l1, l2])
        two_r = 2.0 * params.radius
        opened = (pred["N1_next"] == 0) & (pred["N2_next"] == 0)
        opened |= (b1 > two_r) | (b2 > two_r)  # separated grains carry no force (docs/model.md step 3)
        for k in (3, 4, 5):
            new[opened, k] = 0.0
        flags = np.column_stack([
            (np.abs(pred["T1_next"]) >= params.tan_phi * pred["N1_next"] * (1 - 1e-9)) & ~opened,
            opened, opened, l1 <= two_r, l2 <= two_r])
        return Increment(new, flags, net.outside(X), lambda i: ", ".join(
            f"{k}={cols[k][i]:.4g}" for k in REPORT_INPUTS), network_cells=len(v))

    def _predict(self, net: Networks, cols: dict[str, np.ndarray], X: np.ndarray) -> dict[str, np.ndarray]:
        """The state after the increment, with the zero-increment correction."""
        X0 = X.copy()
        X0[:, :2] = 0.0
        Y, Y0 = net.forward(X), net.forward(X0)
        return self.decode(cols, self._corrected(cols, Y, Y0))

    @abstractmethod
    def inputs(self, c: dict[str, np.ndarray]) -> np.ndarray:
        """X (n, 8) from database columns (the state before and the strain)."""

    @abstractmethod
    def targets(self, c: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """Targets Y from database columns (the state after), and the weight of every target in
        the loss."""

    @abstractmethod
    def decode(self, c: dict[str, np.ndarray], Y: np.ndarray) -> dict[str, np.ndarray]:
        """Predicted state after the increment from predictions Y and the state before."""

    @abstractmethod
    def _corrected(self, cols, Y, Y0) -> np.ndarray:
        """Predictions Y less the answer Y0 to a zero increment, as :meth:`decode` reads them."""


@dataclass(frozen=True)
class ReportFormulation(StrainFormulation):
    """``report`` (report §2.3): X = (δε1, δε2, α, l1, l2, N1, N2, T1) and Y = (α′, N1′, N2′,
    T1′)."""

    name = "report"
    logit_column = None

    def inputs(self, c: dict[str, np.ndarray]) -> np.ndarray:
        """X (n, 8) from database columns (the state before and the strain)."""
        return np.column_stack([c[k] for k in REPORT_INPUTS]).astype(float)

    def targets(self, c: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """Targets Y (n, 4) from database columns (the state after), and the weight (all 1) of
        every target in the loss."""
        Y = np.column_stack([c[k] for k in OUTPUTS]).astype(float)
        return Y, np.ones_like(Y)

    def decode(self, c: dict[str, np.ndarray], Y: np.ndarray) -> dict[str, np.ndarray]:
        """Predicted state after the increment: the predictions themselves."""
        return {k: Y[:, j] for j, k in enumerate(OUTPUTS)}

    def _corrected(self, cols, Y, Y0):
        before = np.column_stack([cols[k] for k in ("alpha", "N1", "N2", "T1")])
        return before + Y - Y0


@dataclass(frozen=True)
class LeakedReportFormulation(ReportFormulation):
    """``report-leak``: the report's published inputs, X = (δε1, δε2, α, l1, l2, N1′, N2′, T1′),
    with the forces after the increment (the answer leak); Y as ``report``. For accuracy
    tables only."""

    name = "report-leak"
    #: Its inputs need the state after the increment: no cell solver can run it.
    needs_answer = True

    def inputs(self, c: dict[str, np.ndarray]) -> np.ndarray:
        """X (n, 8): the strain, α and the lengths before, the forces after the increment."""
        return np.column_stack([c[k + "_next" if k in ("N1", "N2", "T1") else k]
                                for k in REPORT_INPUTS]).astype(float)

    def step_cells(self, net, params, v, e1, e2, dl):
        raise InputError(LEAK_REFUSED)


@dataclass(frozen=True)
class IncrementFormulation(StrainFormulation):
    """``increment``: dimensionless inputs, increments as targets and the opening logit (see the
    module docstring)."""

    name = "increment"
    logit_column = 4

    def inputs(self, c: dict[str, np.ndarray]) -> np.ndarray:
        """X (n, 8) from database columns (the state before and the strain)."""
        F, d = self.force_scale, 2 * self.radius
        return np.column_stack([c["deps1"], c["deps2"], c["alpha"], c["l1"] / d, c["l2"] / d,
                                c["N1"] / F, c["N2"] / F, c["T1"] / F]).astype(float)

    def targets(self, c: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """Targets Y (n, 5, the last the opening logit) from database columns (the state after),
        and the weight (0 or 1) of every target in the loss."""
        F = self.force_scale
        n1 = c["N1_next"]
        opened = np.asarray(c["open1"], bool) | np.asarray(c["open2"], bool)
        Y = np.column_stack([c["alpha_next"] - c["alpha"], (n1 - c["N1"]) / F,
                             (c["N2_next"] - c["N2"]) / F,
                             np.clip(self.mobilized_friction(n1, c["T1_next"]), -1.0, 1.0),
                             opened.astype(float)])
        W = np.ones_like(Y)
        W[opened, 1:4] = 0.0  # forces of an opened cell are zero whatever the trial: not regressed
        return Y, W

    def decode(self, c: dict[str, np.ndarray], Y: np.ndarray) -> dict[str, np.ndarray]:
        """Predicted state after the increment from predictions Y and the state before."""
        F = self.force_scale
        closed = Y[:, 4] <= 0.0
        n1 = np.maximum(c["N1"] + F * Y[:, 1], 0.0) * closed
        n2 = np.maximum(c["N2"] + F * Y[:, 2], 0.0) * closed
        return {"alpha_next": c["alpha"] + Y[:, 0], "N1_next": n1, "N2_next": n2,
                "T1_next": np.clip(Y[:, 3], -1.0, 1.0) * self.tan_phi * n1}

    def _corrected(self, cols, Y, Y0):
        s_in = self.mobilized_friction(cols["N1"], cols["T1"])
        Y = Y.copy()
        Y[:, :3] -= Y0[:, :3]
        Y[:, 3] = s_in + Y[:, 3] - Y0[:, 3]
        # Opening decided as eq. 1.7's closed form does, on the continued force increments
        # (regressed on closed cells only): a force that would turn negative opens the cell. The
        # rule takes the logit's column, so that decode reads both the same way.
        trial1, trial2 = cols["N1"] + self.force_scale * Y[:, 1], cols["N2"] + self.force_scale * Y[:, 2]
        Y[:, 4] = np.where((trial1 < 0) | (trial2 < 0), 1.0, -1.0)
        return Y
