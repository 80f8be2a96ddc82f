"""Measured tests to calibrate on: biaxial (2D) or triaxial (3D) tests after isotropic
consolidation to p0, in hmodel's sign convention (compression positive)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io import read_csv_rows
from ..units import parse_pressure
from .kinds import Kind

#: The names of the axial strain column a test file may use: hmodel's ``result.csv`` writes
#: eps11, a triaxial laboratory or DEM record eps_a.
AXIAL_COLUMNS = ("eps11", "eps_a")


@dataclass(frozen=True)
class Test:
    """One test: its kind, its consolidation pressure p0 [Pa] and its rows.

    Attributes
    ----------
    kind : Kind (or its name)
        ``drained`` (σ22 held at p0) or ``undrained`` (isochoric) biaxial compression of the
        2D model; ``triaxial-drained``, ``triaxial-undrained`` or ``triaxial-extension`` of the
        3D model (:class:`~hmodel.calibrate.kinds.Kind`); always after isotropic consolidation
        to p0.
    p0 : float
        Consolidation pressure [Pa].
    eps11 : ndarray (n,)
        Axial strain since the end of consolidation, compression positive: increasing from
        >= 0 in compression, decreasing from <= 0 in extension.
    q : ndarray (n,)
        Deviatoric stress σ11 − σ22 (2D) or σa − σr = σ11 − (σ22 + σ33)/2 (3D) [Pa]; negative
        in extension.
    eps_v : ndarray (n,) or None
        Volumetric strain since the end of consolidation, contraction positive (drained tests).
    name : str
        A label for tables and figures.
    """

    __test__ = False  # a calibration test, not a pytest class

    kind: Kind
    p0: float
    eps11: np.ndarray
    q: np.ndarray
    eps_v: np.ndarray | None = None
    name: str = ""

    def __post_init__(self) -> None:
        kind = Kind.parse(self.kind)
        if not (np.isfinite(self.p0) and self.p0 > 0):
            raise InputError(f"test p0 must be a positive pressure, got {self.p0}")
        e = np.asarray(self.eps11, float)
        columns = {"eps11": e, "q": np.asarray(self.q, float)}
        if self.eps_v is not None:
            columns["eps_v"] = np.asarray(self.eps_v, float)
        label = self.name or f"{kind} {self.p0 / 1e3:g} kPa"
        for k, v in columns.items():
            if v.ndim != 1 or len(v) != len(e):
                raise InputError(f"{label}: column {k} must have one value per row")
            if not np.all(np.isfinite(v)):
                raise InputError(f"{label}: column {k} has non-finite values")
        if len(e) < 2:
            raise InputError(f"{label}: a test needs at least 2 rows, got {len(e)}")
        _check_axial(label, kind, e)
        object.__setattr__(self, "kind", kind)
        object.__setattr__(self, "eps11", e)
        object.__setattr__(self, "q", columns["q"])
        object.__setattr__(self, "eps_v", columns.get("eps_v"))
        object.__setattr__(self, "name", label)

    @property
    def strain(self) -> np.ndarray:
        """The axial strain's magnitude along the test, increasing from >= 0."""
        return self.kind.sign * self.eps11

    @property
    def q_scale(self) -> float:
        """The scale of the q residuals: the test's peak |q| [Pa]."""
        return float(max(np.abs(self.q).max(), 1e-12 * self.p0))

    @property
    def eps_v_scale(self) -> float:
        """The scale of the εv residuals: the range of the test's εv."""
        return float(max(np.ptp(self.eps_v), 1e-12)) if self.eps_v is not None else 1.0

    @classmethod
    def from_csv(cls, path, kind: str, p0: float, name: str = "") -> Test:
        """A test from a CSV with header ``eps11,q[,eps_v][,p]`` or ``eps_a,q[,eps_v][,p]``
        (other numeric columns are ignored): strains since the end of consolidation, stresses
        in Pa, compression positive (the columns of ``result.csv``). A 2D kind is refused on a
        file with 3D columns (eps33, sig33, s33, eps_a) and a 3D kind on a file with 2D ones
        only (a 22 component but no 33)."""
        path = Path(path)
        kind = Kind.parse(kind)
        rows = read_csv_rows(path, "test file")
        if not rows:
            raise InputError(f"{path}: empty file")
        header = [h.strip() for h in rows[0]]
        axial = [c for c in AXIAL_COLUMNS if c in header]
        if not axial or "q" not in header:
            missing = ", ".join(([] if axial else ["eps11 (or eps_a)"]) + ([] if "q" in header else ["q"]))
            raise InputError(f"{path}: missing column(s) {missing} (header: eps11,q[,eps_v][,p])")
        _check_dimension(path, kind, header)
        try:
            data = np.array([[float(x) for x in r] for r in rows[1:] if r], float)
        except ValueError:
            raise InputError(f"{path}: every value must be a number") from None
        if data.ndim != 2 or data.shape[0] == 0 or data.shape[1] != len(header):
            raise InputError(f"{path}: every row needs {len(header)} values")
        col = {h: data[:, i] for i, h in enumerate(header)}
        if len(axial) == 2 and not np.allclose(col["eps11"], col["eps_a"], rtol=1e-9, atol=1e-12):
            raise InputError(f"{path}: columns eps11 and eps_a both given and they differ: keep one")
        return cls(kind, p0, col[axial[0]], col["q"], col.get("eps_v"), name or path.stem)


