"""What a surrogate learns: inputs and targets built from database columns, and the way back.

A formulation maps the columns of the H-cell databases (``hmodel.data.schema``) to network
inputs X and targets Y, and maps predictions back to the state after the increment
(``alpha_next, N1_next, N2_next, T1_next``; lengths follow from the strain, report §2.3).

- ``report`` (report §2.3): X = (δε1, δε2, α, l1, l2, N1, N2, T1), Y = (α′, N1′, N2′, T1′).
- ``increment`` (ours): dimensionless inputs (lengths over 2r, forces over kn·2r) and targets
  that are the *increments* α′ − α, (N1′ − N1)/(kn·2r), (N2′ − N2)/(kn·2r), the mobilized
  friction s = T1′/(tan φg N1′) in [−1, 1], and a fifth output, the logit of "a contact opens"
  (Fig. 1.5). Opening is a jump of the forces to zero, which a regression smears; it is learned
  as a classification (binary cross-entropy) and the force targets of opened rows are left out
  of the regression loss. Predictions are mapped back with N′ = max(N + ΔN, 0), all forces zero
  where the logit is positive, and T1′ = clip(s, −1, 1)·tan φg·N1′, so that |T1′| ≤ tan φg N1′
  holds by construction (eq. 1.3), whatever the network outputs. Learning increments keeps the
  network from having to copy its inputs, where all the variance lies.
- ``compliance`` (ours, :mod:`hmodel.surrogate.compliance`): the network sees the state only and
  outputs the compliance of eq. 1.7 in each contact regime; the contact law is applied exactly.
- ``meso`` (ours, :mod:`hmodel.surrogate.meso`): richer DEM cells through a summary state (the
  H-cell fields and the Love-Weber meso-stress), learned as increments.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..params import Params

OUTPUTS = ("alpha_next", "N1_next", "N2_next", "T1_next")
REPORT_INPUTS = ("deps1", "deps2", "alpha", "l1", "l2", "N1", "N2", "T1")


class MaterialScales:
    """Scales of a formulation whose material is ``self.params``: grain radius, friction
    coefficient and the force unit F = kn 2r."""

    params: Params

    @property
    def radius(self) -> float:
        return self.params.radius

    @property
    def tan_phi(self) -> float:
        return self.params.tan_phi

    @property
    def force_scale(self) -> float:
        return self.params.kn * 2 * self.params.radius


@dataclass(frozen=True)
class Formulation:
    """Inputs/targets of one formulation for a material (force scale kn·2r, tan φg)."""

    name: str
    force_scale: float
    tan_phi: float
    radius: float

    def to_dict(self) -> dict:
        return {"name": self.name, "force_scale": self.force_scale, "tan_phi": self.tan_phi,
                "radius": self.radius}

    def aux(self, c: dict[str, np.ndarray]) -> None:
        """Per-row inputs of :meth:`head` (none: the network's outputs are the targets)."""
        return None

    def head(self, out, aux, target=None):
        return out

    @property
    def logit_column(self) -> int | None:
        """Index of the output trained by classification (None: all regression)."""
        return None if self.name == "report" else 4

    def inputs(self, c: dict[str, np.ndarray]) -> np.ndarray:
        """X (n, 8) from database columns (the state before and the strain)."""
        if self.name == "report":
            return np.column_stack([c[k] for k in REPORT_INPUTS]).astype(float)
        F, d = self.force_scale, 2 * self.radius
        return np.column_stack([c["deps1"], c["deps2"], c["alpha"], c["l1"] / d, c["l2"] / d,
                                c["N1"] / F, c["N2"] / F, c["T1"] / F]).astype(float)

    def targets(self, c: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """Targets Y (n, 4; 5 with the opening logit) from database columns (the state after), and the weight
        (0 or 1) of every target in the loss."""
        if self.name == "report":
            Y = np.column_stack([c[k] for k in OUTPUTS]).astype(float)
            return Y, np.ones_like(Y)
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

    def mobilized_friction(self, n1: np.ndarray, t1: np.ndarray) -> np.ndarray:
        """s = T1 / (tan φg N1), 0 where the contact carries no normal force."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(n1 > 0, t1 / (self.tan_phi * np.where(n1 > 0, n1, 1.0)), 0.0)

    def decode(self, c: dict[str, np.ndarray], Y: np.ndarray) -> dict[str, np.ndarray]:
        """Predicted state after the increment from predictions Y and the state before."""
        if self.name == "report":
            return {k: Y[:, j] for j, k in enumerate(OUTPUTS)}
        F = self.force_scale
        closed = Y[:, 4] <= 0.0
        n1 = np.maximum(c["N1"] + F * Y[:, 1], 0.0) * closed
        n2 = np.maximum(c["N2"] + F * Y[:, 2], 0.0) * closed
        return {"alpha_next": c["alpha"] + Y[:, 0], "N1_next": n1, "N2_next": n2,
                "T1_next": np.clip(Y[:, 3], -1.0, 1.0) * self.tan_phi * n1}
