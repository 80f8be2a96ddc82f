"""Laboratory test files in: the Sand Triaxial Test Database's sectioned CSV files and plain
CSV files whose headers carry units, converted once, when read, to hmodel's units (stresses in
Pa, strains as fractions, compression positive for both).

The database (compiled by H. Wang, NGI; CC BY 4.0) keeps one file per material, in sections
that each open with a line ``# ===== [k] NAME =====`` followed by a CSV table with a header:
``FILE_INFO`` (``key,value``: ``format_version``, ``material_name``, ``license``, ...),
``SOURCES``, ``INDEX_PROPERTIES`` (``property,symbol,value,unit``: ``e_min``, ``e_max``, ...),
``PARTICLE_SIZE_DISTRIBUTION``, ``TEST_PROGRAMME`` (one row per test: ``test_id``,
``test_type``, ``drainage``, ``loading``, ``consolidation``, ``sigma_r0[kPa]``,
``sigma_v0[kPa]``, ``e_0[-]``, ...) and ``TEST_DATA``
(``test_id,eps_a[%],eps_v[%],sigma_r[kPa],sigma_v[kPa]``, compression positive). A test is
named ``FILE#TEST_ID``: its kind, consolidation pressure and void ratio come from the test
programme.

"""

from __future__ import annotations

import csv
import io
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..units import convert_columns, unit_factor
from .kinds import Kind

#: The database format versions this reader knows (the major version must match).
FORMAT_MAJOR = "1"
_SECTION = re.compile(r"^#\s*=+\s*\[\s*\d+\s*\]\s*([A-Z_ ]+?)\s*=+\s*$")

#: The database format versions this reader knows (the major version must match).
FORMAT_MAJOR = "1"
@dataclass(frozen=True)
class LabTest:
    """One laboratory test in hmodel's units: axial strain since consolidation ``eps_a``,
    deviatoric stress ``q`` = σv − σr [Pa], volumetric strain ``eps_v`` (contraction positive;
    None when not measured), at consolidation pressure ``p0`` [Pa] and void ratio ``e0``."""

    __test__ = False

    name: str
    kind: Kind
    p0: float
    e0: float | None
    eps_a: np.ndarray
    q: np.ndarray
    eps_v: np.ndarray | None


@dataclass(frozen=True)
class LabDatabase:
    """One material's file of the Sand Triaxial Test Database, read and checked.

    Attributes: ``path``; ``info`` (``FILE_INFO``: material name, licence, ...); ``sources``
    (rows of ``SOURCES``); ``index`` (symbol -> value of ``INDEX_PROPERTIES``); ``programme``
    (test id -> its row of ``TEST_PROGRAMME``); ``data`` (test id -> its rows of ``TEST_DATA``,
    in the file's units).
    """

    path: Path
    info: dict[str, str]
    sources: list[dict[str, str]]
    index: dict[str, float]
    programme: dict[str, dict[str, str]]
    data: dict[str, np.ndarray] = field(repr=False)
    data_header: list[str] = field(repr=False)

    @property
    def material(self) -> str:
        return self.info.get("material_name", self.path.stem)

    @property
    def void_ratio_range(self) -> tuple[float, float] | None:
        """The sand's (e_min, e_max) from its index properties, when the file gives both."""
        if "e_min" in self.index and "e_max" in self.index:
            return self.index["e_min"], self.index["e_max"]
        return None

    @property
    def attribution(self) -> str:
        """The licence and the sources, as the licence asks them to be cited."""
        cites = "; ".join(s.get("citation", "") for s in self.sources if s.get("citation"))
        by = self.info.get("compiled_by", "")
        return (f"{self.material}: Sand Triaxial Test Database{', compiled by ' + by if by else ''}, "
                f"licence {self.info.get('license', 'unknown')}. Sources: {cites}")

    def test(self, test_id: str) -> LabTest:
        """The test ``test_id`` in hmodel's units (a one-line InputError for an unknown id, a
        test whose loading hmodel does not run, or a void ratio outside e_min–e_max)."""
        if test_id not in self.programme:
            known = ", ".join(list(self.programme)[:8]) + (", ..." if len(self.programme) > 8 else "")
            raise InputError(f"{self.path.name}: no test {test_id!r} in the test programme (tests: {known})")
        row = self.programme[test_id]
        name = f"{self.path.name}#{test_id}"
        kind = _kind_of(row, name)
        try:
            sr, sv = float(row["sigma_r0[kPa]"]) * 1e3, float(row["sigma_v0[kPa]"]) * 1e3
        except (KeyError, ValueError):
            raise InputError(f"{name}: the test programme gives no sigma_r0[kPa] and sigma_v0[kPa]") from None
        e0 = _optional_float(row.get("e_0[-]", ""))
        if e0 is not None:
            check_void_ratio(e0, self.void_ratio_range, name)
        if test_id not in self.data:
            raise InputError(f"{name}: the file has no test data for it")
        cols = convert_columns(self.data_header[1:], self.data[test_id], name)
        missing = [c for c in ("eps_a", "q") if c not in cols]
        if missing:
            raise InputError(f"{name}: the test data lack {', '.join(missing)}")
        # p0 is the mean stress at the end of consolidation; the model consolidates isotropically
        return LabTest(name, kind, (sv + 2 * sr) / 3, e0, cols["eps_a"], cols["q"], cols.get("eps_v"))

    def tests(self) -> list[LabTest]:
        """Every test of the programme that hmodel can run, in the file's order."""
        return [self.test(t) for t in self.programme]


