"""One test of a DEM sample (biaxial for disks, triaxial for spheres): its recorded rows, the
CSV that ``hmodel calibrate --data`` reads, the npz of every row and state, and its record in
sample.json."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .geometry import (  # noqa: F401 (the columns: importers of their first home)
    CSV_COLUMNS,
    CSV_COLUMNS_3D,
    ROW_COLUMNS,
    ROW_COLUMNS_3D,
    grains,
)
from .state import SampleState


def row_columns(dim: int) -> tuple[str, ...]:
    return grains(dim).row_columns


def csv_columns(dim: int) -> tuple[str, ...]:
    return grains(dim).csv_columns


def read_table(path: Path) -> dict[str, np.ndarray] | None:
    """A test CSV's columns, or None for a CSV removed by hand."""
    if not path.exists():
        return None
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    header = path.read_text().split("\n", 1)[0].split(",")
    return {c: data[:, k] for k, c in enumerate(header)}


def file_stem(kind: str, p0: float) -> str:
    """File stem of a test: ``drained_100kPa``."""
    return f"{kind}_{p0 / 1e3:g}kPa"


@dataclass(frozen=True)
class SampleTest:
    """One test of the sample.

    Attributes
    ----------
    kind : str
        ``drained`` or ``undrained`` (disks), ``triaxial-drained``, ``triaxial-undrained`` or
        ``triaxial-extension`` (spheres).
    p0 : float
        Consolidation pressure [N/m for disks, Pa for spheres].
    rows : ndarray (rows + 1, 7 or 12)
        Columns :data:`ROW_COLUMNS` (:data:`ROW_COLUMNS_3D` for spheres); row 0 is the end of
        the consolidation.
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

    @property
    def dim(self) -> int:
        return self.consolidated.dim

    def column(self, name: str) -> np.ndarray:
        return self.rows[:, self.consolidated.grains.row_columns.index(name)]

    def table(self) -> dict[str, np.ndarray]:
        """The CSV's columns: :data:`CSV_COLUMNS` for disks (q = s11 - s22, p = (s11 + s22) / 2);
        :data:`CSV_COLUMNS_3D` for spheres (q = s11 - (s22 + s33) / 2, p = tr(s) / 3)."""
        return self.consolidated.grains.table(self)

    def write_csv(self, path: "str | os.PathLike") -> None:
        t = self.table()
        columns = self.consolidated.grains.csv_columns
        with open(path, "w") as fh:
            fh.write(",".join(columns) + "\n")
            for k in range(len(self.rows)):
                fh.write(",".join(repr(float(t[c][k])) for c in columns) + "\n")

    def write_npz(self, path: "str | os.PathLike") -> None:
        with open(path, "wb") as fh:
            g = self.consolidated.grains
            np.savez_compressed(fh, rows=self.rows, row_columns=np.array(g.row_columns),
                                contact_columns=np.array(g.contact_columns),
                                radii=self.final.radii,
                                **self.consolidated.arrays("consolidated"),
                                **self.final.arrays("final"))

    def summary(self) -> dict:
        """The test's record in sample.json."""
        t = self.table()
        out = {"kind": self.kind, "p0": self.p0, "csv": self.name + ".csv",
               **self.info,
               "consolidated": self.consolidated.summary(), "final": self.final.summary(),
               # the q of largest magnitude: the peak, negative in extension
               "peak_q": float(t["q"][np.argmax(np.abs(t["q"]))]),
               "max_unbalanced_shear": float(np.max(self.column("unbalanced")[1:])),
               "median_unbalanced_shear": float(np.median(self.column("unbalanced")[1:]))}
        if self.kind.endswith("undrained"):
            out["max_abs_eps_v"] = float(np.max(np.abs(t["eps_v"])))
        else:
            lateral = np.stack([self.column(f"s{i}{i}") for i in range(2, self.dim + 1)])
            out["max_lateral_stress_error"] = float(np.max(np.abs(lateral - self.p0)) / self.p0)
        out["max_sliding"] = float(np.max(t["sliding"]))
        return out
