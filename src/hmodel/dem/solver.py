"""The DEM cell solver: the engine's :class:`~hmodel.cell.base.CellSolver` backed by YADE.

``get_solver("dem:MESOSTRUCTURE")`` (``dem:standard``, ``dem:hexagon-center``,
``dem:hexagon-unequal``; options after a second colon, e.g. ``dem:hexagon-unequal:ratio=0.6``,
where numerical settings of :class:`~hmodel.dem.scene.DEMOptions` may be given too, e.g.
``dem:hexagon-center:tol=1e-7,max_iter=50000``) returns a :class:`DEMSolver`. :meth:`DEMSolver.step` writes every cell of the batch, with its
state, into one request to the persistent YADE process of :mod:`hmodel.dem.server`, which
rebuilds the cells (positions and tangential contact forces from the state), applies the
increment and relaxes them to the quasi-static criterion. The answer depends on the state and
the increment only (each cell is frozen as soon as it is balanced), so ``step`` is pure, as
the Newton iterations of the loading drivers need; identical (state, increment) rows of a
batch are sent once, and rows the previous request solved are not sent again (the material
points a Newton iteration has converged keep their trial, so that a batch of points costs the
DEM work of its unconverged ones).

State layouts (``CellState.values``, last axis):

- ``dem:standard``: the closed form's 8 fields ``d1, d2, alpha, N1, N2, T1, l1, l2``
  (:data:`hmodel.cell.state.FIELDS`). The cell is rebuilt mirror-symmetric: grains 1, 4 at
  (-/+ l1/2, 0), grains 2, 3 / 6, 5 at (-/+ d2/2, +/- l2/2); the four type-1 contacts carry
  T1 (signs of :data:`~hmodel.dem.mesostructure.TYPE1_SIGN`), the others none (zero by
  symmetry). Its meso-stress is eq. 1.12 of the fields, as for the closed form.
- a richer cell with g grains: the same 8 fields (measured on the six hexagon grains, as
  :func:`~hmodel.dem.scene.hcell_state` does; l1, l2 drive the localization), then the grain
  centres ``x_1, t_1, ..., x_g, t_g`` [m] (cell frame), then the tangential force ``ft`` [N]
  of every grain pair (i < j, in the order of ``numpy.triu_indices(g, 1)``; 0 when open),
  i.e. ``8 + 2 g + g (g - 1) / 2`` fields (:meth:`DEMSolver.field_names`). Its meso-stress
  is the symmetric Love-Weber sum over the closed contacts (normal force kn x overlap,
  tangential ``ft``) with the meso-volume of :meth:`Mesostructure.volume`, given to the REV by
  :meth:`DEMSolver.meso`.

Flags: ``sliding`` a type-1 contact on the Coulomb cone; ``open1``/``open2`` a type-1/type-2
contact open; ``contact14`` grains 1-4 in contact; ``contact26`` grains 2-6 or 3-5.
"""

from __future__ import annotations

import math
import os
import weakref
from dataclasses import replace

import numpy as np

from ..cell.state import FIELDS, FLAGS, CellFlags, CellState
from ..errors import InputError, SolverError
from ..params import Params
from .mesostructure import CONSTRUCTORS, TYPE1, TYPE1_SIGN, TYPE2, Mesostructure, build
from .scene import DEMOptions
from .server import YadeServer
from .yade import find_yade

#: Defaults of the solver: a tight quasi-static criterion, so that the stress is a smooth
#: enough function of the increment for Newton's finite-difference tangents.
SOLVER_OPTIONS = DEMOptions(tol=1e-10, max_iter=400_000, substeps=100, check_every=10)


def _parse(spec: str) -> tuple[str, dict, dict]:
    """Mesostructure name, its options and :class:`DEMOptions` changes of ``dem:NAME:K=V,...``."""
    parts = spec.split(":")
    name = parts[1] if len(parts) > 1 and parts[1] else "standard"
    opts = {}
    for item in (parts[2].split(",") if len(parts) > 2 and parts[2] else []):
        key, _, value = item.partition("=")
        try:
            opts[key.strip()] = float(value)
        except ValueError:
            raise InputError(f"DEM solver option must be NAME=NUMBER, got {item!r}") from None
    if name not in CONSTRUCTORS:
        raise InputError(f"unknown mesostructure {name!r} (available: {', '.join(CONSTRUCTORS)})")
    numerics = {k: (int(v) if k in _INTEGER else v) for k, v in opts.items() if k in _NUMERICS}
    return name, {k: v for k, v in opts.items() if k not in _NUMERICS}, numerics