def check_void_ratio(e0: float, bounds: tuple[float, float] | None, where: str) -> None:
    """Refuse a void ratio that is not positive, or outside the sand's e_min–e_max."""
    if not (np.isfinite(e0) and e0 > 0):
        raise InputError(f"{where}: e0 must be a positive void ratio, got {e0:g}")
    if bounds is not None and not (bounds[0] <= e0 <= bounds[1]):
        raise InputError(f"{where}: e0 = {e0:g} lies outside the sand's e_min–e_max "
                         f"({bounds[0]:g}–{bounds[1]:g})")


def _optional_float(text: str) -> float | None:
    try:
        return float(text) if str(text).strip() else None
    except ValueError:
        return None


def _kind_of(row: dict[str, str], name: str) -> Kind:
    test_type = row.get("test_type", "").strip().lower()
    drainage = row.get("drainage", "").strip().lower()
    loading = row.get("loading", "monotonic").strip().lower() or "monotonic"
    consolidation = row.get("consolidation", "isotropic").strip().lower() or "isotropic"
    if loading != "monotonic":
        raise InputError(f"{name}: {loading} loading is not a test hmodel calibrates on (monotonic only)")
    if consolidation != "isotropic":
        raise InputError(f"{name}: {consolidation} consolidation: hmodel's tests start from an isotropic state")
    kinds = {("triaxial compression", "drained"): Kind.TRIAXIAL_DRAINED,
             ("triaxial compression", "undrained"): Kind.TRIAXIAL_UNDRAINED,
             ("triaxial extension", "drained"): Kind.TRIAXIAL_EXTENSION}
    if (test_type, drainage) not in kinds:
        raise InputError(f"{name}: a {drainage} {test_type} test is not one hmodel runs "
                         f"(drained or undrained triaxial compression, drained triaxial extension)")
    return kinds[test_type, drainage]


def _sections(path: Path) -> dict[str, list[list[str]]]:
    try:
        text = path.read_text(encoding="utf-8-sig")
    except OSError as e:
        raise InputError(f"cannot read laboratory file {str(path)!r}: {e.strerror}") from None
    except UnicodeDecodeError:
        raise InputError(f"laboratory file {str(path)!r} is not UTF-8 text") from None
    sections: dict[str, list[str]] = {}
    current = None
    for line in text.splitlines():
        m = _SECTION.match(line)
        if m:
            current = m.group(1).strip().replace(" ", "_")
            sections[current] = []
        elif current is not None and line.strip() and not line.lstrip().startswith("#"):
            sections[current].append(line)
    try:
        return {k: list(csv.reader(io.StringIO("\n".join(v)))) for k, v in sections.items()}
    except csv.Error as e:
        raise InputError(f"laboratory file {str(path)!r}: {e}") from None


def _records(rows: list[list[str]]) -> list[dict[str, str]]:
    if not rows:
        return []
    header = [h.strip() for h in rows[0]]
    return [dict(zip(header, (c.strip() for c in r))) for r in rows[1:]]


def is_database_file(path: "str | Path") -> bool:
    """Whether ``path`` opens as a file of the Sand Triaxial Test Database (its first section
    line is ``FILE_INFO``)."""
    try:
        with open(path, encoding="utf-8-sig") as fh:
            head = fh.read(4096)
    except (OSError, UnicodeDecodeError):
        return False
    return any((m := _SECTION.match(line)) and m.group(1).strip() == "FILE_INFO" for line in head.splitlines())


