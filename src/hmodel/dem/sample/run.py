"""A DEM sample to calibrate on: a 2D periodic assembly of polydisperse disks in YADE, consolidated
isotropically to p0 and sheared in a drained or undrained biaxial test.

:func:`run_sample` runs one test per pressure (resumable: a test whose CSV exists is not run
again) and writes, into one folder,

- ``{kind}_{p0}kPa.csv``: ``eps11,q,eps_v,p`` (axial and volumetric logarithmic strain since the
  end of the consolidation, compression positive; q = s11 - s22, p = (s11 + s22) / 2), the
  format of ``hmodel calibrate --data``;
- ``{kind}_{p0}kPa.npz``: every recorded row (also eps22, s11, s22, s12, unbalanced-force ratio,
  contact count) and the consolidated and final states (radii, positions, cell, contacts);
- ``sample.json``: the settings, the YADE version and one record per test (porosity, void
  ratio, coordination numbers, inertial number, servo accuracy, steps, wall times);
- ``sample.png``: the final packing of every test with its contact force chains.

:func:`run_test` runs one test and returns a :class:`SampleTest`. The YADE side is
:mod:`hmodel.dem.yade_sample` (read its docstring for the scene and the servo control), run
through :func:`hmodel.dem.yade.run_script`.

Units and the 2D convention: lengths in m, forces in N, kn in N/m; stresses are the 2D
Love-Weber stress (1/A) sum f (x) l over the contacts, A the cell's area, in N/m (Pa m: Pa for a
sample of unit thickness), as hmodel's DEM cells (:mod:`hmodel.dem.stress`). Masses are those of
disks of unit thickness, ``density`` pi r^2, and the inertial number is
I = strain rate x mean diameter x sqrt(density / p).
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import InputError
from ..io import write_outputs
from .yade import DEMError, run_script

SCRIPT = Path(__file__).with_name("yade_sample.py")
KINDS = ("drained", "undrained")
DISTRIBUTIONS = ("uniform", "equal-area")
#: Columns of the test CSV (the ``--data`` format of ``hmodel calibrate``).
CSV_COLUMNS = ("eps11", "q", "eps_v", "p")
#: Columns of a recorded row (``rows`` of the npz file).
ROW_COLUMNS = ("eps11", "eps22", "s11", "s22", "s12", "unbalanced", "contacts")
#: Columns of a contact row: grain indices, normal force (compression positive), tangential
#: force f.(e_y, -e_x), branch vector l from i to j (across the periodic boundary if need be);
#: f is the force on j by i, e = l / |l|.
CONTACT_COLUMNS = ("i", "j", "fn", "ft", "lx", "ly")
#: Settings that may differ between the runs that fill one folder.
RESUME_FREE = ("timeout",)


@dataclass(frozen=True)
class SampleSettings:
    """Everything that defines a sample and its tests, except the tests' kind and p0.

    Attributes
    ----------
    disks : int
        Number of disks.
    radius : float
        Mean of r_min and r_max [m].
    radius_ratio : float
        r_max / r_min (1: monodisperse).
    distribution : str
        ``uniform`` (radius uniform in [r_min, r_max]) or ``equal-area`` (density proportional
        to r^-2: every radius interval holds the same solid area).
    kn : float
        Normal contact stiffness [N/m].
    kt_kn : float
        kt / kn.
    phi_g : float
        Contact friction angle during the test [deg].
    compaction_friction : float or None
        Contact friction angle during the consolidation [deg]; None: 0 (the densest sample),
        or phi_g when ``porosity`` is given.
    porosity : float or None
        Target porosity: the consolidation starts with ``compaction_friction`` and lowers the
        friction (tan phi x 0.9 per step, each followed by a new equilibrium at p0) until the
        porosity is at most this.
    density : float
        Grain density [kg/m^3] (disks of unit thickness).
    axial_strain : float
        Axial strain of the test (logarithmic).
    rows : int
        Rows of the CSV after its first (eps11 = 0): one every axial_strain / rows.
    inertial_number : float
        Sets the axial strain rate, strain_rate = I / (d_mean sqrt(density / p0)).
    strain_rate : float or None
        The axial strain rate [1/s], instead of ``inertial_number``.
    seed : int
        Seed of the radii and initial positions.
    damping : float
        Cundall's non-viscous damping of NewtonIntegrator.
    dt_safety : float
        Time step = dt_safety sqrt(m_min / kn).
    tol_stress, tol_unbalanced : float
        The consolidation ends when |s_ii - p0| <= tol_stress p0 and the unbalanced-force ratio
        is at most tol_unbalanced.
    compaction_inertial_number : float
        The largest strain rate of the consolidation, as an inertial number at p0.
    period : int
        Time steps between two servo updates.
    check : int
        Time steps between two checks of the consolidation's criterion.
    gain, gain_i : float
        Proportional and integral gains of the servo (dimensionless, relative to the affine
        stiffness).
    lateral_rate_factor : float
        The drained lateral strain rate is at most this times the axial one.
    max_steps : int
        Time steps allowed for the consolidation.
    timeout : float
        Wall-clock limit of one test's YADE run [s].
    """

    disks: int = 2000
    radius: float = 1.0
    radius_ratio: float = 2.0
    distribution: str = "uniform"
    kn: float = 2.0e8
    kt_kn: float = 0.5
    phi_g: float = 30.0
    compaction_friction: float | None = None
    porosity: float | None = None
    density: float = 2650.0
    axial_strain: float = 0.1
    rows: int = 100
    inertial_number: float = 1e-4
    strain_rate: float | None = None
    seed: int = 0
    damping: float = 0.2
    dt_safety: float = 0.3
    tol_stress: float = 1e-3
    tol_unbalanced: float = 1e-3
    compaction_inertial_number: float = 1e-2
    period: int = 5
    check: int = 50
    gain: float = 0.5
    gain_i: float = 0.1
    lateral_rate_factor: float = 10.0
    max_steps: int = 5_000_000
    timeout: float = 3600.0

    def __post_init__(self) -> None:
        def finite(name):
            v = getattr(self, name)
            return v is not None and isinstance(v, (int, float)) and math.isfinite(v)

        for name in ("radius", "radius_ratio", "kn", "kt_kn", "density", "axial_strain",
                     "inertial_number", "tol_stress", "tol_unbalanced",
                     "compaction_inertial_number", "gain", "lateral_rate_factor", "timeout"):
            if not (finite(name) and getattr(self, name) > 0):
                raise InputError(f"{_option(name)} must be a positive number, got {getattr(self, name)}")
        if self.disks < 20:
            raise InputError(f"--disks must be at least 20, got {self.disks}")
        if self.radius_ratio < 1:
            raise InputError(f"--radius-ratio must be >= 1 (r_max / r_min), got {self.radius_ratio}")
        if self.distribution not in DISTRIBUTIONS:
            raise InputError(f"--distribution must be one of {', '.join(DISTRIBUTIONS)}, "
                             f"got {self.distribution!r}")
        if not (finite("phi_g") and 0 < self.phi_g < 90):
            raise InputError(f"--phi-g must lie in (0, 90) degrees, got {self.phi_g}")
        if self.compaction_friction is not None and not (
                finite("compaction_friction") and 0 <= self.compaction_friction < 90):
            raise InputError(f"--compaction-friction must lie in [0, 90) degrees, got "
                             f"{self.compaction_friction}")
        if self.porosity is not None and not (finite("porosity") and 0 < self.porosity < 1):
            raise InputError(f"--porosity must lie in (0, 1), got {self.porosity}")
        if self.porosity is not None and self.compaction_friction == 0:
            raise InputError("--porosity lowers the friction from --compaction-friction, which "
                             "must then be above 0")
        if self.axial_strain >= 1:
            raise InputError(f"--axial-strain must be below 1, got {self.axial_strain}")
        if self.seed < 0:
            raise InputError(f"--seed must be >= 0, got {self.seed}")
        if self.rows < 1:
            raise InputError(f"--rows must be a positive integer, got {self.rows}")
        if self.strain_rate is not None and not (finite("strain_rate") and self.strain_rate > 0):
            raise InputError(f"--strain-rate must be a positive number, got {self.strain_rate}")
        if not (0 <= self.damping < 1 and 0 < self.dt_safety <= 1 and 0 < self.gain_i
                and self.period >= 1 and self.check >= 1 and self.max_steps >= 1):
            raise InputError(f"invalid numerical settings of the DEM sample: {self}")

    @property
    def r_min(self) -> float:
        return 2.0 * self.radius / (1.0 + self.radius_ratio)

    @property
    def r_max(self) -> float:
        return self.radius_ratio * self.r_min

    @property
    def friction_compact(self) -> float:
        """Friction angle of the consolidation [deg]."""
        if self.compaction_friction is not None:
            return self.compaction_friction
        return self.phi_g if self.porosity is not None else 0.0

    def to_dict(self) -> dict:
        return asdict(self)


def _option(name: str) -> str:
    return "--" + name.replace("_", "-")


def file_stem(kind: str, p0: float) -> str:
    """File stem of a test: ``drained_100kPa``."""
    return f"{kind}_{p0 / 1e3:g}kPa"


def radii(settings: SampleSettings, rng: np.random.Generator) -> np.ndarray:
    """The disks' radii, in random order."""
    a, b = settings.r_min, settings.r_max
    u = rng.random(settings.disks)
    if settings.distribution == "uniform" or a == b:
        return a + (b - a) * u
    return 1.0 / (1.0 / a - u * (1.0 / a - 1.0 / b))  # equal-area: pdf ~ r^-2


