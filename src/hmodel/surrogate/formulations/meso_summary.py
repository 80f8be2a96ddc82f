"""The ``meso`` formulation's summary state (:mod:`hmodel.surrogate.formulations.meso`).

A richer DEM cell (the hexagon with a centre grain, ...) has no closed form and a state of
8 + 2g + g(g-1)/2 fields (grain centres, contact shear forces; :mod:`hmodel.cell.geometry`). Its
surrogate carries a summary of that state instead, 11 fields (:data:`STATE_FIELDS`): the 8
H-cell fields measured on the six hexagon grains (:data:`hmodel.cell.FIELDS`), which describe
the cell's shape and its outer contacts, and the cell's meso-stress times its meso-volume,
``Vs = V sigma`` (nn, tt, nt), the Love-Weber sum over all its contacts (eq. 1.11). What the
grains inside do enters through Vs, which is also all the REV needs of a cell (eqs. 1.13-1.14):
its meso-volume is the six driven grains' hexagon's, V = 2 d1 sin(alpha) (d2 + d1 cos(alpha))
(eq. 1.20, the DEM cells' meso-volume).

Training rows come from any cell solver: a richer DEM cell's extra state columns give its
Love-Weber stress (:meth:`MesoSummary.augment`); for H-cells (``closed-form``,
``dem:standard``) it is eq. 1.12 of the fields (with the extra contacts of over-compressed
cells), as in the REV.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from ...cell.base import CellSolver
from ...cell.geometry import CellGeometry
from ...cell.mesostress import meso_vsigma
from ...cell.state import FIELDS, CellState
from ...errors import InputError
from ...params import Params
from .base import MaterialScales

MESO_FIELDS = ("Vs_nn", "Vs_tt", "Vs_nt")
STATE_FIELDS = FIELDS + MESO_FIELDS
#: Column of each field in a summary state.
COLUMN = {k: j for j, k in enumerate(STATE_FIELDS)}


class MesoSummary(MaterialScales):
    """The summary state of cells of the solver ``self.cell`` for the material ``self.params``:
    its layout, its meso-stress and the summary of full cell states."""

    params: Params
    cell: str
    n_state = len(STATE_FIELDS)
    state_fields = STATE_FIELDS

    @cached_property
    def cell_solver(self) -> CellSolver:
        """The solver of the data's cells, as the one registry resolves ``self.cell``: what it
        declares says what its cells are."""
        from ...solvers import get_solver

        return get_solver(self.cell)

    @cached_property
    def geometry(self) -> CellGeometry:
        """The cells' geometry: state layout and Love-Weber sum (a DEM cell's, as its solver
        declares it; H-cells of a solver without one: the standard cell's)."""
        geometry = self.cell_solver.geometry
        return CellGeometry() if geometry is None else geometry

    @property
    def richer(self) -> bool:
        """A richer cell (more than the H-cell's 8 fields): V sigma is learned, not eq. 1.12."""
        return self.geometry.n_fields > len(FIELDS)

    def vsigma(self, full: np.ndarray) -> np.ndarray:
        """(V sigma_nn, V sigma_tt, V sigma_nt) (n, 3) of full cell states (n, n_fields): the
        Love-Weber sum of a richer cell's contacts; eq. 1.12 of an H-cell's fields, as the REV
        computes it (a sum over contacts rebuilt from positions would differ where the closed
        form's incremental d1, alpha drift from eq. 1.2 at second order: 1e-7 of a length is
        ~1e-3 of a force)."""
        full = np.asarray(full, float)
        if full.shape[1] == len(FIELDS):
            vs = meso_vsigma(self.params, CellState(np.ascontiguousarray(full)))
            return np.column_stack([vs, np.zeros(len(full))])
        return self.geometry.love_weber(self.params, full)[0]

    def summary(self, full: np.ndarray) -> np.ndarray:
        """Summary rows (n, 11) of full cell states (n, n_fields) of the data's solver."""
        return np.hstack([full[:, :8], self.vsigma(full)])

    def initial(self, params: Params, shape: tuple[int, ...] = ()) -> CellState:
        """Summary of unloaded cells of opening angle ``self.params.alpha0``, the one the model
        was trained for (``params``, the run's material, adds nothing to it)."""
        return CellState(np.broadcast_to(self._unloaded, (*shape, self.n_state)).copy())

    def initial_cells(self, params: Params, alpha0: np.ndarray) -> CellState:
        """Unloaded cells: a summary state knows one opening angle only, the trained one."""
        alpha0 = np.asarray(alpha0, float)
        if not np.allclose(alpha0, params.alpha0, rtol=0.0, atol=1e-12):
            raise InputError("a meso surrogate's cells start at the opening angle it was trained "
                             f"for (alpha0 = {np.degrees(params.alpha0):.6g} deg)")
        return self.initial(params, alpha0.shape)

    @cached_property
    def _unloaded(self) -> np.ndarray:
        """The summary (11,) of an unloaded cell."""
        return self.summary(self.cell_solver.initial(self.params, (1,)).values)[0]

    def meso(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(V sigma) (..., 3) and meso-volume (...) of summary states (..., 11), for the REV."""
        d1, d2, a = values[..., 0], values[..., 1], values[..., 2]
        return values[..., 8:11], 2 * d1 * np.sin(a) * (d2 + d1 * np.cos(a))  # eq. 1.20

    def augment(self, c: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Database columns plus the meso-stress before and after (``Vs_nn``, ``Vs_nn_next``, ...)."""
        if "Vs_nn" in c:
            return c
        n_extra = self.geometry.n_fields - 8
        if n_extra and "state_extra" not in c:
            raise InputError(f"rows of {self.cell} cells need their state_extra columns (a DEM dataset "
                             f"or a sample made from one)")
        out = dict(c)
        for suffix, extra in (("", "state_extra"), ("_next", "state_extra_next")):
            full = np.column_stack([c[k + suffix] for k in FIELDS]
                                   + ([np.asarray(c[extra], float).reshape(len(c["deps1"]), -1)] if n_extra else []))
            vs = self.vsigma(full)
            for j, k in enumerate(MESO_FIELDS):
                out[k + suffix] = vs[:, j]
        return out

    def _hexagon(self, v: np.ndarray) -> np.ndarray:
        """V sigma (n, 3) of the six hexagon grains' contacts: eq. 1.12 of the first 8 fields."""
        vs = meso_vsigma(self.params, CellState(np.ascontiguousarray(v[:, :8])))
        return np.column_stack([vs, np.zeros(len(v))])

    @cached_property
    def _cage(self) -> tuple[float, float, float]:
        """The reach of the cell's free grains, half the span of a chain of them all (the sum of
        their radii; 0 without free grains: a cage whose clearance at its centre exceeds it holds
        them without force), and the radii of the grains driven along n (1, 4) and t (2, 3, 5, 6)."""
        m = self.geometry.cell(self.params, self.params.alpha0)
        reach = sum(r for r, d in zip(m.radii, m.drive) if d == "free")
        return float(reach), float(m.radii[0]), float(m.radii[1])
