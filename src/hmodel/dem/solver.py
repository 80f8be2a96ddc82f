"""The DEM cell solver: the engine's :class:`~hmodel.cell.base.CellSolver` backed by YADE.

``get_solver("dem:MESOSTRUCTURE")`` (``dem:standard``, ``dem:hexagon-center``,
``dem:hexagon-unequal``; options after a second colon, e.g. ``dem:hexagon-unequal:ratio=0.6``,
where numerical settings of :class:`~hmodel.dem.scene.DEMOptions` may be given too, e.g.
``dem:hexagon-center:tol=1e-7,max_iter=50000``) returns a :class:`DEMSolver`.
:meth:`DEMSolver.step` writes every cell of the batch, with its state, into one request (task
``increment``) to the YADE process the solver keeps (:mod:`hmodel.dem.yade`), which rebuilds the
cells (positions and tangential contact forces from the state), applies the increment and
relaxes them to the quasi-static criterion. The answer depends on the state and
the increment only (each cell is frozen as soon as it is balanced), so ``step`` is pure, as
the Newton iterations of the loading drivers need; identical (state, increment) rows of a
batch are sent once, and rows the previous request solved are not sent again (the material
points a Newton iteration has converged keep their trial, so that a batch of points costs the
DEM work of its unconverged ones).

State layouts (``CellState.values``, last axis) and the meso-stress of the cells that the REV
takes from :meth:`DEMSolver.meso` are those of :mod:`hmodel.cell.geometry`
(:class:`~hmodel.cell.geometry.CellGeometry`, which the solver composes: the surrogates of
these cells need that geometry without YADE).

Flags: ``sliding`` a type-1 contact on the Coulomb cone; ``open1``/``open2`` a type-1/type-2
contact open; ``contact14`` grains 1-4 in contact; ``contact26`` grains 2-6 or 3-5.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import replace

import numpy as np

from ..cell.base import STATE_H_CELL, STATE_OWN, CellSolver
from ..cell.geometry import CellGeometry
from ..cell.mesostructure import TYPE1, TYPE2, option_names
from ..cell.state import FLAGS, CellFlags, CellState
from ..errors import InputError, SolverError
from ..params import Params
from .scene import DEMOptions, scene_settings
from .yade import YadeServer, find_yade

#: Defaults of the solver: a tight quasi-static criterion, so that the stress is a smooth
#: enough function of the increment for Newton's finite-difference tangents.
SOLVER_OPTIONS = DEMOptions(tol=1e-10, max_iter=400_000, substeps=100, check_every=10)


def _parse(spec: str) -> tuple[CellGeometry, dict]:
    """The cells' geometry and the :class:`DEMOptions` changes of ``dem:NAME:K=V,...``."""
    geometry, rest = CellGeometry.from_spec(spec)
    unknown = [k for k in rest if k not in _NUMERICS]
    if unknown:
        own = ", ".join(option_names(geometry.mesostructure)) or "none"
        raise InputError(f"unknown option {unknown[0]!r} of {spec!r} (the mesostructure's: {own}; "
                         f"numerics: {', '.join(_NUMERICS)})")
    return geometry, {k: (int(v) if k in _INTEGER else v) for k, v in rest.items()}


#: DEMOptions fields that a solver spec may set (``dem:hexagon-center:tol=1e-7``).
_NUMERICS = ("tol", "max_iter", "substeps", "damping", "dt_safety", "check_every", "timeout", "max_cells")
_INTEGER = ("max_iter", "substeps", "check_every", "max_cells")


def measure(geo: CellGeometry, params: Params, pos: np.ndarray, contacts: list) -> tuple[np.ndarray, np.ndarray]:
    """State rows (n, n_fields) and flags (n, 5) of DEM cells of ``geo``, from their grain
    centres (n, g, 2) and closed-contact rows (n lists of rows [i, j, fn, ft, ...], the columns
    of :data:`hmodel.dem.scene.CONTACT_COLUMNS`); see the module docstring for the flags."""
    n = len(pos)
    new_ft = np.zeros((n, len(geo.pairs)))
    col = geo.pair_columns()
    contact = np.zeros((n, len(geo.pairs)), bool)
    fn = np.zeros((n, len(geo.pairs)))
    for k, rows in enumerate(contacts):
        for row in rows:
            p = col[(int(row[0]), int(row[1]))]
            contact[k, p] = True
            fn[k, p] = row[2]
            new_ft[k, p] = row[3]
    out = geo.pack(params, pos, new_ft)
    t1 = [col[c] for c in TYPE1]
    t2 = [col[c] for c in TYPE2]
    mu = math.tan(params.phi_g)
    sliding = np.any(contact[:, t1] & (np.abs(new_ft[:, t1]) >= mu * fn[:, t1] * (1 - 5e-3))
                     & (fn[:, t1] > 0), axis=1)
    flags = np.stack([sliding, ~contact[:, t1].all(axis=1), ~contact[:, t2].all(axis=1),
                      contact[:, col[(0, 3)]], contact[:, col[(1, 5)]] | contact[:, col[(2, 4)]]],
                     axis=1)
    return out, flags


