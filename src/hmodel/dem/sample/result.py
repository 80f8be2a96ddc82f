"""One biaxial test of a DEM sample: its recorded rows, the CSV that ``hmodel calibrate --data``
reads, the npz of every row and state, and its record in sample.json."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from .state import CONTACT_COLUMNS, SampleState

#: Columns of the test CSV (the ``--data`` format of ``hmodel calibrate``).
CSV_COLUMNS = ("eps11", "q", "eps_v", "p")
#: Columns of a recorded row (``rows`` of the npz file).
ROW_COLUMNS = ("eps11", "eps22", "s11", "s22", "s12", "unbalanced", "contacts")


def file_stem(kind: str, p0: float) -> str:
    """File stem of a test: ``drained_100kPa``."""
    return f"{kind}_{p0 / 1e3:g}kPa"


@dataclass(frozen=True)
class SampleTest:
    """One biaxial test of the sample.

    Attributes
    ----------
    kind : str
        ``drained`` or ``undrained``.
    p0 : float
        Consolidation pressure [N/m].
    rows : ndarray (rows + 1, 7)
        Columns :data:`ROW_COLUMNS`; row 0 is the end of the consolidation.
    consolidated, final : SampleState
    info : dict
        Strain rate, inertial numbers, time step, steps, wall times, YADE version.
    """

    kind: str
    p0: float
    rows: np.ndarray
    consolidated: SampleState
    final: SampleState
    info: dict

    @property
    def name(self) -> str:
        return file_stem(self.kind, self.p0)

    def column(self, name: str) -> np.ndarray:
        return self.rows[:, ROW_COLUMNS.index(name)]

    def table(self) -> dict[str, np.ndarray]:
        """The CSV's columns: eps11, q, eps_v, p."""
        e1, e2 = self.column("eps11"), self.column("eps22")
        s1, s2 = self.column("s11"), self.column("s22")
        return {"eps11": e1, "q": s1 - s2, "eps_v": e1 + e2, "p": 0.5 * (s1 + s2)}

    def write_csv(self, path: "str | os.PathLike") -> None:
        t = self.table()
        with open(path, "w") as fh:
            fh.write(",".join(CSV_COLUMNS) + "\n")
            for k in range(len(self.rows)):
                fh.write(",".join(repr(float(t[c][k])) for c in CSV_COLUMNS) + "\n")

    def write_npz(self, path: "str | os.PathLike") -> None:
        with open(path, "wb") as fh:
            np.savez_compressed(fh, rows=self.rows, row_columns=np.array(ROW_COLUMNS),
                                contact_columns=np.array(CONTACT_COLUMNS),
                                radii=self.final.radii,
                                **self.consolidated.arrays("consolidated"),
                                **self.final.arrays("final"))

    def summary(self) -> dict:
        """The test's record in sample.json."""
        t = self.table()
        s22 = self.column("s22")
        out = {"kind": self.kind, "p0": self.p0, "csv": self.name + ".csv",
               **self.info,
               "consolidated": self.consolidated.summary(), "final": self.final.summary(),
               "peak_q": float(np.max(t["q"])),
               "max_unbalanced_shear": float(np.max(self.column("unbalanced")[1:])),
               "median_unbalanced_shear": float(np.median(self.column("unbalanced")[1:]))}
        if self.kind == "drained":
            out["max_lateral_stress_error"] = float(np.max(np.abs(s22 - self.p0)) / self.p0)
        else:
            out["max_abs_eps_v"] = float(np.max(np.abs(t["eps_v"])))
        return out