def _check_axial(label: str, kind: Kind, e: np.ndarray) -> None:
    """The axial strain runs away from 0 in the test's direction (compression positive), below
    1 in magnitude; a file that does so with the other sign is in the tension-positive
    convention, and the message says so."""
    s = kind.sign * e
    if np.any(np.diff(s) <= 0) or s[0] < 0:
        way = "non-positive and decreasing (extension)" if kind.extension else "non-negative and increasing"
        hint = ""
        if np.all(np.diff(-s) > 0) and -s[0] >= 0:
            hint = ("; it runs the other way: hmodel's strains are compression positive "
                    "(YADE's and continuum mechanics' are tension positive: flip the signs of "
                    "eps11, q and eps_v)")
        raise InputError(f"{label}: eps11 must be {way}{hint}")
    if s[-1] >= 1:  # a strain of 1 leaves the specimen no height
        raise InputError(f"{label}: eps11 must stay below 1 in magnitude (a strain, not a "
                         f"percentage), reaches {e[-1]:g}")


def _check_dimension(path: Path, kind: Kind, header: list[str]) -> None:
    """Refuse a 2D kind on a file whose columns are a 3D test's, and the reverse."""
    three = [h for h in header if "33" in h or h == "eps_a"]
    two = [h for h in header if "22" in h]
    if kind.dim == 2 and three:
        raise InputError(f"{path}: kind {kind} is the 2D model's biaxial test but the file has 3D "
                         f"column(s) {', '.join(three)}: use a triaxial-... kind")
    if kind.dim == 3 and two and not three:
        raise InputError(f"{path}: kind {kind} is the 3D model's triaxial test but the file has 2D "
                         f"column(s) {', '.join(two)} and no 33 component: use drained or undrained")


def parse_data_spec(spec: str) -> Test:
    """``KIND:P0:FILE`` (the ``--data`` option): ``drained:100kPa:tests/d100.csv``,
    ``triaxial-drained:100kPa:tests/t100.csv``."""
    parts = spec.split(":", 2)
    if len(parts) != 3 or not all(p.strip() for p in parts):
        raise InputError(f"--data expects KIND:P0:FILE (e.g. drained:100kPa:d100.csv), got {spec!r}")
    kind, p0, file = (p.strip() for p in parts)
    try:
        kind = Kind.parse(kind)
    except InputError as e:
        raise InputError(f"--data {spec!r}: {e}") from None
    return Test.from_csv(file, kind, parse_pressure(p0))
