"""The outcome of a finite-element run: one row per converged load step, saved field snapshots."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .mesh import Domain


@dataclass
class Snapshot:
    """Fields of one converged load step: nodal displacement since consolidation (N,), and per
    Gauss point (B, ...) the strain since consolidation and stress (hmodel's convention), the
    fractions of sliding and open cells, and the normalized second-order work of the step's
    increments (d2W / (|dsig| |deps|), :func:`hmodel.stability.second_order_work`)."""

    step: int
    load: float
    u: np.ndarray
    eps: np.ndarray
    sig: np.ndarray
    frac_sliding: np.ndarray
    frac_open: np.ndarray
    d2w: np.ndarray


@dataclass
class FemResult:
    """Rows (column -> array, one entry per converged step, step 0 the consolidated state),
    snapshots, the Newton residual history of every step, and ``stopped`` (None, or why the
    run ended before the full load)."""

    problem: str
    domain: Domain
    columns: tuple[str, ...]
    rows: dict
    snapshots: list[Snapshot]
    residuals: list[list[float]]
    gauss_x: np.ndarray
    gauss_dx: np.ndarray
    meta: dict
    stopped: str | None = None
    reference: object = None  # material-point PathResult of the same parameters (biaxial)
    extra: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.rows[self.columns[0]])

    def column(self, name: str) -> np.ndarray:
        return np.asarray(self.rows[name])

    def to_csv(self, path) -> None:
        cols = [np.asarray(self.rows[c]) for c in self.columns]
        with open(path, "w") as f:
            f.write(",".join(self.columns) + "\n")
            for i in range(len(self)):
                f.write(",".join(_fmt(c[i]) for c in cols) + "\n")


def _fmt(x) -> str:
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    return repr(float(x))


def material_point_curve(reference) -> dict:
    """The material-point test's shear stage as (axial strain since consolidation, q, eps_v
    since consolidation, p), starting with the consolidated state (strain 0)."""
    cons, sh = reference.stage("consolidation"), reference.stage("shear")
    e0, v0 = cons["eps11"][-1], cons["eps_v"][-1]
    return {"eps11": np.concatenate([[0.0], sh["eps11"] - e0]),
            "q": np.concatenate([[cons["q"][-1]], sh["q"]]),
            "p": np.concatenate([[cons["p"][-1]], sh["p"]]),
            "eps_v": np.concatenate([[0.0], sh["eps_v"] - v0])}
