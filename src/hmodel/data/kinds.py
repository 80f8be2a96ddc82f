"""The kinds of dataset rows, one class each (the module doc of :mod:`hmodel.data.generator`
describes what each holds).

A :class:`~hmodel.data.generator.DatasetSpec` names its kind as manifests store it, by the
dataset number ``kind`` (1, 2, 3) and the dimension ``dim`` (2, 3); :func:`dataset_kind` finds
the class, which says what the rows are (columns, units, the options a command line leaves out),
what it refuses, how many paths and rows there are and how shards group them, and computes the
rows of some paths. A new kind of rows is one subclass of :class:`DatasetKind` listed in
:data:`KINDS`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pyarrow as pa

from ..cell import CellState
from ..cell.bihex import BiHexSolver
from ..errors import InputError
from ..solvers import get_solver
from .rows import bihex_table, increment_rows, start_states, table
from .schema import COLUMNS, COLUMNS_3D, FLAG_COLUMNS, FLAG_COLUMNS_3D, UNITS, UNITS_3D

#: Generator options of H-cell rows that a command line leaves out: the report's scale.
HCELL_DEFAULTS = {"n_directions": 91, "theta": "0:90", "alpha0": "32:88:2", "max_strain": 0.30,
                  "start_every": 0.01, "magnitude": 0.01, "magnitude_min": None, "n_increments": 168,
                  "substeps": 10}
#: Options of a ``dim = 3`` dataset where ``hmodel data generate --dim 3`` is given none: single
#: REV-scale increments (≤ 0.2 %, as the shipped default network's REV_DATASET) from 12 paths
#: × 3 opening angles × 20 start states, 26 directions: 18,720 rows.
DIM3_DEFAULTS = {"n_directions": 12, "theta": "-60:150", "alpha0": "40:60:10", "max_strain": 0.1,
                 "start_every": 0.005, "magnitude": 0.002, "magnitude_min": 0.0, "n_increments": 26,
                 "substeps": 1}


class DatasetKind:
    """One kind of rows. The defaults below are those of an H-cell kind whose paths are the
    α0 × θ grid and whose rows are increments from start states along them."""

    #: The dataset number (the manifest's ``kind``).
    number: int = 0
    #: 2: H-cell rows; 3: bi-hexagon rows.
    dim: int = 2
    #: What it writes, in an error that refuses another number at this dimension.
    description: str = ""
    #: Columns and units of its rows (:mod:`hmodel.data.schema`).
    columns: tuple[str, ...] = COLUMNS
    units: dict = UNITS
    #: Options a command line leaves out take these values (the kinds of one dimension share them).
    defaults: dict = HCELL_DEFAULTS
    #: Whether a path may draw its own material (``kt_kn_range``, ``phi_g_range``).
    material_per_path: bool = True
    #: Whether the rows start from states along the paths (``start_every`` applies).
    increments: bool = True

    @property
    def label(self) -> str:
        """How messages name it: ``dataset 2``."""
        return f"dataset {self.number}"

    def check(self, spec, cell) -> None:
        """Refuse options that do not apply (InputError); ``cell`` is the spec's solver."""
        self.check_cell(spec, cell)
        self.check_options(spec)

    def check_cell(self, spec, cell) -> None:
        pass

    def check_options(self, spec) -> None:
        if spec.rev_paths.strip():
            raise InputError(_rev_paths_message(spec))

    def n_paths(self, spec) -> int:
        return len(spec.alpha0_deg) * spec.n_directions

    def rows_per_path(self, spec) -> int:
        return len(spec.start_steps) * spec.n_increments

    def paths_per_shard(self, spec) -> int:
        return max(1, spec.shard_rows // self.rows_per_path(spec))

    def material_groups(self, spec, shard: int, paths: np.ndarray) -> tuple[list[np.ndarray], list]:
        """The paths of a shard that share a drawn material, and the key each group's material
        is drawn with (:meth:`~hmodel.data.generator.DatasetSpec.path_materials`): a path alone,
        by its id."""
        return [np.array([p]) for p in paths], paths

    def drawn_ranges(self, spec) -> dict[str, tuple[float, float]]:
        """The parameters a path's material draws, with their ranges."""
        return dict(spec.material_ranges)

    def rows(self, spec, params, paths: np.ndarray) -> pa.Table:
        """The rows of ``paths``, of one material ``params``."""
        raise NotImplementedError


def _rev_paths_message(spec) -> str:
    return ("rev_paths (the REV's loading paths) must be given for dataset 3 and only for it, "
            f"got {spec.rev_paths!r} for dataset {spec.kind}")


class _HCellPaths(DatasetKind):
    """H-cell rows along the paths of the α0 × θ grid, each cell made and prestrained by the
    spec's solver."""

    def check_cell(self, spec, cell) -> None:
        if cell.n_lengths != 2:
            raise InputError(f"{spec.solver} is the 3D model's cell (three lengths), not a 2D cell to make 2D "
                             "rows of; --dim 3 rows are the closed-form bi-hexagon's")

    def rows(self, spec, params, paths: np.ndarray) -> pa.Table:
        alpha0 = np.radians(spec.alpha0_deg)[paths // spec.n_directions]
        theta = spec.theta[paths % spec.n_directions]
        solver = get_solver(spec.solver)
        # each solver makes its own cell states (richer DEM cells: more than the 8 fields)
        cells = solver.initial_cells(params, alpha0)
        l10, l20 = cells.l1.copy(), cells.l2.copy()
        for _ in range(spec.prestrain_steps):
            cells, _ = solver.step(params, cells, -l10 * spec.step, -l20 * spec.step)
        dl1, dl2 = -l10 * spec.step * np.cos(theta), -l20 * spec.step * np.sin(theta)
        return self.path_rows(spec, params, solver, cells, dl1, dl2, paths, alpha0, theta, (l10, l20))

    def path_rows(self, spec, params, solver, cells, dl1, dl2, paths, alpha0, theta, l0) -> pa.Table:
        """The rows of P paths from their (prestrained) cells, whose steps are (dl1, dl2)."""
        raise NotImplementedError


class Paths(_HCellPaths):
    """Dataset 1: every path in steps of ``step`` up to ``max_strain``; row k holds the initial
    state, the total strain so far and the state reached."""

    number = 1
    increments = False

    def rows_per_path(self, spec) -> int:
        return spec.n_steps

    def path_rows(self, spec, params, solver, cells, dl1, dl2, paths, alpha0, theta, l0) -> pa.Table:
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
        return table(deps.reshape(-1, 2), before.reshape(-1, nf), after.reshape(-1, nf),
                     flags.reshape(-1, flags.shape[-1]), [np.repeat(v, n) for v in labels])


class Increments(_HCellPaths):
    """Dataset 2: increments in ``n_increments`` directions from the states of every path at
    every ``start_every`` of strain."""

    number = 2

    def path_rows(self, spec, params, solver, cells, dl1, dl2, paths, alpha0, theta, l0) -> pa.Table:
        state = cells

        def advance() -> np.ndarray:
            nonlocal state
            state, _ = solver.step(params, state, dl1, dl2)
            return state.values

        start = start_states(spec, cells.values, advance)
        return increment_rows(spec, params, solver, start, l0, paths, alpha0, theta,
                              spec.step * spec.start_steps)


class RevHistories(_HCellPaths):
    """Dataset 3: the increments of Dataset 2 from the states a REV's own cells pass through on
    its loading paths (``rev_paths``); one shard is one loading path, whose material (α0 too)
    a spec that draws materials draws once."""

    number = 3

    def check_options(self, spec) -> None:
        if not spec.rev_paths.strip():
            raise InputError(_rev_paths_message(spec))
        if spec.prestrain:
            raise InputError("prestrain does not apply to dataset 3 (its REV is consolidated to p0)")

    def n_paths(self, spec) -> int:
        return len(spec.rev_loadings) * spec.n_directions

    def paths_per_shard(self, spec) -> int:
        return spec.n_directions  # one REV loading path per shard

    def material_groups(self, spec, shard: int, paths: np.ndarray) -> tuple[list[np.ndarray], list]:
        return [paths], [shard]

    def drawn_ranges(self, spec) -> dict[str, tuple[float, float]]:
        ranges = super().drawn_ranges(spec)
        ranges["alpha0"] = (spec.alpha0_min, spec.alpha0_max)
        return ranges

    def rows(self, spec, params, paths: np.ndarray) -> pa.Table:
        from ..loading.named_paths import (  # the loading layer sits above the data's
            biaxial,
            consolidate,
        )
        from ..rev import Rev

        loading, p0 = spec.rev_loadings[int(paths[0]) // spec.n_directions]
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

        start = start_states(spec, state.cells.values[0], advance)
        alpha0 = np.full(len(paths), params.alpha0)
        return increment_rows(spec, params, solver, start, (cells0[:, 6], cells0[:, 7]), paths, alpha0,
                              rev.directions.theta, spec.step * spec.start_steps)


class BiHexIncrements(DatasetKind):
    """3D Dataset 2: bi-hexagon increments from the states of bi-hexagon paths, in closed form
    (the module doc of :mod:`hmodel.data.generator`)."""

    number = 2
    dim = 3
    description = "dataset 2 (bi-hexagon increments from the states of bi-hexagon paths)"
    columns = COLUMNS_3D
    units = UNITS_3D
    defaults = DIM3_DEFAULTS
    material_per_path = False

    @property
    def label(self) -> str:
        return f"dataset {self.number} (3D, bi-hexagons)"

    def check_cell(self, spec, cell) -> None:
        if cell.learned or cell.dem_cells:
            raise InputError(f"--dim 3 rows are the closed-form bi-hexagon's; --solver {spec.solver} "
                             "is a 2D cell solver option only")

    def rows(self, spec, params, paths: np.ndarray) -> pa.Table:
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

        start = start_states(spec, cells.values, advance)  # (P, L, 16)
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
        return bihex_table(np.tile(deps, (P * L, 1)), before.values.reshape(-1, nf), new.values.reshape(-1, nf),
                           f.flags.reshape(-1, len(FLAG_COLUMNS_3D)), labels)


#: Every kind of rows.
KINDS: tuple[DatasetKind, ...] = (Paths(), Increments(), RevHistories(), BiHexIncrements())


def dataset_kind(number, dim) -> DatasetKind:
    """The kind of rows of dataset ``number`` at dimension ``dim`` (InputError if none)."""
    numbers = sorted({k.number for k in KINDS})
    if number not in numbers:
        raise InputError(f"dataset must be {_either(numbers)}, got {number}")
    dims = sorted({k.dim for k in KINDS})
    if dim not in dims:
        raise InputError(f"dim must be {_either(dims)}, got {dim!r}")
    for k in KINDS:
        if k.number == number and k.dim == dim:
            return k
    written = " or ".join(k.description for k in KINDS if k.dim == dim)
    raise InputError(f"--dim {dim} writes {written}; dataset {number} is the 2D H-cell's only")


def option_defaults(dim) -> dict:
    """The generator options a command line leaves out, for rows of dimension ``dim``."""
    for k in KINDS:
        if k.dim == dim:
            return dict(k.defaults)
    raise InputError(f"--dim must be {_either(sorted({k.dim for k in KINDS}))}, got {dim}")


def _either(values) -> str:
    return ", ".join(map(str, values[:-1])) + " or " + str(values[-1])