def initial_packing(settings: SampleSettings) -> tuple[np.ndarray, np.ndarray, tuple[float, float]]:
    """(radii, centres (n, 2), (Lx, Ly)): a granular gas, every disk inside its own square of a
    jittered lattice of spacing 2.1 r_max (no overlap), in random sites."""
    rng = np.random.default_rng(settings.seed)
    r = radii(settings, rng)
    n = settings.disks
    nx = math.ceil(math.sqrt(n))
    ny = math.ceil(n / nx)
    s = 2.1 * settings.r_max
    sites = rng.permutation(nx * ny)[:n]
    ij = np.stack([sites % nx, sites // nx], axis=1).astype(float)
    slack = (0.5 * s - r)[:, None]
    pos = (ij + 0.5) * s + rng.uniform(-1.0, 1.0, (n, 2)) * slack
    return r, pos, (nx * s, ny * s)


def mean_diameter(r: np.ndarray) -> float:
    return float(2.0 * np.mean(r))


def strain_rate(settings: SampleSettings, p0: float, d_mean: float) -> float:
    """Axial strain rate of a test at p0 [1/s]."""
    if settings.strain_rate is not None:
        return settings.strain_rate
    return settings.inertial_number / (d_mean * math.sqrt(settings.density / p0))


def inertial_number(rate: float, d_mean: float, density: float, p: float) -> float:
    """I = rate d_mean sqrt(density / p)."""
    return rate * d_mean * math.sqrt(density / p) if p > 0 else math.inf


@dataclass(frozen=True)
class SampleState:
    """A state of the sample: cell size (Lx, Ly), radii, centres wrapped into the cell, contacts
    (columns :data:`CONTACT_COLUMNS`)."""

    cell: tuple[float, float]
    radii: np.ndarray
    positions: np.ndarray
    contacts: np.ndarray = field(repr=False)

    @classmethod
    def from_json(cls, d: dict) -> "SampleState":
        return cls(cell=(float(d["cell"][0]), float(d["cell"][1])),
                   radii=np.asarray(d["radii"], float),
                   positions=np.asarray(d["pos"], float).reshape(-1, 2),
                   contacts=np.asarray(d["contacts"], float).reshape(-1, len(CONTACT_COLUMNS)))

    @property
    def area(self) -> float:
        return self.cell[0] * self.cell[1]

    @property
    def porosity(self) -> float:
        return 1.0 - float(np.sum(math.pi * self.radii ** 2)) / self.area

    @property
    def void_ratio(self) -> float:
        n = self.porosity
        return n / (1.0 - n)

    def contact_counts(self) -> np.ndarray:
        """Contacts of every disk."""
        c = self.contacts[:, :2].astype(int).ravel()
        return np.bincount(c, minlength=len(self.radii))

    @property
    def coordination(self) -> float:
        """z = 2 C / N over all disks."""
        return 2.0 * len(self.contacts) / len(self.radii)

    @property
    def rattlers(self) -> float:
        """Fraction of disks with fewer than 2 contacts."""
        return float(np.mean(self.contact_counts() < 2))

    @property
    def mechanical_coordination(self) -> float:
        """z without the rattlers (disks with 0 or 1 contact) and their contacts."""
        counts = self.contact_counts()
        keep = counts >= 2
        i, j = self.contacts[:, 0].astype(int), self.contacts[:, 1].astype(int)
        both = keep[i] & keep[j]
        return 2.0 * int(np.sum(both)) / max(int(np.sum(keep)), 1)

    def forces(self) -> np.ndarray:
        """Contact forces on j by i, (c, 2) [N]."""
        fn, ft, l = self.contacts[:, 2], self.contacts[:, 3], self.contacts[:, 4:6]
        e = l / np.linalg.norm(l, axis=1)[:, None]
        t = np.stack([e[:, 1], -e[:, 0]], axis=1)
        return fn[:, None] * e + ft[:, None] * t

    def stress(self) -> np.ndarray:
        """2D Love-Weber stress (1/A) sum f (x) l, compression positive, (2, 2) [N/m]."""
        return np.einsum("ca,cb->ab", self.forces(), self.contacts[:, 4:6]) / self.area

    def summary(self) -> dict:
        return {"porosity": self.porosity, "void_ratio": self.void_ratio,
                "coordination": self.coordination,
                "mechanical_coordination": self.mechanical_coordination,
                "rattlers": self.rattlers, "contacts": len(self.contacts),
                "cell": list(self.cell)}

    def arrays(self, prefix: str) -> dict[str, np.ndarray]:
        return {f"{prefix}_cell": np.asarray(self.cell), f"{prefix}_positions": self.positions,
                f"{prefix}_contacts": self.contacts}


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


def run_test(settings: SampleSettings, kind: str, p0: float) -> SampleTest:
    """Build the sample, consolidate it to p0 and run one biaxial test in YADE.

    Raises
    ------
    InputError
        Bad kind or p0; a target porosity out of reach.
    DEMError
        YADE missing, crashed or timed out; EquilibriumError when the consolidation does not
        reach p0 in equilibrium within ``max_steps``.
    """
    if kind not in KINDS:
        raise InputError(f"test kind must be drained or undrained, got {kind!r}")
    if not (isinstance(p0, (int, float)) and math.isfinite(p0) and p0 > 0):
        raise InputError(f"p0 must be a positive pressure, got {p0}")
    r, pos, cell = initial_packing(settings)
    d_mean = mean_diameter(r)
    rate = strain_rate(settings, p0, d_mean)
    spec = {
        "radii": r.tolist(), "pos": pos.tolist(), "cell": list(cell),
        "kn": settings.kn, "kt_kn": settings.kt_kn, "phi_g": math.radians(settings.phi_g),
        "phi_compact": math.radians(settings.friction_compact), "porosity": settings.porosity,
        "density": settings.density, "damping": settings.damping, "dt_safety": settings.dt_safety,
        "p0": p0, "kind": kind, "strain_rate": rate, "axial_strain": settings.axial_strain,
        "rows": settings.rows,
        "rate_compact": settings.compaction_inertial_number / (d_mean * math.sqrt(settings.density / p0)),
        "period": settings.period, "check": settings.check, "gain": settings.gain,
        "gain_i": settings.gain_i, "lateral_rate_factor": settings.lateral_rate_factor,
        "tol_stress": settings.tol_stress, "tol_unbalanced": settings.tol_unbalanced,
        "max_steps": settings.max_steps,
    }
    t0 = time.perf_counter()
    try:
        out = run_script(SCRIPT.read_text(), spec, timeout=settings.timeout)
    except DEMError as e:
        if "target porosity" in str(e):
            raise InputError(str(e).removeprefix("DEM: ")) from None
        raise
    wall = time.perf_counter() - t0
    rows = np.asarray(out["rows"], float).reshape(-1, len(ROW_COLUMNS))
    p_min = float(np.min(0.5 * (rows[:, 2] + rows[:, 3])))
    info = {"strain_rate": rate, "mean_diameter": d_mean,
            "inertial_number": inertial_number(rate, d_mean, settings.density, p0),
            "inertial_number_max": inertial_number(rate, d_mean, settings.density, p_min),
            "dt": out["dt"], "consolidation_steps": out["consolidation"]["steps"],
            "consolidation_friction_deg": out["consolidation"]["friction_deg"],
            "shear_steps": out["shear"]["steps"],
            "wall_s": wall, "consolidation_wall_s": out["consolidation"]["wall_s"],
            "shear_wall_s": out["shear"]["wall_s"], "yade_version": out["yade_version"]}
    return SampleTest(kind=kind, p0=float(p0), rows=rows,
                      consolidated=SampleState.from_json(out["consolidated"]),
                      final=SampleState.from_json(out["final"]), info=info)


def draw_sample(states: list[tuple[str, SampleState]], path: "str | os.PathLike") -> None:
    """The packings side by side: disks, and contacts as lines from centre to centre whose
    width and colour follow the normal force (force chains); contacts across the periodic
    boundary are drawn from both ends."""
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.collections import LineCollection, PatchCollection
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle, Rectangle

    n = max(len(states), 1)
    cols = min(n, 3)
    nrows = math.ceil(n / cols)
    fig = Figure(figsize=(5.2 * cols, 5.0 * nrows), layout="constrained")
    axes = np.atleast_1d(fig.subplots(nrows, cols, squeeze=False)).ravel()
    cmap = colormaps["inferno_r"]
    for ax, (title, st) in zip(axes, states):
        lx, ly = st.cell
        ax.add_collection(PatchCollection([Circle(p, r) for p, r in zip(st.positions, st.radii)],
                                          facecolor="#e4e4e4", edgecolor="#aaaaaa", lw=0.2))
        c = st.contacts
        fn = np.clip(c[:, 2], 0.0, None)
        fmean = float(np.mean(fn)) if len(fn) and np.mean(fn) > 0 else 1.0
        i = c[:, 0].astype(int)
        j = c[:, 1].astype(int)
        a = st.positions[i]
        b = st.positions[j]
        segs = np.concatenate([np.stack([a, a + c[:, 4:6]], axis=1),
                               np.stack([b - c[:, 4:6], b], axis=1)])
        crossing = np.concatenate([np.zeros(len(c), bool),
                                   np.linalg.norm(a + c[:, 4:6] - b, axis=1) > 1e-9 * max(lx, ly)])
        keep = np.concatenate([np.ones(len(c), bool), np.zeros(len(c), bool)]) | crossing
        f2 = np.concatenate([fn, fn])[keep]
        norm = Normalize(0.0, 3.0 * fmean)
        thin = min(1.0, max(0.2, 14.0 / math.sqrt(len(st.radii))))  # finer lines for many disks
        lc = LineCollection(segs[keep], colors=cmap(norm(f2)),
                            linewidths=thin * (0.3 + 2.5 * np.clip(f2 / (3 * fmean), 0, 1.5)))
        ax.add_collection(lc)
        ax.add_patch(Rectangle((0, 0), lx, ly, fill=False, ec="k", lw=0.8))
        ax.set_xlim(-0.02 * lx, 1.02 * lx)
        ax.set_ylim(-0.02 * ly, 1.02 * ly)
        ax.set_aspect("equal")
        ax.set_xlabel("x (axis 1) [m]")
        ax.set_ylabel("y (axis 2) [m]")
        ax.set_title(title, fontsize=9)
        fig.colorbar(ScalarMappable(cmap=cmap, norm=norm), ax=ax, shrink=0.8,
                     label="normal contact force [N]")
    for ax in axes[len(states):]:
        ax.set_axis_off()
    fig.savefig(path, dpi=110 if max(len(st.radii) for _, st in states) <= 1000 else 160)


def _read_json(path: Path) -> dict | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _load_state(path: Path) -> SampleState | None:
    if not path.exists():
        return None
    with np.load(path) as z:
        return SampleState(cell=tuple(float(v) for v in z["final_cell"]), radii=z["radii"],
                           positions=z["final_positions"], contacts=z["final_contacts"])


def _title(rec: dict, st: SampleState) -> str:
    return (f"{rec['kind']} {rec['p0'] / 1e3:g} kPa, eps11 = {100 * rec['axial_strain']:g} %: "
            f"n = {st.porosity:.3f}, z = {st.coordination:.2f}")


def run_sample(settings: SampleSettings, pressures: list[float], kind: str,
               out: "str | os.PathLike",
               progress: Callable[[str], None] | None = None) -> dict:
    """Run a test of ``kind`` at every pressure into ``out`` (see the module docstring); a test
    whose CSV is already in ``out`` is skipped. Returns the contents of sample.json.

    A folder written with other settings is refused (InputError), so that every test of a
    sample.json shares one sample; each test's files appear together, once it has succeeded.
    """
    if kind not in KINDS:
        raise InputError(f"test kind must be drained or undrained, got {kind!r}")
    if not pressures:
        raise InputError("no pressure given")
    for p0 in pressures:
        if not (math.isfinite(p0) and p0 > 0):
            raise InputError(f"p0 must be a positive pressure, got {p0}")
    names = [file_stem(kind, p0) for p0 in pressures]
    if len(set(names)) != len(names):
        raise InputError("the pressures must differ (to 1 Pa): " + ", ".join(names))
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"output path {str(out)!r} exists and is not a folder")
    wanted = settings.to_dict()
    meta = _read_json(out / "sample.json")
    if meta is not None:
        old = meta.get("settings", {})
        diff = sorted(k for k in set(old) | set(wanted)
                      if k not in RESUME_FREE and old.get(k) != wanted.get(k))
        if diff:
            raise InputError(f"{out} holds a sample with other settings "
                             f"({', '.join(_option(k) for k in diff)}): use another --out")
    elif out.is_dir() and any((out / f"{n}.csv").exists() for n in names):
        raise InputError(f"{out} has test CSVs but no readable sample.json: use another --out")
    meta = meta or {"settings": wanted, "yade_version": None, "tests": {}}
    meta["settings"] = wanted
    for p0, name in zip(pressures, names):
        if (out / f"{name}.csv").exists():
            if name not in meta["tests"]:
                raise InputError(f"{out / (name + '.csv')} is not described by "
                                 f"{out / 'sample.json'}: remove it or use another --out")
            if progress:
                progress(f"{name}: {name}.csv exists, skipped")
            continue
        test = run_test(settings, kind, p0)
        rec = test.summary()
        rec["axial_strain"] = settings.axial_strain
        meta["tests"][name] = rec
        meta["yade_version"] = test.info["yade_version"]
        meta["tests"] = dict(sorted(meta["tests"].items(), key=lambda kv: (kv[1]["kind"], kv[1]["p0"])))

        def draw(path: Path, meta=meta, test=test, name=name) -> None:
            states = []
            for n, r in meta["tests"].items():
                st = test.final if n == name else _load_state(out / f"{n}.npz")
                if st is not None:  # an npz removed by hand: its panel is left out
                    states.append((_title(r, st), st))
            draw_sample(states, path)

        # the CSV last: a test whose CSV exists has all its files
        write_outputs(out, {f"{name}.npz": test.write_npz,
                            "sample.json": lambda p, meta=meta: p.write_text(json.dumps(meta, indent=1)),
                            "sample.png": draw,
                            f"{name}.csv": test.write_csv})
        if progress:
            progress(f"{name}: {len(test.rows)} rows, peak q {rec['peak_q'] / 1e3:.4g} kPa, "
                     f"porosity {rec['consolidated']['porosity']:.4f}, z "
                     f"{rec['consolidated']['coordination']:.3f}, I {rec['inertial_number']:.2g}, "
                     f"YADE {rec['wall_s']:.1f} s")
    return meta
