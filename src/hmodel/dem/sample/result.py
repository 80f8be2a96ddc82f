"""One test of a DEM sample (biaxial for disks, triaxial for spheres): its recorded rows, the
CSV that ``hmodel calibrate --data`` reads, the npz of every row and state, and its record in
sample.json."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from .state import SampleState, contact_columns

#: Columns of the test CSV: the ``--data`` format of ``hmodel calibrate`` (eps11, q, eps_v, p),
#: then the coordination number and the sliding fraction (ignored by ``--data``).
CSV_COLUMNS = ("eps11", "q", "eps_v", "p", "coordination", "sliding")
#: Columns of a recorded row (``rows`` of the npz file); contacts: YADE's real interactions,
#: sliding: the fraction of the contacts at the Coulomb limit.
ROW_COLUMNS = ("eps11", "eps22", "s11", "s22", "s12", "unbalanced", "contacts", "sliding")
#: Columns of a sphere sample's test CSV: the triaxial ``--data`` format (eps_a, q, eps_v, p),
#: then the coordination number, the sliding fraction and the stress tensor [Pa].
CSV_COLUMNS_3D = ("eps_a", "q", "eps_v", "p", "coordination", "sliding",
                  "sig11", "sig22", "sig33", "sig12", "sig13", "sig23")
#: Columns of a sphere sample's recorded row (``rows`` of the npz file); contacts: pairs in
#: contact, sliding: the fraction of them at the Coulomb limit.
ROW_COLUMNS_3D = ("eps11", "eps22", "eps33", "s11", "s22", "s33", "s12", "s13", "s23",
                  "unbalanced", "contacts", "sliding")


def row_columns(dim: int) -> tuple[str, ...]:
    return ROW_COLUMNS if dim == 2 else ROW_COLUMNS_3D


def csv_columns(dim: int) -> tuple[str, ...]:
    return CSV_COLUMNS if dim == 2 else CSV_COLUMNS_3D


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
        return self.rows[:, row_columns(self.dim).index(name)]

    def table(self) -> dict[str, np.ndarray]:
        """The CSV's columns: :data:`CSV_COLUMNS` for disks (q = s11 - s22, p = (s11 + s22) / 2);
        :data:`CSV_COLUMNS_3D` for spheres (q = s11 - (s22 + s33) / 2, p = tr(s) / 3)."""
        if self.dim == 2:
            e1, e2 = self.column("eps11"), self.column("eps22")
            s1, s2 = self.column("s11"), self.column("s22")
            return {"eps11": e1, "q": s1 - s2, "eps_v": e1 + e2, "p": 0.5 * (s1 + s2),
                    "coordination": 2.0 * self.column("contacts") / len(self.final.radii),
                    "sliding": self.column("sliding")}
        e = [self.column(f"eps{i}{i}") for i in (1, 2, 3)]
        s = {c: self.column("s" + c) for c in ("11", "22", "33", "12", "13", "23")}
        return {"eps_a": e[0], "q": s["11"] - 0.5 * (s["22"] + s["33"]), "eps_v": e[0] + e[1] + e[2],
                "p": (s["11"] + s["22"] + s["33"]) / 3.0,
                "coordination": 2.0 * self.column("contacts") / len(self.final.radii),
                "sliding": self.column("sliding"), **{"sig" + c: v for c, v in s.items()}}

    def write_csv(self, path: "str | os.PathLike") -> None:
        t = self.table()
        columns = csv_columns(self.dim)
        with open(path, "w") as fh:
            fh.write(",".join(columns) + "\n")
            for k in range(len(self.rows)):
                fh.write(",".join(repr(float(t[c][k])) for c in columns) + "\n")

    def write_npz(self, path: "str | os.PathLike") -> None:
        with open(path, "wb") as fh:
            np.savez_compressed(fh, rows=self.rows, row_columns=np.array(row_columns(self.dim)),
                                contact_columns=np.array(contact_columns(self.dim)),
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
