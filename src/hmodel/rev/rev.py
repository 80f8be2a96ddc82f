"""The representative elementary volume: many material points, each a population of H-cells.

A :class:`Rev` holds what does not change along a path (parameters, directions, the cell
solver); a :class:`RevState` is the state of ``B`` independent material points with
``n_theta`` cells each. :meth:`Rev.step` returns a new state and never writes the old one.

Strains and stresses are ``(..., 3)`` arrays ``(11, 22, 12)``, tensor components, soil-mechanics
signs (compression positive); stresses in Pa.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..cell import (
    CellFlags,
    CellKernel,
    CellSolver,
    CellState,
    ClosedFormSolver,
    meso_volume,
)
from ..cell.closed_form import P_HERTZ, kernel_params
from ..errors import InputError
from ..params import Params, check_batch
from .batch import RevBatch
from .directions import Directions, opening_angles
from .kernels import LOC_BOX, LOC_CELL, LOC_VIRTUAL, average, localize, renew_mix
from .state import (  # noqa: F401
    RevState,
    deviatoric_stress,
    equivalent_stress,
    mean_stress,
    volumetric_strain,
)

_LOC_MODE = {"hexagon": LOC_CELL, "rectangle": LOC_CELL, "box": LOC_BOX,
             "hexagon-consistent": LOC_VIRTUAL}


class Rev(RevBatch):
    """Directional averaging of H-cells (eqs. 1.1, 1.13-1.21) over a batch of material points.

    Parameters
    ----------
    params : Params or sequence of Params
        One parameter set for every material point, or one per point (material parameters may
        differ; n_theta, radius and volume are shared: :func:`hmodel.params.check_batch`).
        With K > 1 sets, a state has K points, point b with set b.
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

    #: strain and stress components of its states (11, 22, 12)
    n_components = 3

    def __init__(self, params: Params | Sequence[Params], solver: CellSolver | None = None):
        if solver is None:
            solver = ClosedFormSolver()
        elif not isinstance(solver, CellSolver):
            raise InputError(f"Rev takes a cell solver, got {solver!r} (resolve a spec with "
                             "hmodel.solvers.get_solver)")
        elif solver.n_lengths != 2:
            raise InputError(f"the 2D REV's cells take two lengths; {solver.name!r} is a 3D cell "
                             f"solver ({solver.n_lengths} lengths: the 3D model's run triaxial, "
                             "true-triaxial, oedometer)")
        #: the parameter sets (K,), and the first, whose shared fields all sets have
        self.sets = check_batch(params)
        self.params = params = self.sets[0]
        self.solver = solver
        self.check_mechanisms()
        self.check_size(len(self.sets))
        self.directions = d = Directions.from_params(params)
        self._trig = (d.cos2, d.sin2, d.sincos)
        #: direction weights of eq. 1.17 per set (K, n_theta): the fabric is a material property
        self.weights = np.stack([Directions.from_params(s).weights for s in self.sets])
        self._wtrig = tuple(np.ascontiguousarray(self.weights * t) for t in self._trig)
        self._kn = np.array([s.kn for s in self.sets])
        self._hertz = np.array([kernel_params(s)[P_HERTZ] for s in self.sets])
        #: localization mode of the meso-volume option (eq. 1.1 on l or l*), for the kernels
        self.mode = _LOC_MODE[params.volume]
        spread = [s for s in self.sets if s.alpha0_spread > 0]
        if spread and not solver.spread_alpha0:
            # the closed form's state carries each cell's α0; a network or DEM cell may read
            # α0 from the parameters as well (CellSolver.spread_alpha0)
            raise InputError(f"alpha0_spread > 0 is implemented for the closed-form H-cell, not "
                             f"for {solver.name} cells")
        cell0 = [solver.initial(s, ()) for s in self.sets]
        #: cells with their own meso-stress (richer DEM cells, meso surrogates), or eq. 1.12
        self.own_meso = solver.meso(params, cell0[0]) is not None
        # Initial macro volume V0 = sum_i w_i V_meso,i (eq. 1.14) per set; all cells start alike
        # but with a spread of α0
        vol0 = np.array([float(solver.meso(s, c)[1]) if self.own_meso else float(meso_volume(s, c))
                         for s, c in zip(self.sets, cell0)])
        #: initial macro volume of each set's points (K,)
        self.volumes0 = vol0 * self.weights.sum(axis=1)
        for k, s in enumerate(self.sets):
            if s.alpha0_spread > 0:
                self.volumes0[k] = float(self.weights[k] @ meso_volume(s, self._initial_cells(s, ())))
        kernels = [solver.kernel(s) for s in self.sets]
        #: the solver's compiled increment of each set (None: the loading drivers call
        #: ``solver.step``)
        self.kernels: tuple[CellKernel, ...] | None = (None if any(k is None for k in kernels)
                                                          else tuple(kernels))

    def _initial_cells(self, params: Params, shape: tuple[int, ...]) -> CellState:
        """Unloaded cells of one set, shape (..., n_theta), each direction with its own α0
        (:func:`~hmodel.rev.directions.opening_angles`) where the set has a spread of them."""
        if params.alpha0_spread == 0:
            return self.solver.initial(params, shape)
        alpha0 = opening_angles(params)
        return self.solver.initial_cells(params, np.broadcast_to(alpha0, (*shape[:-1], len(alpha0)))
                                         if shape else alpha0)

    @property
    def n_theta(self) -> int:
        return self.params.n_theta

    @property
    def n_cells(self) -> int:
        """Cells per material point: one per direction."""
        return self.params.n_theta

    def _describe(self, n_points: int) -> str:
        return (f"a REV of {n_points:,} material point{'s' if n_points != 1 else ''} × "
                f"{self.params.n_theta:.4g} directions ({self.solver.name} cells)")

    def _no_flags(self, shape: tuple[int, ...]) -> CellFlags:
        return CellFlags.none(shape)

    _mix_kernel = staticmethod(renew_mix)  # RevBatch._renew

    def _kernel_geometry(self) -> np.ndarray:
        """Each set's direction factors (K, n_theta, 6) of the 2D trial
        (:func:`hmodel.rev.kernels.trial`): cos², sin², sin·cos and each times the set's weight."""
        d = self.directions
        return np.stack([np.stack([d.cos2, d.sin2, d.sincos, w * d.cos2, w * d.sin2, w * d.sincos],
                                  axis=-1) for w in self.weights])

    def localize(self, cells: CellState, deps: np.ndarray) -> np.ndarray:
        """Length increments (B, n_theta, 2) of every cell for macro strain increments (B, 3)."""
        values = np.ascontiguousarray(cells.values[..., :8]).reshape(-1, 8)
        dl = np.empty((values.shape[0], 2))
        localize(values, np.ascontiguousarray(deps, dtype=float), *self._trig, self.mode,
                 self.params.radius, dl)
        return dl.reshape(*cells.shape, 2)

    def macro_volume(self, eps: np.ndarray, sets: np.ndarray | None = None) -> np.ndarray:
        """V = V0 det(I - eps): the macro volume follows the macro strain (B,)."""
        v0 = self.volume0 if sets is None else self.volumes0[sets]
        return v0 * ((1 - eps[:, 0]) * (1 - eps[:, 1]) - eps[:, 2] ** 2)

    def stress(self, cells: CellState, eps: np.ndarray, sets: np.ndarray | None = None) -> np.ndarray:
        """Macro stress (B, 3) of cells (B, n_theta) at macro strain eps (B, 3) (eq. 1.15),
        the points' parameter sets ``sets`` (B,) (None: the first for all)."""
        idx = np.zeros(cells.shape[0], np.int64) if sets is None else np.asarray(sets, np.int64)
        if self.own_meso:
            vsig = self._meso_stress(cells, idx)
        else:
            vsig = np.empty((cells.shape[0], 3))
            average(np.ascontiguousarray(cells.values[..., :8]).reshape(-1, 8), *self._wtrig,
                    self._kn, self._hertz, idx, self.params.radius, vsig)
        return vsig / self.macro_volume(eps, None if sets is None else idx)[:, None]

    def _meso_stress(self, cells: CellState, idx: np.ndarray) -> np.ndarray:
        """sum_i w_i V_i sigma_i (B, 3) from the solver's cell-frame (nn, tt, nt) meso-stress."""
        vs, _ = self._by_set(idx, lambda s, rows: self.solver.meso(s, CellState(cells.values[rows])))
        nn, tt, nt = vs[..., 0], vs[..., 1], vs[..., 2]
        wc2, ws2, wsc = (w[idx] for w in self._wtrig)
        c2s2 = self.weights[idx] * (self.directions.cos2 - self.directions.sin2)
        dot = lambda a, b: np.einsum("bi,bi->b", a, b)  # noqa: E731 (per-point weights)
        return np.stack([dot(nn, wc2) + dot(tt, ws2) - 2.0 * dot(nt, wsc),
                         dot(nn, ws2) + dot(tt, wc2) + 2.0 * dot(nt, wsc),
                         dot(nn - tt, wsc) + dot(nt, c2s2)], axis=-1)

