"""Measured tests to calibrate on: biaxial (2D) or triaxial (3D) tests after isotropic
consolidation to p0, in hmodel's sign convention (compression positive)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io import read_csv_rows
from ..units import convert_columns, parse_pressure, unit_factor
from .kinds import Kind
from .lab import LabTest, check_void_ratio, is_database_file, parse_lab_reference, read_database

#: The names of the axial strain column a test file may use: hmodel's ``result.csv`` writes
#: eps11, a triaxial laboratory or DEM record eps_a.
AXIAL_COLUMNS = ("eps11", "eps_a")
#: An axial strain at least this large (half the specimen's height) is taken for a percentage:
#: a test to under 1 % written in percent, not one to 50 % written as a fraction.
PERCENT_LIKE = 0.5
#: The least peak |q| of a test, as a fraction of its p0: below it, q is taken to be in kPa.
Q_MIN = 0.01
#: The columns a test file's rows are read from; any other column may hold text.
USED_COLUMNS = (*AXIAL_COLUMNS, "q", "eps_v", "sigma_r", "sigma_v")


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
    e0 : float or None
        The specimen's void ratio after consolidation, when known (laboratory tests).
    """

    __test__ = False  # a calibration test, not a pytest class

    kind: Kind
    p0: float
    eps11: np.ndarray
    q: np.ndarray
    eps_v: np.ndarray | None = None
    name: str = ""
    e0: float | None = None

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
        _check_stress(label, float(self.p0), columns["q"])
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
    def from_lab(cls, t: LabTest) -> Test:
        """The test of a laboratory file (:mod:`hmodel.calibrate.lab`)."""
        return cls(t.kind, t.p0, t.eps_a, t.q, t.eps_v, name=t.name, e0=t.e0)

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
        raw = [h.strip() for h in rows[0]]
        header = [unit_factor(h)[0] for h in raw]
        if "q" not in header and {"sigma_v", "sigma_r"} <= set(header):
            header.append("q")  # derived below as sigma_v - sigma_r
        axial = [c for c in AXIAL_COLUMNS if c in header]
        if not axial or "q" not in header:
            missing = ", ".join(([] if axial else ["eps11 (or eps_a)"]) + ([] if "q" in header else ["q"]))
            raise InputError(f"{path}: missing column(s) {missing} (header: eps11,q[,eps_v][,p])")
        _check_dimension(path, kind, header)
        data = _numeric_columns(path, raw, rows[1:])
        col = convert_columns(raw, data, str(path))
        if "stage" in header:
            col = _after_consolidation(path, col, [r[header.index("stage")].strip() for r in rows[1:]])
        if len(axial) == 2 and not np.allclose(col["eps11"], col["eps_a"], rtol=1e-9, atol=1e-12):
            raise InputError(f"{path}: columns eps11 and eps_a both given and they differ: keep one")
        return cls(kind, p0, col[axial[0]], col["q"], col.get("eps_v"), name or path.stem)


def _numeric_columns(path: Path, header: list[str], rows: list[list[str]]) -> np.ndarray:
    """The rows as numbers, columns a test does not use (``stage``, ``point``) left as NaN when
    they hold text; a value that is not a number in a used column is named with its line."""
    used = {i for i, h in enumerate(header) if unit_factor(h)[0] in USED_COLUMNS}
    data = np.full((len(rows), len(header)), np.nan)
    for line, r in enumerate(rows, start=2):
        if len(r) != len(header):
            raise InputError(f"{path}, line {line}: expected {len(header)} values, got {len(r)}")
        for i, cell in enumerate(r):
            try:
                data[line - 2, i] = float(cell)
            except ValueError:
                if i in used:
                    raise InputError(f"{path}, line {line}: column {header[i]} must be a number, "
                                     f"got {cell.strip()[:40]!r}") from None
    if not len(rows):
        raise InputError(f"{path}: a header and no rows")
    return data


def _after_consolidation(path: Path, col: dict[str, np.ndarray], stages: list[str]) -> dict[str, np.ndarray]:
    """The rows of an hmodel ``result.csv`` (a ``stage`` column) from the end of consolidation
    on, strains measured from there: what a test file holds."""
    if "point" in col and len(np.unique(col["point"])) > 1:
        raise InputError(f"{path}: rows of {len(np.unique(col['point']))} material points (column point): "
                         f"keep one point's rows")
    iso = [i for i, s in enumerate(stages) if s == "consolidation"]
    start = iso[-1] if iso else 0
    out = {k: v[start:] for k, v in col.items()}
    for k in ("eps11", "eps_a", "eps_v"):
        if k in out and iso:
            out[k] = out[k] - out[k][0]
    return out


