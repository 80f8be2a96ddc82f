"""The representative elementary volume: many material points, each a population of H-cells.

A :class:`Rev` holds what does not change along a path (parameters, directions, the cell
solver); a :class:`RevState` is the state of ``B`` independent material points with
``n_theta`` cells each. :meth:`Rev.step` returns a new state and never writes the old one.

Strains and stresses are ``(..., 3)`` arrays ``(11, 22, 12)``, tensor components, soil-mechanics
signs (compression positive); stresses in Pa.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..cell import CellFlags, CellKernel, CellSolver, CellState, ClosedFormSolver, meso_volume
from ..errors import InputError, SolverError
from ..params import Params
from .directions import Directions
from .kernels import LOC_BOX, LOC_CELL, LOC_VIRTUAL, average, localize

_LOC_MODE = {"hexagon": LOC_CELL, "rectangle": LOC_CELL, "box": LOC_BOX,
             "hexagon-consistent": LOC_VIRTUAL}


@dataclass(frozen=True)
class RevState:
    """State of B material points.

    Attributes
    ----------
    cells : CellState, shape (B, n_theta)
    flags : CellFlags, shape (B, n_theta)
    eps : ndarray (B, 3)   cumulative macro strain (eps11, eps22, eps12)
    sig : ndarray (B, 3)   macro stress (sig11, sig22, sig12) [Pa]
    """

    cells: CellState
    flags: CellFlags
    eps: np.ndarray
    sig: np.ndarray

    @property
    def n_points(self) -> int:
        return self.eps.shape[0]

    @property
    def p(self) -> np.ndarray:
        """Mean stress (sig11 + sig22)/2 [Pa]."""
        return 0.5 * (self.sig[:, 0] + self.sig[:, 1])

    @property
    def q(self) -> np.ndarray:
        """Deviatoric stress sig11 - sig22 [Pa]."""
        return self.sig[:, 0] - self.sig[:, 1]

    @property
    def eps_v(self) -> np.ndarray:
        """Volumetric strain eps11 + eps22 (compression positive)."""
        return self.eps[:, 0] + self.eps[:, 1]

    def where(self, mask: np.ndarray, other: "RevState") -> "RevState":
        """Material points of ``self`` where ``mask`` (B,) is true, else those of ``other``."""
        m = np.asarray(mask, dtype=bool)
        return RevState(self.cells.where(m[:, None], other.cells),
                        CellFlags(np.where(m[:, None, None], self.flags.flags, other.flags.flags)),
                        np.where(m[:, None], self.eps, other.eps),
                        np.where(m[:, None], self.sig, other.sig))

    def select(self, index) -> "RevState":
        """Sub-batch of material points (index array or slice)."""
        return RevState(CellState(self.cells.values[index]), CellFlags(self.flags.flags[index]),
                        self.eps[index], self.sig[index])

    def scatter(self, index: np.ndarray, sub: "RevState") -> "RevState":
        """A copy with the material points at ``index`` replaced by those of ``sub``."""
        parts = []
        for mine, theirs in ((self.cells.values, sub.cells.values), (self.flags.flags, sub.flags.flags),
                             (self.eps, sub.eps), (self.sig, sub.sig)):
            arr = mine.copy()
            arr[index] = theirs
            parts.append(arr)
        return RevState(CellState(parts[0]), CellFlags(parts[1]), parts[2], parts[3])

    def fractions(self) -> dict[str, np.ndarray]:
        """Weighted-free fraction of cells per diagnostic, each (B,)."""
        f = self.flags
        return {"frac_sliding": f.sliding.mean(axis=1), "frac_open": f.broken.mean(axis=1),
                "frac_contact14": f.contact14.mean(axis=1), "frac_contact26": f.contact26.mean(axis=1)}


class Rev:
    """Directional averaging of H-cells (eqs. 1.1, 1.13-1.21) over a batch of material points.

    Parameters
    ----------
    params : Params
    solver : CellSolver, optional
        The cell solver (default the closed form of eq. 1.7); resolve a spec such as
        ``"dem:standard"`` with :func:`hmodel.solvers.get_solver`.

    Examples
    --------
    >>> rev = Rev(Params(n_theta=36))
    >>> s = rev.step(rev.initial(2), np.array([[1e-4, 1e-4, 0.0], [2e-4, 2e-4, 0.0]]))
    >>> bool(abs(s.sig[0, 0] - s.sig[0, 1]) < 1e-9 * s.sig[0, 0]), bool(s.sig[1, 0] > s.sig[0, 0])
    (True, True)
    """

    def __init__(self, params: Params, solver: CellSolver | None = None):
        if solver is None:
            solver = ClosedFormSolver()
        elif not isinstance(solver, CellSolver):
            raise InputError(f"Rev takes a cell solver, got {solver!r} (resolve a spec with "
                             "hmodel.solvers.get_solver)")
        self.params = params
        self.solver = solver
        self.directions = d = Directions.from_params(params)
        self._trig = (d.cos2, d.sin2, d.sincos)
        self._wtrig = (d.weights * d.cos2, d.weights * d.sin2, d.weights * d.sincos)
        #: localization mode of the meso-volume option (eq. 1.1 on l or l*), for the kernels
        self.mode = _LOC_MODE[params.volume]
        cell0 = solver.initial(params, ())
        # cells with their own meso-stress (richer DEM cells, meso surrogates), or eq. 1.12
        self._own_meso = solver.meso(params, cell0) is not None
        # Initial macro volume V0 = sum_i w_i V_meso,i (eq. 1.14); all cells start alike.
        vol0 = solver.meso(params, cell0)[1] if self._own_meso else meso_volume(params, cell0)
        self.volume0 = float(vol0 * d.weights.sum())
        #: the solver's compiled increment (None: the loading drivers call ``solver.step``)
        self.kernel: CellKernel | None = solver.kernel(params)

    @property
    def n_theta(self) -> int:
        return self.params.n_theta

    def initial(self, n_points: int = 1) -> RevState:
        """B unloaded material points."""
        shape = (n_points, self.n_theta)
        cells = self.solver.initial(self.params, shape)
        return RevState(cells, CellFlags.none(shape),
                        np.zeros((n_points, 3)), np.zeros((n_points, 3)))

    def localize(self, cells: CellState, deps: np.ndarray) -> np.ndarray:
        """Length increments (B, n_theta, 2) of every cell for macro strain increments (B, 3)."""
        values = np.ascontiguousarray(cells.values[..., :8]).reshape(-1, 8)
        dl = np.empty((values.shape[0], 2))
        localize(values, np.ascontiguousarray(deps, dtype=float), *self._trig, self.mode,
                 self.params.radius, dl)
        return dl.reshape(*cells.shape, 2)

    def macro_volume(self, eps: np.ndarray) -> np.ndarray:
        """V = V0 det(I - eps): the macro volume follows the macro strain (B,)."""
        return self.volume0 * ((1 - eps[:, 0]) * (1 - eps[:, 1]) - eps[:, 2] ** 2)

    def stress(self, cells: CellState, eps: np.ndarray) -> np.ndarray:
        """Macro stress (B, 3) of cells (B, n_theta) at macro strain eps (B, 3) (eq. 1.15)."""
        if self._own_meso:
            return self._meso_stress(cells) / self.macro_volume(eps)[:, None]
        vsig = np.empty((cells.shape[0], 3))
        average(np.ascontiguousarray(cells.values[..., :8]).reshape(-1, 8), *self._wtrig,
                self.params.kn, self.params.radius, vsig)
        return vsig / self.macro_volume(eps)[:, None]

    def _meso_stress(self, cells: CellState) -> np.ndarray:
        """sum_i w_i V_i sigma_i (B, 3) from the solver's cell-frame (nn, tt, nt) meso-stress."""
        vs, _ = self.solver.meso(self.params, cells)
        nn, tt, nt = vs[..., 0], vs[..., 1], vs[..., 2]
        wc2, ws2, wsc = self._wtrig
        w = self.directions.weights
        c2s2 = w * (self.directions.cos2 - self.directions.sin2)
        return np.stack([nn @ wc2 + tt @ ws2 - 2.0 * (nt @ wsc),
                         nn @ ws2 + tt @ wc2 + 2.0 * (nt @ wsc),
                         (nn - tt) @ wsc + nt @ c2s2], axis=-1)

    def step(self, state: RevState, deps: np.ndarray) -> RevState:
        """Apply macro strain increments ``deps`` (B, 3) in one cell increment."""
        deps = np.asarray(deps, dtype=float)
        if not np.all(np.isfinite(deps)):
            raise SolverError(f"non-finite strain increment at strain {state.eps.tolist()}")
        dl = self.localize(state.cells, deps)
        cells, flags = self.solver.step(self.params, state.cells, dl[..., 0], dl[..., 1])
        eps = state.eps + deps
        return RevState(cells, flags, eps, self.stress(cells, eps))
