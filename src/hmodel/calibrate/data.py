"""Measured tests to calibrate on: biaxial tests after isotropic consolidation to p0."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io import read_csv_rows
from ..units import parse_pressure

KINDS = ("drained", "undrained")


@dataclass(frozen=True)
class Test:
    """One biaxial test: its kind, its consolidation pressure p0 [Pa] and its rows.

    Attributes
    ----------
    kind : str
        ``drained`` (σ22 held at p0) or ``undrained`` (isochoric) biaxial compression after
        isotropic consolidation to p0.
    p0 : float
        Consolidation pressure [Pa].
    eps11 : ndarray (n,)
        Axial strain since the end of consolidation, compression positive, increasing.
    q : ndarray (n,)
        Deviatoric stress σ11 − σ22 [Pa].
    eps_v : ndarray (n,) or None
        Volumetric strain since the end of consolidation (drained tests).
    name : str
        A label for tables and figures.
    """

    __test__ = False  # a calibration test, not a pytest class

    kind: str
    p0: float
    eps11: np.ndarray
    q: np.ndarray
    eps_v: np.ndarray | None = None
    name: str = ""

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise InputError(f"test kind must be drained or undrained, got {self.kind!r}")
        if not (np.isfinite(self.p0) and self.p0 > 0):
            raise InputError(f"test p0 must be a positive pressure, got {self.p0}")
        e = np.asarray(self.eps11, float)
        columns = {"eps11": e, "q": np.asarray(self.q, float)}
        if self.eps_v is not None:
            columns["eps_v"] = np.asarray(self.eps_v, float)
        label = self.name or f"{self.kind} {self.p0 / 1e3:g} kPa"
        for k, v in columns.items():
            if v.ndim != 1 or len(v) != len(e):
                raise InputError(f"{label}: column {k} must have one value per row")
            if not np.all(np.isfinite(v)):
                raise InputError(f"{label}: column {k} has non-finite values")
        if len(e) < 2:
            raise InputError(f"{label}: a test needs at least 2 rows, got {len(e)}")
        if np.any(np.diff(e) <= 0) or e[0] < 0:
            raise InputError(f"{label}: eps11 must be non-negative and increasing")
        if e[-1] >= 1:  # a strain of 1 leaves the specimen no height
            raise InputError(f"{label}: eps11 must stay below 1 (a strain, not a percentage), "
                             f"reaches {e[-1]:g}")
        object.__setattr__(self, "eps11", e)
        object.__setattr__(self, "q", columns["q"])
        object.__setattr__(self, "eps_v", columns.get("eps_v"))
        object.__setattr__(self, "name", label)

    @property
    def q_scale(self) -> float:
        """The scale of the q residuals: the test's peak |q| [Pa]."""
        return float(max(np.abs(self.q).max(), 1e-12 * self.p0))

    @property
    def eps_v_scale(self) -> float:
        """The scale of the εv residuals: the range of the test's εv."""
        return float(max(np.ptp(self.eps_v), 1e-12)) if self.eps_v is not None else 1.0

    @classmethod
    def from_csv(cls, path, kind: str, p0: float, name: str = "") -> "Test":
        """A test from a CSV with header ``eps11,q[,eps_v][,p]`` (the columns of ``result.csv``:
        strains since the end of consolidation, stresses in Pa, compression positive)."""
        path = Path(path)
        rows = read_csv_rows(path, "test file")
        if not rows:
            raise InputError(f"{path}: empty file")
        header = [h.strip() for h in rows[0]]
        missing = [c for c in ("eps11", "q") if c not in header]
        if missing:
            raise InputError(f"{path}: missing column(s) {', '.join(missing)} (header: eps11,q[,eps_v][,p])")
        try:
            data = np.array([[float(x) for x in r] for r in rows[1:] if r], float)
        except ValueError:
            raise InputError(f"{path}: every value must be a number") from None
        if data.ndim != 2 or data.shape[0] == 0 or data.shape[1] != len(header):
            raise InputError(f"{path}: every row needs {len(header)} values")
        col = {h: data[:, i] for i, h in enumerate(header)}
        return cls(kind, p0, col["eps11"], col["q"], col.get("eps_v"), name or path.stem)


def parse_data_spec(spec: str) -> Test:
    """``KIND:P0:FILE`` (the ``--data`` option): ``drained:100kPa:tests/d100.csv``."""
    parts = spec.split(":", 2)
    if len(parts) != 3 or not all(p.strip() for p in parts):
        raise InputError(f"--data expects KIND:P0:FILE (e.g. drained:100kPa:d100.csv), got {spec!r}")
    kind, p0, file = (p.strip() for p in parts)
    if kind not in KINDS:
        raise InputError(f"--data {spec!r}: kind must be drained or undrained")
    return Test.from_csv(file, kind, parse_pressure(p0))