def _check_axial(label: str, kind: Kind, e: np.ndarray) -> None:
    """The axial strain runs away from 0 in the test's direction (compression positive), below
    1 in magnitude and below :data:`PERCENT_LIKE` (a larger one is a percentage, the message
    says); a file that does so with the other sign is in the tension-positive convention, and
    the message says so."""
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
    if s[-1] >= PERCENT_LIKE:
        raise InputError(f"{label}: eps11 reaches {e[-1]:g}, half the specimen's height or more: that looks "
                         f"like a percentage ({e[-1]:g} %), and hmodel's strains are fractions: divide the "
                         f"strain columns by 100, or give their unit in the header (eps11[%])")


def _check_stress(label: str, p0: float, q: np.ndarray) -> None:
    """Refuse a test whose q stays below :data:`Q_MIN` of its p0: a shear test's q reaches a
    good fraction of p0 (of the order of p0 in drained compression, a few tenths where an
    undrained test liquefies), and one a thousandth of it is a q in kPa against a p0 in Pa."""
    peak = float(np.abs(q).max())
    if peak < Q_MIN * p0:
        raise InputError(f"{label}: q peaks at {peak:.3g} Pa, {peak / p0:.2g} of p0 = {p0 / 1e3:g} kPa: "
                         f"that looks like kPa, and the file's stresses are in Pa: multiply q by 1000, or "
                         f"give its unit in the header (q[kPa])")


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
    """A test named on the command line (``--data``): ``KIND:P0:FILE[:e0=VALUE]`` for a test
    file (``triaxial-drained:100kPa:t100.csv:e0=0.81``), or ``FILE#TEST_ID`` for a test of a
    Sand Triaxial Test Database file, whose programme gives its kind, p0 and e0
    (``example:kfs#TMD12``)."""
    from ..examples import resolve

    ref = parse_lab_reference(spec) if not _is_kind_spec(spec) else None
    if ref is not None:
        file, test_id = ref
        return Test.from_lab(read_database(resolve(file)).test(test_id))
    parts = spec.split(":", 2)
    if len(parts) != 3 or not all(p.strip() for p in parts):
        raise InputError(f"--data expects KIND:P0:FILE[:e0=VALUE] or FILE#TEST_ID (e.g. drained:100kPa:d100.csv, "
                         f"example:kfs#TMD12), got {spec!r}")
    kind, p0, file = (p.strip() for p in parts)
    e0 = None
    if ":e0=" in file:
        file, _, text = file.rpartition(":e0=")
        try:
            e0 = float(text)
        except ValueError:
            raise InputError(f"--data {spec!r}: e0 must be a number, got {text!r}") from None
        check_void_ratio(e0, None, f"--data {spec!r}")
    try:
        kind = Kind.parse(kind)
    except InputError as e:
        raise InputError(f"--data {spec!r}: {e}") from None
    test = Test.from_csv(resolve(file), kind, _data_p0(spec, p0))
    return test if e0 is None else replace(test, e0=e0)


def _data_p0(spec: str, text: str) -> float:
    """The P0 of ``--data`` [Pa]: with its unit (``100kPa``), or a bare number in Pa, refused
    below :data:`~hmodel.units.BARE_PRESSURE_MIN` as every pressure of the command line is (a
    kPa value without its unit, most likely)."""
    return parse_pressure(text, f"--data {spec!r}: p0")


def _is_kind_spec(spec: str) -> bool:
    """Whether ``spec`` starts with a test kind (``KIND:P0:FILE``), where a # is the file's own."""
    return spec.split(":", 1)[0].strip() in {k.value for k in Kind}


def read_lab_tests(path: str, test_ids: list[str] | None = None, kind: str | None = None,
                   p0: float | None = None) -> tuple[list[LabTest], str]:
    """The tests of a laboratory file and its attribution (empty for a plain CSV): every test
    of a database file (or those of ``test_ids``), or the one test of a plain CSV whose
    headers may carry units, which needs its ``kind`` and ``p0`` [Pa] given."""
    from ..examples import resolve

    file = resolve(path)
    if is_database_file(file):
        if kind is not None or p0 is not None:
            raise InputError(f"{path}: a database file gives each test's kind and p0 in its test programme")
        db = read_database(file)
        return [db.test(t) for t in (test_ids or list(db.programme))], db.attribution
    if test_ids:
        raise InputError(f"{path}: --test needs a Sand Triaxial Test Database file (sections FILE_INFO, ...)")
    if kind is None or p0 is None:
        raise InputError(f"{path}: a plain CSV test needs its kind and p0 (--kind, --p0)")
    t = Test.from_csv(file, kind, p0)
    return [LabTest(t.name, t.kind, t.p0, t.e0, t.eps11, t.q, t.eps_v)], ""
