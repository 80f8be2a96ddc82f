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

**3D rows** (``dim = 3``, issue 34): Dataset 2 of the bi-hexagon of the 3D H-model
(docs/model3d.md), solved in closed form (``BiHexSolver``): path ``path_id`` loads a
bi-hexagon of opening angle α0 along the cell-strain direction (cos θ, sin θ cos ψ, sin θ sin ψ)
of its three lengths (l1 along n, l2 and l3 the two hexagons' columns), ψ ∈ [0, π/2] spread over
the paths by the golden-ratio sequence (so that the two hexagons see different lateral
strains); from its states every ``start_every``, increments of the spec's magnitudes in
``n_increments`` directions of (δε1, δε2, δε3) on the unit sphere (a Fibonacci lattice), in
``substeps`` sub-steps. Columns: :data:`~hmodel.data.schema.COLUMNS_3D`. Small defaults:
:data:`DIM3_DEFAULTS`. Dataset 2 only, closed form only.

Cell strains are measured on the initial lengths, compression positive: δl = −(l10, l20)·δε.
A shard is a contiguous range of paths, so that any shard can be computed alone, in any
process, and always gives the same rows.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, fields, replace

import numpy as np
import pyarrow as pa

from ..cell import CellState
from ..cell.bihex import BiHexSolver
from ..errors import InputError
from ..params import Params
from ..solvers import get_solver
from .schema import (
    EXTRA_COLUMNS,
    FLAG_COLUMNS,
    FLAG_COLUMNS_3D,
    STATE,
    STATE_B,
    arrow_schema,
    to_arrow,
)

#: The REV loading paths of Dataset 3.
REV_LOADINGS = ("drained", "undrained")
#: Field order of the packed cell state (hmodel.cell.state.FIELDS) for each schema column.
_PACKED = {"d1": 0, "d2": 1, "alpha": 2, "N1": 3, "N2": 4, "T1": 5, "l1": 6, "l2": 7}
#: The same for hexagon B's columns of a bi-hexagon state (hmodel.cell.bihex.BIHEX_FIELDS).
_PACKED_B = {b: 8 + _PACKED[a] for a, b in zip(STATE, STATE_B)}
#: Options of a ``dim = 3`` dataset where ``hmodel data generate --dim 3`` is given none: single
#: REV-scale increments (≤ 0.2 %, as the shipped default network's REV_DATASET) from 12 paths
#: × 3 opening angles × 20 start states, 26 directions: 18,720 rows.
DIM3_DEFAULTS = {"n_directions": 12, "theta": "-60:150", "alpha0": "40:60:10", "max_strain": 0.1,
                 "start_every": 0.005, "magnitude": 0.002, "magnitude_min": 0.0, "n_increments": 26,
                 "substeps": 1}
#: Golden ratio's fractional part: the low-discrepancy sequences of ψ and of the sphere lattice.
_GOLDEN = 0.6180339887498949


@dataclass(frozen=True)
class DatasetSpec:
    """Generator options of one database; the defaults reproduce the report's scale.

    Angles in degrees here (as on the command line); rows store radians.
    """

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
    #: A material per path (issue 36, networks over a range of materials): ``"LO:HI"`` ranges of
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
        if self.kind not in (1, 2, 3):
            raise InputError(f"dataset must be 1, 2 or 3, got {self.kind}")
        if self.dim not in (2, 3):
            raise InputError(f"dim must be 2 or 3, got {self.dim!r}")
        if self.dim == 3 and self.kind != 2:
            raise InputError(f"--dim 3 writes dataset 2 (bi-hexagon increments from the states of "
                             f"bi-hexagon paths); dataset {self.kind} is the 2D H-cell's only")
        if self.draws_material and self.dim == 3:
            raise InputError("a material per path (--kt-kn, --phi-g ranges) is drawn for 2D datasets only")
        self.material_ranges  # parses and checks
        cell = get_solver(self.solver)  # what rows it makes: its declarations (CellSolver)
        if self.dim == 3 and (cell.learned or cell.dem_cells):
            raise InputError(f"--dim 3 rows are the closed-form bi-hexagon's; --solver {self.solver} "
                             "is a 2D cell solver option only")
        if self.dim == 2 and cell.n_lengths != 2:
            raise InputError(f"{self.solver} is the 3D model's cell (three lengths), not a 2D cell to make 2D "
                             "rows of; --dim 3 rows are the closed-form bi-hexagon's")
        if (self.kind == 3) != bool(self.rev_paths.strip()):
            raise InputError("rev_paths (the REV's loading paths) must be given for dataset 3 and "
                             f"only for it, got {self.rev_paths!r} for dataset {self.kind}")
        if self.kind == 3 and self.prestrain:
            raise InputError("prestrain does not apply to dataset 3 (its REV is consolidated to p0)")
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
        if self.kind >= 2:
            _ratio(self.start_every, self.step, "start_every", "step")
            _ratio(self.max_strain, self.start_every, "max_strain", "start_every")

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
        ranges = dict(self.material_ranges)
        if self.kind == 3:
            ranges["alpha0"] = (self.alpha0_min, self.alpha0_max)
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
        if self.kind == 3:
            return len(self.rev_loadings) * self.n_directions
        return len(self.alpha0_deg) * self.n_directions

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
        return self.n_steps if self.kind == 1 else len(self.start_steps) * self.n_increments

    @property
    def paths_per_shard(self) -> int:
        if self.kind == 3:  # one REV loading path per shard
            return self.n_directions
        return max(1, self.shard_rows // self.rows_per_path)

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
    if spec.draws_material:  # one material per path (dataset 3: per REV): one by one
        parts = []
        groups = [paths] if spec.kind == 3 else [np.array([p]) for p in paths]
        keys = [shard] if spec.kind == 3 else paths
        for group, material in zip(groups, spec.path_materials(params, keys)):
            t = _paths(spec, material, group)
            n = t.num_rows
            parts.append(t.append_column("kt_kn", pa.array(np.full(n, material.kt_kn)))
                         .append_column("phi_g", pa.array(np.full(n, material.phi_g))))
        return pa.concat_tables(parts)
    return _paths(spec, params, paths)


def _paths(spec: DatasetSpec, params: Params, paths: np.ndarray) -> pa.Table:
    """The rows of ``paths`` of one material."""
    if spec.dim == 3:
        return _bihex_increments(spec, params, paths)
    if spec.kind == 3:
        return _rev_histories(spec, params, int(paths[0]) // spec.n_directions, paths)
    alpha0 = np.radians(spec.alpha0_deg)[paths // spec.n_directions]
    theta = spec.theta[paths % spec.n_directions]
    solver = get_solver(spec.solver)
    # each solver makes its own cell states (richer DEM cells: more than the 8 fields)
    cells = solver.initial_cells(params, alpha0)
    l10, l20 = cells.l1.copy(), cells.l2.copy()
    for _ in range(spec.prestrain_steps):
        cells, _ = solver.step(params, cells, -l10 * spec.step, -l20 * spec.step)
    dl1, dl2 = -l10 * spec.step * np.cos(theta), -l20 * spec.step * np.sin(theta)
    if spec.kind == 1:
        return _dataset1(spec, params, solver, cells, dl1, dl2, paths, alpha0, theta)
    return _dataset2(spec, params, solver, cells, dl1, dl2, paths, alpha0, theta, (l10, l20))


def _dataset1(spec, params, solver, cells, dl1, dl2, paths, alpha0, theta) -> pa.Table:
    P, n = len(paths), spec.n_steps
    nf = cells.values.shape[-1]
    after = np.empty((P, n, nf))
    flags = np.empty((P, n, len(FLAG_COLUMNS)), bool)
    state = cells
    for k in range(n):
        state, f = solver.step(params, state, dl1, dl2)
        after[:, k], flags[:, k] = state.values, f.flags
    total = spec.step * np.arange(1, n + 1)
    deps = np.stack([np.outer(np.cos(theta), total), np.outer(np.sin(theta), total)], axis=-1)
    before = np.broadcast_to(cells.values[:, None, :], after.shape)
    labels = (alpha0, paths, theta, np.zeros(P))
    return _table(deps.reshape(-1, 2), before.reshape(-1, nf), after.reshape(-1, nf),
                  flags.reshape(-1, flags.shape[-1]), [np.repeat(v, n) for v in labels])


def _dataset2(spec, params, solver, cells, dl1, dl2, paths, alpha0, theta, l0) -> pa.Table:
    state = cells

    def advance() -> np.ndarray:
        nonlocal state
        state, _ = solver.step(params, state, dl1, dl2)
        return state.values

    start = _start_states(spec, cells.values, advance)
    return _increments(spec, params, solver, start, l0, paths, alpha0, theta)


def _rev_histories(spec, params, shard, paths) -> pa.Table:
    """Dataset 3: the increments from the states of a REV's cells along one loading path."""
    from ..loading.named_paths import (  # the loading layer sits above the data's
        biaxial,
        consolidate,
    )
    from ..rev import Rev

    loading, p0 = spec.rev_loadings[shard]
    solver = get_solver(spec.solver)
    rev = Rev(replace(params, n_theta=spec.n_directions), solver)
    cells0 = rev.initial(1).cells.values[0]
    state = consolidate(rev, [p0], step=spec.step / 5)
    undrained = loading == "undrained"

    def advance() -> np.ndarray:
        nonlocal state
        state = biaxial(rev, state, spec.step, undrained=undrained,
                        lateral_stress=None if undrained else [p0], step=spec.step)
        return state.cells.values[0]

    start = _start_states(spec, state.cells.values[0], advance)
    alpha0 = np.full(len(paths), params.alpha0)
    return _increments(spec, params, solver, start, (cells0[:, 6], cells0[:, 7]), paths, alpha0,
                       rev.directions.theta)


def _start_states(spec, first: np.ndarray, advance: Callable[[], np.ndarray]) -> np.ndarray:
    """The states (P, L, n_fields) of P paths at the spec's start steps: ``first`` (P, n_fields)
    at step 0, then what ``advance()`` returns at each step."""
    starts = spec.start_steps
    out = np.empty((first.shape[0], len(starts), first.shape[1]))
    level = 0
    if starts[0] == 0:
        out[:, 0] = first
        level = 1
    for k in range(1, spec.n_steps + 1):
        values = advance()
        if level < len(starts) and k == starts[level]:
            out[:, level] = values
            level += 1
    return out


def _increments(spec, params, solver, start, l0, paths, alpha0, theta) -> pa.Table:
    """Dataset-2 increments from start states (P, L, n_fields) of P paths."""
    return increment_rows(spec, params, solver, start, l0, paths, alpha0, theta,
                          spec.step * spec.start_steps)


def increment_rows(spec: DatasetSpec, params: Params, solver, start: np.ndarray, l0, paths: np.ndarray,
                   alpha0: np.ndarray, theta: np.ndarray, strain: np.ndarray) -> pa.Table:
    """Rows of the spec's Dataset-2 increments (``n_increments`` directions, their magnitudes,
    ``substeps``) applied by ``solver`` to start states (P, L, n_fields): P cells of initial
    lengths ``l0`` = (l10, l20) (P,) each, at L states each, labelled by ``paths``, ``alpha0``,
    ``theta`` (P,) and ``strain`` (L,, the ``start_strain`` column). Used by the generator and
    by active learning (:mod:`hmodel.studies.refine`), whose start states are a REV's."""
    P, L, nf = start.shape
    J = spec.n_increments
    phi = spec.increment_angles
    deps = spec.increment_magnitudes[:, None] * np.stack([np.cos(phi), np.sin(phi)], axis=-1)  # (J, 2)
    l10 = np.broadcast_to(l0[0][:, None, None], (P, L, J))  # strains on the initial lengths
    l20 = np.broadcast_to(l0[1][:, None, None], (P, L, J))
    sub1 = -l10 * deps[:, 0] / spec.substeps
    sub2 = -l20 * deps[:, 1] / spec.substeps
    before = CellState(np.ascontiguousarray(np.broadcast_to(start[:, :, None, :], (P, L, J, nf))))
    state = before
    for _ in range(spec.substeps):
        state, f = solver.step(params, state, sub1, sub2)
    labels = (np.repeat(alpha0, L * J), np.repeat(paths, L * J), np.repeat(theta, L * J),
              np.tile(np.repeat(strain, J), P))
    return _table(np.tile(deps, (P * L, 1)), before.values.reshape(-1, nf),
                  state.values.reshape(-1, nf), f.flags.reshape(-1, len(FLAG_COLUMNS)), labels)


def _bihex_increments(spec: DatasetSpec, params: Params, paths: np.ndarray) -> pa.Table:
    """3D Dataset 2: bi-hexagon increments from the states of bi-hexagon paths (module doc)."""
    solver = BiHexSolver()
    alpha0 = np.radians(spec.alpha0_deg)[paths // spec.n_directions]
    theta = spec.theta[paths % spec.n_directions]
    psi = spec.psi[paths]
    cells = solver.initial_cells(params, alpha0)
    l0 = [cells.values[:, k].copy() for k in (6, 7, 15)]  # l10, l20, l30
    for _ in range(spec.prestrain_steps):
        cells, _ = solver.step(params, cells, *(-l * spec.step for l in l0))
    direction = (np.cos(theta), np.sin(theta) * np.cos(psi), np.sin(theta) * np.sin(psi))
    dl = [-l * spec.step * d for l, d in zip(l0, direction)]
    state = cells

    def advance() -> np.ndarray:
        nonlocal state
        state, _ = solver.step(params, state, *dl)
        return state.values

    start = _start_states(spec, cells.values, advance)  # (P, L, 16)
    P, L, nf = start.shape
    J = spec.n_increments
    deps = spec.increment_magnitudes[:, None] * spec.increment_directions_3d  # (J, 3)
    sub = [-np.broadcast_to(l[:, None, None], (P, L, J)) * deps[:, k] / spec.substeps
           for k, l in enumerate(l0)]
    before = CellState(np.ascontiguousarray(np.broadcast_to(start[:, :, None, :], (P, L, J, nf))))
    new = before
    for _ in range(spec.substeps):
        new, f = solver.step(params, new, *sub)
    labels = (np.repeat(alpha0, L * J), np.repeat(paths, L * J), np.repeat(theta, L * J),
              np.tile(np.repeat(spec.step * spec.start_steps, J), P))
    b, a = before.values.reshape(-1, nf), new.values.reshape(-1, nf)
    deps = np.tile(deps, (P * L, 1))
    cols = {"deps1": deps[:, 0], "deps2": deps[:, 1], "deps3": deps[:, 2]}
    for packed in (_PACKED, _PACKED_B):
        for c, k in packed.items():
            cols[c] = b[:, k]
    for packed in (_PACKED, _PACKED_B):
        for c, k in packed.items():
            cols[f"{c}_next"] = a[:, k]
    flags = f.flags.reshape(-1, len(FLAG_COLUMNS_3D))
    for j, c in enumerate(FLAG_COLUMNS_3D):
        cols[c] = flags[:, j]
    cols.update(alpha0=labels[0], path_id=labels[1].astype(np.int32), theta=labels[2], start_strain=labels[3])
    schema = arrow_schema(dim=3)
    return pa.Table.from_arrays([to_arrow(cols[fl.name], fl.type) for fl in schema], schema=schema)


def _table(deps, before, after, flags, labels) -> pa.Table:
    cols = {"deps1": deps[:, 0], "deps2": deps[:, 1]}
    for c in STATE:
        cols[c] = before[:, _PACKED[c]]
    for c in STATE:
        cols[f"{c}_next"] = after[:, _PACKED[c]]
    for j, c in enumerate(FLAG_COLUMNS):
        cols[c] = flags[:, j]
    alpha0, paths, theta, start = labels
    cols.update(alpha0=alpha0, path_id=paths.astype(np.int32), theta=theta, start_strain=start)
    n_extra = before.shape[1] - 8
    schema = arrow_schema(n_extra=n_extra)
    if n_extra:
        cols.update(zip(EXTRA_COLUMNS, (before[:, 8:], after[:, 8:])))
    return pa.Table.from_arrays([to_arrow(cols[f.name], f.type) for f in schema], schema=schema)