#: DEMOptions fields that a solver spec may set (``dem:hexagon-center:tol=1e-7``).
_NUMERICS = ("tol", "max_iter", "substeps", "damping", "dt_safety", "check_every", "timeout", "max_cells")
_INTEGER = ("max_iter", "substeps", "check_every", "max_cells")


class DEMSolver:
    """YADE cells of one mesostructure; see the module docstring for the state layout."""

    def __init__(self, spec: str = "dem:standard", options: DEMOptions | None = None):
        self.mesostructure, self.meso_options, numerics = _parse(spec)
        named = {**self.meso_options, **numerics}
        self.name = f"dem:{self.mesostructure}" + (":" + ",".join(f"{k}={v:g}" for k, v in named.items()) if named else "")
        self.options = replace(options or SOLVER_OPTIONS, **numerics)
        proto = build(self.mesostructure, **self.meso_options)
        self.n_grains = proto.n_grains
        self.standard = self.mesostructure == "standard"
        self.pairs = np.array(np.triu_indices(self.n_grains, 1)).T
        self.n_fields = 8 if self.standard else 8 + 2 * self.n_grains + len(self.pairs)
        #: Newton's stress tolerance for this solver (the loading drivers use the larger of
        #: theirs and this): the DEM state is converged to ``options.tol``, not to round-off.
        self.stress_rtol = 1e-7
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
        if s is None or s._pid not in (0, os.getpid()) or s.exe != exe:
            if s is not None and s._pid == os.getpid():
                s.close()
            s = self._server = YadeServer()
            s.exe = exe
            weakref.finalize(self, s.close)
        return s

    def __repr__(self) -> str:
        return f"DEMSolver({self.name!r})"

    # -- state layout -----------------------------------------------------------------
    def field_names(self) -> tuple[str, ...]:
        """Names of the fields of ``CellState.values`` for this solver."""
        if self.standard:
            return FIELDS
        g = self.n_grains
        pos = tuple(f"{a}_{k + 1}" for k in range(g) for a in ("x", "t"))
        return FIELDS + pos + tuple(f"ft_{i + 1}_{j + 1}" for i, j in self.pairs)

    def cell(self, params: Params, alpha0: float) -> Mesostructure:
        return build(self.mesostructure, params.radius, float(alpha0), **self.meso_options)

    def initial_cells(self, params: Params, alpha0: np.ndarray) -> CellState:
        """Unloaded cells with their own opening angles alpha0 (shape of ``alpha0``)."""
        alpha0 = np.asarray(alpha0, float)
        flat = alpha0.reshape(-1)
        rows = {}
        out = np.empty((flat.size, self.n_fields))
        for k, a in enumerate(flat):
            if a not in rows:
                m = self.cell(params, a)
                rows[a] = self._pack(params, m.positions[None], np.zeros((1, len(self.pairs))))[0]
            out[k] = rows[a]
        return CellState(out.reshape(*alpha0.shape, self.n_fields))

    def initial(self, params: Params, shape: tuple[int, ...] = ()) -> CellState:
        """Unloaded cells of opening angle params.alpha0."""
        return self.initial_cells(params, np.full(shape, params.alpha0))

    def _pack(self, params: Params, pos: np.ndarray, ft: np.ndarray) -> np.ndarray:
        """State rows (n, n_fields) from centres (n, g, 2) and pair forces (n, P)."""
        n = len(pos)
        out = np.empty((n, self.n_fields))
        b1 = np.stack([pos[:, j] - pos[:, i] for i, j in TYPE1], axis=1)
        out[:, 0] = np.hypot(b1[..., 0], b1[..., 1]).mean(axis=1)
        out[:, 1] = np.mean([np.hypot(*(pos[:, j] - pos[:, i]).T) for i, j in TYPE2], axis=0)
        out[:, 2] = np.arctan2(np.abs(b1[..., 1]), np.abs(b1[..., 0])).mean(axis=1)
        fn, closed = self._normal(params, pos)
        col = {tuple(p): k for k, p in enumerate(self.pairs)}
        t1 = [col[c] for c in TYPE1]
        t2 = [col[c] for c in TYPE2]
        out[:, 3] = fn[:, t1].mean(axis=1)
        out[:, 4] = fn[:, t2].mean(axis=1)
        out[:, 5] = (ft[:, t1] * np.array(TYPE1_SIGN)).mean(axis=1)
        out[:, 6] = pos[:, 3, 0] - pos[:, 0, 0]
        out[:, 7] = 0.5 * (pos[:, 1, 1] + pos[:, 2, 1] - pos[:, 4, 1] - pos[:, 5, 1])
        if not self.standard:
            out[:, 8:8 + 2 * self.n_grains] = pos.reshape(n, -1)
            out[:, 8 + 2 * self.n_grains:] = ft
        return out

    def _radii(self, params: Params) -> np.ndarray:
        return self.cell(params, params.alpha0).radii

    def _normal(self, params: Params, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Normal forces kn x overlap (n, P) and closed-contact mask of every pair."""
        r = self._radii(params)
        i, j = self.pairs.T
        b = pos[:, j] - pos[:, i]
        overlap = r[i] + r[j] - np.hypot(b[..., 0], b[..., 1])
        return params.kn * np.maximum(overlap, 0.0), overlap >= 0.0

    def _unpack(self, params: Params, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centres (n, g, 2) and pair forces (n, P) of state rows (n, n_fields)."""
        n = len(values)
        if not self.standard:
            g = self.n_grains
            return values[:, 8:8 + 2 * g].reshape(n, g, 2), values[:, 8 + 2 * g:]
        d2, t1, l1, l2 = values[:, 1], values[:, 5], values[:, 6], values[:, 7]
        z = np.zeros(n)
        pos = np.stack([np.stack(p, axis=-1) for p in (
            (-l1 / 2, z), (-d2 / 2, l2 / 2), (d2 / 2, l2 / 2), (l1 / 2, z), (d2 / 2, -l2 / 2),
            (-d2 / 2, -l2 / 2))], axis=1)
        ft = np.zeros((n, len(self.pairs)))
        col = {tuple(p): k for k, p in enumerate(self.pairs)}
        for c, s in zip(TYPE1, TYPE1_SIGN):
            ft[:, col[c]] = s * t1
        return pos, ft

    # -- solver interface -------------------------------------------------------------
    def step(self, params: Params, state: CellState, dl1: np.ndarray,
             dl2: np.ndarray) -> tuple[CellState, CellFlags]:
        values = np.asarray(state.values, float)
        if values.shape[-1] != self.n_fields:
            raise InputError(f"{self.name}: cell states have {values.shape[-1]} fields, this solver "
                             f"needs {self.n_fields} (start from its initial state)")
        shape = values.shape[:-1]
        dl = np.stack(np.broadcast_arrays(np.asarray(dl1, float), np.asarray(dl2, float)), -1)
        dl = np.broadcast_to(dl, (*shape, 2)).reshape(-1, 2)
        if not np.all(np.isfinite(dl)):
            raise InputError("DEM increments must be finite")
        flat = values.reshape(-1, self.n_fields)
        # A length increment as long as the cell itself is no cell increment (a run-away
        # Newton trial): refused before YADE is asked to drive grains through each other.
        worst = np.abs(dl) / np.maximum(np.abs(flat[:, 6:8]), 1e-300) if len(flat) else np.zeros((0, 2))
        if worst.size and worst.max() >= 1.0:
            k = np.unravel_index(int(np.argmax(worst)), worst.shape)
            raise SolverError(f"{self.name}: a cell length increment of {dl[k]:.3g} m on a cell of "
                              f"length {flat[k[0], 6 + k[1]]:.3g} m (at most the cell's length)")
        if flat.shape[0] == 0:
            return CellState(values.copy()), CellFlags.none(shape)
        rows, inverse = np.unique(np.hstack([flat, dl]), axis=0, return_inverse=True)
        new, flags = self._solve(params, rows)
        inverse = inverse.reshape(-1)
        return (CellState(np.ascontiguousarray(new[inverse].reshape(*shape, self.n_fields))),
                CellFlags(np.ascontiguousarray(flags[inverse].reshape(*shape, len(FLAGS)))))

    def _solve(self, params: Params, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """New states and flags of unique (state, increment) rows; those of the previous request
        are taken from it (the answer depends on the row only), the others run in YADE."""
        new = np.empty((len(rows), self.n_fields))
        flags = np.empty((len(rows), len(FLAGS)), bool)
        todo = np.ones(len(rows), bool)
        last = self._last
        if last is not None and last[0] == params:
            _, first, inv = np.unique(np.vstack([last[1], rows]), axis=0, return_index=True,
                                      return_inverse=True)
            src = first[inv.reshape(-1)[len(last[1]):]]
            todo = src >= len(last[1])
            new[~todo], flags[~todo] = last[2][src[~todo]], last[3][src[~todo]]
        if todo.any():
            new[todo], flags[todo] = self._run(params, rows[todo, :-2], rows[todo, -2:])
        self._last = (params, rows, new, flags)
        return new, flags

    def _run(self, params: Params, values: np.ndarray, dl: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pos, ft = self._unpack(params, values)
        r = self._radii(params)
        proto = self.cell(params, params.alpha0)
        _, closed = self._normal(params, pos)
        o = self.options
        r_ref = float(np.max(r))
        req = {"kn": params.kn, "kt_kn": params.kt_kn, "phi_g": params.phi_g, "r_ref": r_ref,
               "density": 1.0, "mass": 4.0 / 3.0 * math.pi * r_ref ** 3, "gap": 2.0 * r_ref,
               "tol": o.tol, "max_iter": o.max_iter, "substeps": o.substeps, "damping": o.damping,
               "dt_safety": o.dt_safety, "check_every": o.check_every,
               "detect_margin": o.detect_margin}
        cells = []
        for k in range(len(values)):
            half = float(np.max(np.abs(pos[k, :, 0]) + r))
            height = float(np.max(np.abs(pos[k, :, 1]) + r))
            shear = [[int(i), int(j), float(ft[k, p])] for p, (i, j) in enumerate(self.pairs)
                     if closed[k, p] and ft[k, p] != 0.0]
            cells.append({"radii": r.tolist(), "pos": pos[k].tolist(), "drive": list(proto.drive),
                          "l": [float(values[k, 6]), float(values[k, 7])], "half_width": half,
                          "half_height": height, "increment": dl[k].tolist(), "shear": shear})
        done = []
        for k in range(0, len(cells), o.max_cells):
            done += self.yade().request({**req, "cells": cells[k:k + o.max_cells]}, timeout=o.timeout)["cells"]
        n = len(values)
        new_pos = np.array([c["pos"] for c in done], float).reshape(n, self.n_grains, 2)
        new_ft = np.zeros((n, len(self.pairs)))
        col = {tuple(p): k for k, p in enumerate(self.pairs)}
        contact = np.zeros((n, len(self.pairs)), bool)
        fn = np.zeros((n, len(self.pairs)))
        for k, c in enumerate(done):
            for row in c["contacts"]:
                p = col[(int(row[0]), int(row[1]))]
                contact[k, p] = True
                fn[k, p] = row[2]
                new_ft[k, p] = row[3]
        out = self._pack(params, new_pos, new_ft)
        t1 = [col[c] for c in TYPE1]
        t2 = [col[c] for c in TYPE2]
        mu = math.tan(params.phi_g)
        sliding = np.any(contact[:, t1] & (np.abs(new_ft[:, t1]) >= mu * fn[:, t1] * (1 - 5e-3))
                         & (fn[:, t1] > 0), axis=1)
        flags = np.stack([sliding, ~contact[:, t1].all(axis=1), ~contact[:, t2].all(axis=1),
                          contact[:, col[(0, 3)]], contact[:, col[(1, 5)]] | contact[:, col[(2, 4)]]],
                         axis=1)
        return out, flags

    # -- meso-stress hook for the REV -------------------------------------------------
    def meso(self, params: Params, state: CellState) -> tuple[np.ndarray, np.ndarray] | None:
        """(V sigma_nn, V sigma_tt, V sigma_nt) (..., 3) [N m] and meso-volume (...) [m^2].

        None for the standard cell, whose stress is eq. 1.12 of its 8 fields (the REV then
        keeps its compiled path). Otherwise the symmetric Love-Weber sum over the closed
        contacts, compression positive, and the area of the driven grains' polygon.
        """
        if self.standard:
            return None
        values = np.asarray(state.values, float)
        shape = values.shape[:-1]
        vsig, vol = self.love_weber(params, values.reshape(-1, self.n_fields))
        return vsig.reshape(*shape, 3), vol.reshape(shape)

    def kernel(self, params: Params) -> None:
        """None: every cell increment is a YADE run (the generic loading driver)."""
        return None

    def love_weber(self, params: Params, flat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(V sigma_nn, V sigma_tt, V sigma_nt) (n, 3) and meso-volume (n,) of state rows (n,
        n_fields), every layout (for the standard cell it equals eq. 1.12 of its fields)."""
        pos, ft = self._unpack(params, flat)
        fn, closed = self._normal(params, pos)
        i, j = self.pairs.T
        b = pos[:, j] - pos[:, i]
        e = b / np.hypot(b[..., 0], b[..., 1])[..., None]
        tang = np.stack([e[..., 1], -e[..., 0]], axis=-1)
        f = (fn[..., None] * e + ft[..., None] * tang) * closed[..., None]
        vs = np.einsum("npa,npb->nab", f, b)
        vsig = np.stack([vs[:, 0, 0], vs[:, 1, 1], 0.5 * (vs[:, 0, 1] + vs[:, 1, 0])], axis=-1)
        return vsig, self.cell(params, params.alpha0).volume(pos)

    def with_options(self, **changes) -> "DEMSolver":
        """A copy with other :class:`DEMOptions`."""
        copy = DEMSolver(self.name)
        copy.options = replace(self.options, **changes)
        return copy