class DEMSolver(CellSolver):
    """YADE cells of one mesostructure; see the module docstring for the state layout."""

    dem_cells = True

    def __init__(self, spec: str = "dem:standard", options: DEMOptions | None = None):
        #: The cells' state layout and meso-stress (:mod:`hmodel.cell.geometry`).
        self.geometry, numerics = _parse(spec)
        named = {**self.geometry.options, **numerics}
        self.name = f"dem:{self.geometry.mesostructure}" + (
            ":" + ",".join(f"{k}={v:g}" for k, v in named.items()) if named else "")
        self.options = replace(options or SOLVER_OPTIONS, **numerics)
        #: Newton's stress tolerance for this solver (the loading drivers use the larger of
        #: theirs and this): the DEM state is converged to ``options.tol``, not to round-off.
        self.stress_rtol = 1e-7
        #: the Python side of a cell (its state and the rows sent to YADE); the YADE scenes
        #: hold a batch of cells at a time (``max_cells``)
        self.bytes_per_cell = 4096
        self.n_lengths = 2
        self._server: YadeServer | None = None
        #: (params, unique rows, new states, flags) of the last request, see :meth:`_solve`.
        self._last: tuple | None = None

    def __getstate__(self) -> dict:  # a copy in another process starts its own YADE
        return {**self.__dict__, "_server": None, "_last": None}

    def yade(self) -> YadeServer:
        """This solver's YADE process: started on first use, anew after a fork (multiprocessing
        workers) or when ``$HMODEL_YADE`` names another executable; ended with the solver."""
        exe = find_yade()
        s = self._server
        if s is None or not s.serves(exe):
            if s is not None:
                s.close()  # ends the process only where it was started
            s = self._server = YadeServer(exe)
            weakref.finalize(self, s.close)
        return s

    def __repr__(self) -> str:
        return f"DEMSolver({self.name!r})"

    def check_available(self) -> None:
        """Refuse a run where YADE is not installed (:func:`hmodel.dem.yade.find_yade`)."""
        find_yade()

    # -- state layout (the geometry's) --------------------------------------------------
    @property
    def state_kind(self) -> str:
        """The standard cell's state is an H-cell's; a richer cell keeps its own."""
        return STATE_H_CELL if self.geometry.standard else STATE_OWN

    @property
    def n_fields(self) -> int:
        return self.geometry.n_fields

    def field_names(self) -> tuple[str, ...]:
        """Names of the fields of ``CellState.values`` for this solver."""
        return self.geometry.field_names()

    def initial_cells(self, params: Params, alpha0: np.ndarray) -> CellState:
        """Unloaded cells with their own opening angles alpha0 (shape of ``alpha0``)."""
        return self.geometry.initial_cells(params, alpha0)

    def initial(self, params: Params, shape: tuple[int, ...] = ()) -> CellState:
        """Unloaded cells of opening angle params.alpha0."""
        return self.geometry.initial(params, shape)

    # -- solver interface -------------------------------------------------------------
    def step(self, params: Params, state: CellState, dl1: np.ndarray,
             dl2: np.ndarray) -> tuple[CellState, CellFlags]:
        return self._step(params, state, (dl1, dl2))

    #: columns of a state's lengths, one per length increment (l1, l2)
    length_columns = (6, 7)
    #: flags of a cell (:data:`hmodel.cell.state.FLAGS`)
    n_flags = len(FLAGS)

    def _step(self, params: Params, state: CellState, dls: tuple) -> tuple[CellState, CellFlags]:
        """:meth:`step` for ``dls``, one increment array per length (:attr:`length_columns`)."""
        values = np.asarray(state.values, float)
        if values.shape[-1] != self.n_fields:
            raise InputError(f"{self.name}: cell states have {values.shape[-1]} fields, this solver "
                             f"needs {self.n_fields} (start from its initial state)")
        shape = values.shape[:-1]
        n = len(dls)
        dl = np.stack(np.broadcast_arrays(*(np.asarray(d, float) for d in dls)), -1)
        dl = np.broadcast_to(dl, (*shape, n)).reshape(-1, n)
        if not np.all(np.isfinite(dl)):
            raise InputError("DEM increments must be finite")
        flat = values.reshape(-1, self.n_fields)
        # A length increment as long as the cell itself is no cell increment (a run-away
        # Newton trial): refused before YADE is asked to drive grains through each other.
        lengths = flat[:, list(self.length_columns)]
        worst = np.abs(dl) / np.maximum(np.abs(lengths), 1e-300) if len(flat) else np.zeros((0, n))
        if worst.size and worst.max() >= 1.0:
            k = np.unravel_index(int(np.argmax(worst)), worst.shape)
            raise SolverError(f"{self.name}: a cell length increment of {dl[k]:.3g} m on a cell of "
                              f"length {lengths[k]:.3g} m (at most the cell's length)")
        if flat.shape[0] == 0:
            return CellState(values.copy()), CellFlags(np.zeros((*shape, self.n_flags), bool))
        rows, inverse = np.unique(np.hstack([flat, dl]), axis=0, return_inverse=True)
        new, flags = self._solve(params, rows)
        inverse = inverse.reshape(-1)
        return (CellState(np.ascontiguousarray(new[inverse].reshape(*shape, self.n_fields))),
                CellFlags(np.ascontiguousarray(flags[inverse].reshape(*shape, self.n_flags))))

    def _solve(self, params: Params, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """New states and flags of unique (state, increment) rows; those of the previous request
        are taken from it (the answer depends on the row only), the others run in YADE."""
        new = np.empty((len(rows), self.n_fields))
        flags = np.empty((len(rows), self.n_flags), bool)
        todo = np.ones(len(rows), bool)
        last = self._last
        if last is not None and last[0] == params:
            _, first, inv = np.unique(np.vstack([last[1], rows]), axis=0, return_index=True,
                                      return_inverse=True)
            src = first[inv.reshape(-1)[len(last[1]):]]
            todo = src >= len(last[1])
            new[~todo], flags[~todo] = last[2][src[~todo]], last[3][src[~todo]]
        if todo.any():
            n = len(self.length_columns)
            new[todo], flags[todo] = self._run(params, rows[todo, :-n], rows[todo, -n:])
        self._last = (params, rows, new, flags)
        return new, flags

    def _run(self, params: Params, values: np.ndarray, dl: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        geo = self.geometry
        pos, ft = geo.unpack(params, values)
        r = geo.radii(params)
        proto = geo.cell(params, params.alpha0)
        _, closed = geo.normal_forces(params, pos)
        o = self.options
        req = scene_settings(params, float(np.max(r)), o)
        cells = []
        for k in range(len(values)):
            half = float(np.max(np.abs(pos[k, :, 0]) + r))
            height = float(np.max(np.abs(pos[k, :, 1]) + r))
            shear = [[int(i), int(j), float(ft[k, p])] for p, (i, j) in enumerate(geo.pairs)
                     if closed[k, p] and ft[k, p] != 0.0]
            cells.append({"radii": r.tolist(), "pos": pos[k].tolist(), "drive": list(proto.drive),
                          "l": [float(values[k, 6]), float(values[k, 7])], "half_width": half,
                          "half_height": height, "increment": dl[k].tolist(), "shear": shear})
        done = []
        for k in range(0, len(cells), o.max_cells):
            done += self.yade().request("increment", {**req, "cells": cells[k:k + o.max_cells]},
                                        timeout=o.timeout)["cells"]
        new_pos = np.array([c["pos"] for c in done], float).reshape(len(values), geo.n_grains, 2)
        return measure(geo, params, new_pos, [c["contacts"] for c in done])

    # -- meso-stress hook for the REV -------------------------------------------------
    def meso(self, params: Params, state: CellState) -> tuple[np.ndarray, np.ndarray] | None:
        """(V sigma) (..., 3) [N m] and meso-volume (...) [m^2] of richer cells; None for the
        standard cell (:meth:`hmodel.cell.geometry.CellGeometry.meso`)."""
        return self.geometry.meso(params, state)

    def kernel(self, params: Params) -> None:
        """None: every cell increment is a YADE run (the generic loading driver)."""
        return None

    def fractions(self, params: Params, state: CellState) -> dict[str, np.ndarray]:
        """None beyond the flags."""
        return {}