def read_database(path: "str | Path") -> LabDatabase:
    """One material's database file, its sections checked (a one-line InputError naming what
    is missing or of another format version)."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f"laboratory file {str(path)!r} is a folder")
    sections = _sections(path)
    missing = [s for s in ("FILE_INFO", "TEST_PROGRAMME", "TEST_DATA") if s not in sections]
    if missing:
        raise InputError(f"{path}: not a Sand Triaxial Test Database file (no section {', '.join(missing)})")
    info = {r.get("key", ""): r.get("value", "") for r in _records(sections["FILE_INFO"])}
    version = info.get("format_version", "")
    if version.split(".")[0] != FORMAT_MAJOR:
        raise InputError(f"{path}: database format version {version or '(none)'} is not one hmodel reads "
                         f"({FORMAT_MAJOR}.x)")
    index = {}
    for r in _records(sections.get("INDEX_PROPERTIES", [])):
        v = _optional_float(r.get("value", ""))
        if v is not None and r.get("symbol"):
            index[r["symbol"]] = v
    programme = {r["test_id"]: r for r in _records(sections["TEST_PROGRAMME"]) if r.get("test_id")}
    rows = sections["TEST_DATA"]
    if len(rows) < 2 or rows[0][0].strip() != "test_id":
        raise InputError(f"{path}: the TEST_DATA section needs a header starting with test_id and rows")
    header = [h.strip() for h in rows[0]]
    groups: dict[str, list[list[float]]] = {}
    for line, r in enumerate(rows[1:], start=2):
        if len(r) != len(header):
            raise InputError(f"{path}: TEST_DATA row {line} has {len(r)} values, the header {len(header)}")
        try:
            groups.setdefault(r[0].strip(), []).append([float(c) for c in r[1:]])
        except ValueError:
            raise InputError(f"{path}: TEST_DATA row {line}: every value after test_id must be a number") from None
    for h in header[1:]:
        unit_factor(h)  # an unknown unit is refused when read, not when a test is asked for
        if "[" not in h:
            raise InputError(f"{path}: TEST_DATA column {h!r} carries no unit (e.g. eps_a[%], sigma_r[kPa])")
    data = {k: np.array(v, float) for k, v in groups.items()}
    return LabDatabase(path, info, _records(sections.get("SOURCES", [])), index, programme, data, header)


def parse_lab_reference(spec: str) -> tuple[str, str] | None:
    """``FILE#TEST_ID`` as (file, test id), or None when ``spec`` is not of that form."""
    if "#" not in spec:
        return None
    file, _, test_id = spec.rpartition("#")
    if not file.strip() or not test_id.strip():
        raise InputError(f"expected FILE#TEST_ID (e.g. kfs.csv#TMD12), got {spec!r}")
    return file.strip(), test_id.strip()


def summary_rows(tests: list[LabTest]) -> list[dict[str, object]]:
    """One row per test: id, kind, p0 [kPa], e0, rows, final axial strain, peak q [kPa], final
    εv (fractions), q/p at the end (with p = p0 + q/3 in a drained compression test)."""
    rows = []
    for t in tests:
        end_q = float(t.q[-1])
        rows.append({"test": t.name, "kind": str(t.kind), "p0_kPa": t.p0 / 1e3,
                     "e0": "" if t.e0 is None else t.e0, "rows": len(t.eps_a),
                     "eps_a_end": float(t.eps_a[-1]), "q_peak_kPa": float(abs(t.q).max()) / 1e3,
                     "eps_v_end": "" if t.eps_v is None else float(t.eps_v[-1]),
                     "q_p_end": end_q / (t.p0 + end_q / 3) if t.kind is Kind.TRIAXIAL_DRAINED else ""})
    return rows


def write_test_csv(t: LabTest, path: Path) -> None:
    """A test in hmodel's test-file format: ``eps_a,q[,eps_v]`` in fractions and Pa."""
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["eps_a", "q"] + ([] if t.eps_v is None else ["eps_v"]))
        for i in range(len(t.eps_a)):
            # 12 digits keep a laboratory value's own digits without the binary noise of its conversion
            w.writerow([f"{t.eps_a[i]:.12g}", f"{t.q[i]:.12g}"] + ([] if t.eps_v is None else [f"{t.eps_v[i]:.12g}"]))
