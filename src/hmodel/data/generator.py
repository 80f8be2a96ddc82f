"""Rows of the two H-cell databases of report §2.3, computed shard by shard from the cell solver.

A *path* is one cell loaded monotonically from its initial state (l1 = l10, l2 = l20, no force)
along a direction θ of the (ε1, ε2) plane, with θ on a grid over [0, 90°] (the report's
compression quadrant; ``theta_min``/``theta_max`` widen it, e.g. to [0, 360°) so that start
states include cells in extension, opened or unloading, as in a REV) and the initial opening
angle α0 on a grid over its admissible range. Path ``path_id = j * n_directions + i``
has α0 number j and θ number i.

- **Dataset 1**: every path in steps of ``step`` up to ``max_strain``; row k holds the initial
  state, the total strain so far (k·step·(cos θ, sin θ)) and the state reached.
- **Dataset 2**: from the states of every path at every ``start_every`` of strain, increments of
  magnitude ``magnitude`` in ``n_increments`` directions over [0, 2π), each applied in
  ``substeps`` equal sub-steps. With ``magnitude_min``, the magnitudes are spread over
  [magnitude_min, magnitude] instead (the surrogate of the ANN-based REV needs small increments).
- **Dataset 3** (REV histories): the increments of Dataset 2, from the states a REV's own cells
  pass through on biaxial paths (``rev_paths``, e.g. ``drained:50e3,undrained:150e3``): a REV of
  ``n_directions`` cells of opening angle ``params.alpha0`` and the solver's cells, consolidated to
  p0 in isotropic steps of ``step``/5, then sheared in axial steps of ``step`` to ``max_strain``;
  its cells' states every ``start_every`` of axial strain (and the consolidated state, with
  ``from_unloaded``) start the increments. A cell's strain path in a REV bends where the
  consolidation turns into shear and again as the cell dilates or opens, states that no
  proportional path of one cell reaches. One shard is one loading path; ``path_id`` is
  ``loading * n_directions + cell``, ``theta`` the cell's direction in the REV and
  ``start_strain`` the axial strain since consolidation; the α0 and θ grids and ``prestrain``
  do not apply.

**3D rows** (``dim = 3``): Dataset 2 of the bi-hexagon of the 3D H-model
(docs/model3d.md), solved in closed form (``BiHexSolver``): path ``path_id`` loads a
bi-hexagon of opening angle α0 along the cell-strain direction (cos θ, sin θ cos ψ, sin θ sin ψ)
of its three lengths (l1 along n, l2 and l3 the two hexagons' columns), ψ ∈ [0, π/2] spread over
the paths by the golden-ratio sequence (so that the two hexagons see different lateral
strains); from its states every ``start_every``, increments of the spec's magnitudes in
``n_increments`` directions of (δε1, δε2, δε3) on the unit sphere (a Fibonacci lattice), in
``substeps`` sub-steps. Columns: :data:`~hmodel.data.schema.COLUMNS_3D`. Small defaults:
:data:`~hmodel.data.kinds.DIM3_DEFAULTS`. Dataset 2 only, closed form only.

Each kind of rows (the three datasets, the 3D rows) is one class of :mod:`hmodel.data.kinds`,
which :class:`DatasetSpec` finds from its ``kind`` and ``dim`` (the numbers manifests store).

Cell strains are measured on the initial lengths, compression positive: δl = −(l10, l20)·δε.
A shard is a contiguous range of paths, so that any shard can be computed alone, in any
process, and always gives the same rows.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

import numpy as np
import pyarrow as pa

from ..errors import InputError
from ..params import Params
from ..solvers import get_solver
from . import kinds
from .kinds import DIM3_DEFAULTS, DatasetKind  # noqa: F401 (DIM3_DEFAULTS: importers of its first home)
from .rows import increment_rows, table as _table  # noqa: F401 (importers of their first home)

#: The REV loading paths of Dataset 3.
REV_LOADINGS = ("drained", "undrained")
#: Golden ratio's fractional part: the low-discrepancy sequences of ψ and of the sphere lattice.
_GOLDEN = 0.6180339887498949


@dataclass(frozen=True)
class DatasetSpec:
    """Generator options of one database; the defaults reproduce the report's scale.

    Angles in degrees here (as on the command line); rows store radians.
    """

    #: The dataset: 1, 2 or 3 (the kinds of rows are :mod:`hmodel.data.kinds`).
    kind: int = 1
    n_directions: int = 91
    theta_min: float = 0.0
    theta_max: float = 90.0
    alpha0_min: float = 32.0
    alpha0_max: float = 88.0
    alpha0_step: float = 2.0
    max_strain: float = 0.30
    step: float = 0.001
    start_every: float = 0.01
    magnitude: float = 0.01
    magnitude_min: float | None = None
    n_increments: int = 168
    substeps: int = 10
    shard_rows: int = 250_000
    solver: str = "closed-form"
    #: Dataset 2: the unloaded cell is a start state too (the report's starts are loaded states;
    #: a learned response must also know the first increments from rest, where every REV starts).
    from_unloaded: bool = False
    #: Cell strain e1 = e2 = prestrain (steps of ``step``) applied to every cell before its path,
    #: as a REV's isotropic consolidation does; the path, its start states and ``start_strain``
    #: begin there (the "unloaded" start of ``from_unloaded`` is then the consolidated cell).
    prestrain: float = 0.0
    #: Dataset 3: the REV's loading paths, ``drained:P0`` or ``undrained:P0`` [Pa], comma-separated.
    rev_paths: str = ""
    #: 2: H-cell rows; 3: bi-hexagon rows of the 3D H-model (Dataset 2, closed form only).
    dim: int = 2
    #: A material per path (for networks over a range of materials): ``"LO:HI"`` ranges of
    #: kt/kn and of φg [deg], each path's value drawn uniformly from them by a generator seeded
    #: with (``material_seed``, path id), so that a path's material does not depend on the shard
    #: it falls in; "" keeps the parameters' value. Rows record it (MATERIAL_COLUMNS).
    kt_kn_range: str = ""
    phi_g_range: str = ""
    material_seed: int = 0

    def __post_init__(self) -> None:
        # One spelling per value (45 and 45.0 alike), so that manifests and shard bytes match.
        for f in fields(self):
            v = getattr(self, f.name)
            if "float" in str(f.type) and isinstance(v, (int, float)) and not isinstance(v, bool):
                object.__setattr__(self, f.name, float(v))
        rows = self.dataset_kind  # refuses an unknown kind or dimension
        if self.draws_material and not rows.material_per_path:
            raise InputError("a material per path (--kt-kn, --phi-g ranges) is drawn for 2D datasets only")
        self.material_ranges  # parses and checks
        rows.check(self, get_solver(self.solver))  # the rows its solver makes: its declarations
        self.rev_loadings  # parses and checks
        for name in ("n_directions", "n_increments", "substeps", "shard_rows"):
            v = getattr(self, name)
            if not isinstance(v, int) or v < 1:
                raise InputError(f"{name} must be a positive integer, got {v!r}")
        for name in ("alpha0_step", "max_strain", "step", "start_every", "magnitude"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise InputError(f"{name} must be a positive finite number, got {v!r}")
        if not (math.isfinite(self.theta_min) and math.isfinite(self.theta_max)
                and self.theta_min <= self.theta_max <= self.theta_min + 360.0):
            raise InputError(f"theta range must satisfy min <= max <= min + 360 deg, got "
                             f"{self.theta_min}:{self.theta_max}")
        if not 30.0 < self.alpha0_min <= self.alpha0_max < 90.0:
            raise InputError(f"alpha0 range must lie in (30, 90) deg with min <= max, got "
                             f"{self.alpha0_min}:{self.alpha0_max}")
        if self.magnitude_min is not None and not 0.0 <= self.magnitude_min <= self.magnitude:
            raise InputError(f"magnitude_min must lie in [0, magnitude], got {self.magnitude_min}")
        if self.prestrain < 0:
            raise InputError(f"prestrain must be positive or zero, got {self.prestrain}")
        if self.prestrain:
            _ratio(self.prestrain, self.step, "prestrain", "step")
        if self.max_strain >= 1.0:
            raise InputError(f"max_strain must be below 1, got {self.max_strain}")
        _ratio(self.max_strain, self.step, "max_strain", "step")
        if rows.increments:
            _ratio(self.start_every, self.step, "start_every", "step")
            _ratio(self.max_strain, self.start_every, "max_strain", "start_every")

    @property
    def dataset_kind(self) -> DatasetKind:
        """The kind of its rows (:mod:`hmodel.data.kinds`), from ``kind`` and ``dim``."""
        return kinds.dataset_kind(self.kind, self.dim)

    # -- materials ---------------------------------------------------------------------------
    @property
    def draws_material(self) -> bool:
        """Whether every path draws its own material (:attr:`kt_kn_range`, :attr:`phi_g_range`)."""
        return bool(self.kt_kn_range.strip() or self.phi_g_range.strip())

    @property
    def material_ranges(self) -> dict[str, tuple[float, float]]:
        """The drawn parameters' ranges, ``{"kt_kn": (lo, hi), "phi_g": (lo, hi) [deg]}`` (those
        given)."""
        out = {}
        for name, text, ok in (("kt_kn", self.kt_kn_range, lambda v: v > 0),
                               ("phi_g", self.phi_g_range, lambda v: 0 < v < 90)):
            if not text.strip():
                continue
            try:
                lo, hi = (float(v) for v in text.split(":"))
            except ValueError:
                lo = hi = float("nan")
            if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi and ok(lo) and ok(hi)):
                raise InputError(f"the range of {name} is LO:HI with LO <= HI (kt_kn > 0, 0 < phi_g < "
                                 f"90 deg), got {text!r}")
            out[name] = (lo, hi)
        return out

    def path_materials(self, params: Params, paths: np.ndarray) -> list[Params]:
        """The material of each path (``params`` with the drawn kt/kn and φg); dataset 3: of
        each REV loading path (``paths`` its index), whose α0 is drawn too, uniformly over
        [alpha0_min, alpha0_max] (its REV's cells share one)."""
        ranges = self.dataset_kind.drawn_ranges(self)
        out = []
        for path in paths:
            rng = np.random.default_rng((self.material_seed, int(path)))
            draw = {k: rng.uniform(lo, hi) for k, (lo, hi) in ranges.items()}
            for k in ("phi_g", "alpha0"):
                if k in draw:
                    draw[k] = math.radians(draw[k])
            out.append(params.with_(**draw))
        return out

    # -- grids -----------------------------------------------------------------------------
    @property
    def rev_loadings(self) -> list[tuple[str, float]]:
        """Dataset 3: the REV's loading paths as (``drained`` or ``undrained``, p0 [Pa])."""
        out = []
        for item in filter(None, (t.strip() for t in self.rev_paths.split(","))):
            name, _, value = item.partition(":")
            try:
                p0 = float(value)
            except ValueError:
                p0 = float("nan")
            if name not in REV_LOADINGS or not (math.isfinite(p0) and p0 > 0):
                raise InputError(f"a REV loading path is drained:P0 or undrained:P0 with P0 > 0 in Pa, "
                                 f"got {item!r}")
            out.append((name, p0))
        return out

    @property
    def alpha0_deg(self) -> np.ndarray:
        n = int(math.floor((self.alpha0_max - self.alpha0_min) / self.alpha0_step + 1e-9)) + 1
        return self.alpha0_min + self.alpha0_step * np.arange(n)

    @property
    def theta(self) -> np.ndarray:
        """Path directions [rad], from ``theta_min`` to ``theta_max`` inclusive (max excluded
        when the range is a full turn)."""
        lo, hi = math.radians(self.theta_min), math.radians(self.theta_max)
        if self.n_directions == 1:
            return np.full(1, lo)
        full = self.theta_max - self.theta_min == 360.0
        return np.linspace(lo, hi, self.n_directions, endpoint=not full)

    @property
    def increment_angles(self) -> np.ndarray:
        """Directions of the Dataset-2 increments [rad], over [0, 2π)."""
        return 2 * math.pi * np.arange(self.n_increments) / self.n_increments

    @property
    def increment_magnitudes(self) -> np.ndarray:
        """Magnitude of each Dataset-2 increment direction: ``magnitude``, or spread over
        [magnitude_min, magnitude] by the golden-ratio sequence (so that every sector of
        directions sees small and large increments)."""
        if self.magnitude_min is None:
            return np.full(self.n_increments, self.magnitude)
        u = np.modf((np.arange(self.n_increments) + 0.5) * 0.6180339887498949)[0]
        return self.magnitude_min + (self.magnitude - self.magnitude_min) * u

    @property
    def n_paths(self) -> int:
        return self.dataset_kind.n_paths(self)

    @property
    def n_steps(self) -> int:
        return _ratio(self.max_strain, self.step, "max_strain", "step")

    @property
    def prestrain_steps(self) -> int:
        """Isotropic steps of ``step`` applied before every path."""
        return _ratio(self.prestrain, self.step, "prestrain", "step") if self.prestrain else 0

    @property
    def start_steps(self) -> np.ndarray:
        """Steps of a path whose states start Dataset-2 increments (1-based; 0: the unloaded
        cell, with ``from_unloaded``)."""
        every = _ratio(self.start_every, self.step, "start_every", "step")
        return np.arange(0 if self.from_unloaded else every, self.n_steps + 1, every)

    @property
    def psi(self) -> np.ndarray:
        """3D paths: the split ψ [rad] of each path's lateral cell strain between l2 (cos ψ) and
        l3 (sin ψ), over [0, π/2] by the golden-ratio sequence of the path index."""
        return 0.5 * math.pi * np.modf((np.arange(self.n_paths) + 0.5) * _GOLDEN)[0]

    @property
    def increment_directions_3d(self) -> np.ndarray:
        """3D: the ``n_increments`` unit directions (J, 3) of (δε1, δε2, δε3), a Fibonacci
        lattice on the sphere."""
        k = np.arange(self.n_increments)
        z = 1.0 - 2.0 * (k + 0.5) / self.n_increments
        r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
        phi = 2.0 * math.pi * np.modf(k * _GOLDEN)[0]
        return np.column_stack([z, r * np.cos(phi), r * np.sin(phi)])

    @property
    def rows_per_path(self) -> int:
        return self.dataset_kind.rows_per_path(self)

    @property
    def paths_per_shard(self) -> int:
        return self.dataset_kind.paths_per_shard(self)

    @property
    def n_shards(self) -> int:
        return -(-self.n_paths // self.paths_per_shard)

    @property
    def n_rows(self) -> int:
        return self.n_paths * self.rows_per_path

    def shard_paths(self, shard: int) -> np.ndarray:
        if not 0 <= shard < self.n_shards:
            raise InputError(f"shard {shard} out of range 0..{self.n_shards - 1}")
        start = shard * self.paths_per_shard
        return np.arange(start, min(start + self.paths_per_shard, self.n_paths))

    def to_dict(self) -> dict:
        d = asdict(self)
        if d["dim"] == 2:  # 2D manifests (and the fingerprints of models trained on them) unchanged
            del d["dim"]
        if not self.draws_material:  # likewise for datasets of one material
            for k in ("kt_kn_range", "phi_g_range", "material_seed"):
                del d[k]
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "DatasetSpec":
        known = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in d.items() if k in known})


def _ratio(total: float, step: float, a: str, b: str) -> int:
    n = round(total / step)
    if n < 1 or abs(n * step - total) > 1e-9 * max(total, 1.0):
        raise InputError(f"{a} ({total}) must be a whole multiple of {b} ({step})")
    return n


def compute_shard(spec: DatasetSpec, params: Params, shard: int) -> pa.Table:
    """The rows of one shard, in path order (a pure function of its arguments)."""
    paths = spec.shard_paths(shard)
    rows = spec.dataset_kind
    if spec.draws_material:  # one material per group of paths (dataset 3: per REV): one by one
        parts = []
        groups, keys = rows.material_groups(spec, shard, paths)
        for group, material in zip(groups, spec.path_materials(params, keys)):
            t = rows.rows(spec, material, group)
            n = t.num_rows
            parts.append(t.append_column("kt_kn", pa.array(np.full(n, material.kt_kn)))
                         .append_column("phi_g", pa.array(np.full(n, material.phi_g))))
        return pa.concat_tables(parts)
    return rows.rows(spec, params, paths)
