"""The representative elementary volume: many material points, each a population of H-cells.

A :class:`Rev` holds what does not change along a path (parameters, directions, the cell
solver); a :class:`RevState` is the state of ``B`` independent material points with
``n_theta`` cells each. :meth:`Rev.step` returns a new state and never writes the old one.

Strains and stresses are ``(..., 3)`` arrays ``(11, 22, 12)``, tensor components, soil-mechanics
signs (compression positive); stresses in Pa.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..cell import CellFlags, CellKernel, CellSolver, CellState, ClosedFormSolver, meso_volume
from ..errors import InputError, SolverError
from ..limits import check_memory
from ..params import Params, check_batch
from .directions import Directions
from .kernels import LOC_BOX, LOC_CELL, LOC_VIRTUAL, average, localize

_LOC_MODE = {"hexagon": LOC_CELL, "rectangle": LOC_CELL, "box": LOC_BOX,
             "hexagon-consistent": LOC_VIRTUAL}


def _normal(n: int) -> int:
    """Normal components of a (..., n) strain or stress: 2 in 2D (n = 3), 3 in 3D (n = 6)."""
    if n not in (3, 6):
        raise InputError(f"a strain or stress has 3 (2D) or 6 (3D) components, got {n}")
    return 2 if n == 3 else 3


def mean_stress(sig: np.ndarray) -> np.ndarray:
    """p (...) of stresses (..., n): the mean of the normal components."""
    if _normal(sig.shape[-1]) == 2:
        return 0.5 * (sig[..., 0] + sig[..., 1])
    return (sig[..., 0] + sig[..., 1] + sig[..., 2]) / 3.0


def deviatoric_stress(sig: np.ndarray) -> np.ndarray:
    """q (...) of stresses (..., n): sig11 - sig22 in 2D (the report's q, §1.1.2); in 3D
    sig11 - (sig22 + sig33)/2, axis 1 axial: sig_a - sig_r in a triaxial test, negative in
    extension (the contract of DESIGN.md; :func:`equivalent_stress` is the invariant)."""
    if _normal(sig.shape[-1]) == 2:
        return sig[..., 0] - sig[..., 1]
    return sig[..., 0] - 0.5 * (sig[..., 1] + sig[..., 2])


def equivalent_stress(sig: np.ndarray) -> np.ndarray:
    """sqrt(3 J2) (...) of 3D stresses (..., 6) (tensor shear components 23, 13, 12): |q| in a
    triaxial test, and the same in every frame."""
    s11, s22, s33 = sig[..., 0], sig[..., 1], sig[..., 2]
    shear = sig[..., 3] ** 2 + sig[..., 4] ** 2 + sig[..., 5] ** 2
    return np.sqrt(0.5 * ((s11 - s22) ** 2 + (s22 - s33) ** 2 + (s33 - s11) ** 2) + 3.0 * shear)


def volumetric_strain(eps: np.ndarray) -> np.ndarray:
    """eps_v (...) of strains (..., n): the trace."""
    if _normal(eps.shape[-1]) == 2:
        return eps[..., 0] + eps[..., 1]
    return eps[..., 0] + eps[..., 1] + eps[..., 2]


@dataclass(frozen=True)
class RevState:
    """State of B material points.

    Attributes
    ----------
    cells : CellState, shape (B, n_theta)
    flags : CellFlags, shape (B, n_theta)
    eps : ndarray (B, n)   cumulative macro strain: (eps11, eps22, eps12) in 2D, n = 3
    sig : ndarray (B, n)   macro stress [Pa], the same components (3D: :mod:`hmodel.rev.rev3d`)
    sets : ndarray (B,) int or None
        Each point's parameter set, an index into :attr:`Rev.sets` (None: the first for all).
    """

    cells: CellState
    flags: CellFlags
    eps: np.ndarray
    sig: np.ndarray
    sets: np.ndarray | None = None

    @property
    def n_points(self) -> int:
        return self.eps.shape[0]

    @property
    def set_index(self) -> np.ndarray:
        """Each point's parameter set (B,), zeros where all share the first."""
        return np.zeros(self.n_points, np.int64) if self.sets is None else self.sets

    @property
    def n_components(self) -> int:
        """Strain and stress components: 3 in 2D (11, 22, 12), 6 in 3D (11, 22, 33, 23, 13, 12)."""
        return self.eps.shape[1]

    @property
    def p(self) -> np.ndarray:
        """Mean stress [Pa]: (sig11 + sig22)/2 in 2D, (sig11 + sig22 + sig33)/3 in 3D."""
        return mean_stress(self.sig)

    @property
    def q(self) -> np.ndarray:
        """Deviatoric stress [Pa]: sig11 - sig22 in 2D, sig11 - (sig22 + sig33)/2 in 3D."""
        return deviatoric_stress(self.sig)

    @property
    def eps_v(self) -> np.ndarray:
        """Volumetric strain, the trace of the strain (compression positive)."""
        return volumetric_strain(self.eps)

    def where(self, mask: np.ndarray, other: "RevState") -> "RevState":
        """Material points of ``self`` where ``mask`` (B,) is true, else those of ``other``."""
        m = np.asarray(mask, dtype=bool)
        return RevState(self.cells.where(m[:, None], other.cells),
                        CellFlags(np.where(m[:, None, None], self.flags.flags, other.flags.flags)),
                        np.where(m[:, None], self.eps, other.eps),
                        np.where(m[:, None], self.sig, other.sig), self.sets)

    def select(self, index) -> "RevState":
        """Sub-batch of material points (index array or slice)."""
        return RevState(CellState(self.cells.values[index]), CellFlags(self.flags.flags[index]),
                        self.eps[index], self.sig[index],
                        None if self.sets is None else self.sets[index])

    def scatter(self, index: np.ndarray, sub: "RevState") -> "RevState":
        """A copy with the material points at ``index`` replaced by those of ``sub``."""
        parts = []
        for mine, theirs in ((self.cells.values, sub.cells.values), (self.flags.flags, sub.flags.flags),
                             (self.eps, sub.eps), (self.sig, sub.sig)):
            arr = mine.copy()
            arr[index] = theirs
            parts.append(arr)
        return RevState(CellState(parts[0]), CellFlags(parts[1]), parts[2], parts[3], self.sets)

    def fractions(self) -> dict[str, np.ndarray]:
        """Weighted-free fraction of hexagons per diagnostic, each (B,) (a bi-hexagon has two
        hexagons; its contact 1-4 is shared, counted once)."""
        h = self.flags.hexagons.astype(float)  # (B, cells, k, 5)
        frac = lambda a: a.mean(axis=(1, 2))  # noqa: E731
        opened = np.maximum(h[..., 1], h[..., 2])
        return {"frac_sliding": frac(h[..., 0]), "frac_open": frac(opened),
                "frac_contact14": h[..., 0, 3].mean(axis=1), "frac_contact26": frac(h[..., 4])}


class Rev:
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
        #: the parameter sets (K,), and the first, whose shared fields all sets have
        self.sets = check_batch(params)
        self.params = params = self.sets[0]
        self.solver = solver
        self.check_size(len(self.sets))
        self.directions = d = Directions.from_params(params)
        self._trig = (d.cos2, d.sin2, d.sincos)
        #: direction weights of eq. 1.17 per set (K, n_theta): the fabric is a material property
        self.weights = np.stack([Directions.from_params(s).weights for s in self.sets])
        self._wtrig = tuple(np.ascontiguousarray(self.weights * t) for t in self._trig)
        self._kn = np.array([s.kn for s in self.sets])
        #: localization mode of the meso-volume option (eq. 1.1 on l or l*), for the kernels
        self.mode = _LOC_MODE[params.volume]
        cell0 = [solver.initial(s, ()) for s in self.sets]
        # cells with their own meso-stress (richer DEM cells, meso surrogates), or eq. 1.12
        self._own_meso = solver.meso(params, cell0[0]) is not None
        # Initial macro volume V0 = sum_i w_i V_meso,i (eq. 1.14) per set; all cells start alike.
        vol0 = np.array([float(solver.meso(s, c)[1]) if self._own_meso else float(meso_volume(s, c))
                         for s, c in zip(self.sets, cell0)])
        #: initial macro volume of each set's points (K,)
        self.volumes0 = vol0 * self.weights.sum(axis=1)
        kernels = [solver.kernel(s) for s in self.sets]
        #: the solver's compiled increment of each set (None: the loading drivers call
        #: ``solver.step``)
        self.kernels: tuple[CellKernel, ...] | None = (None if any(k is None for k in kernels)
                                                          else tuple(kernels))

    @property
    def volume0(self) -> float:
        """Initial macro volume of the first set's points."""
        return float(self.volumes0[0])

    @property
    def kernel(self) -> CellKernel | None:
        """The first set's compiled increment (None: the solver has none)."""
        return None if self.kernels is None else self.kernels[0]

    @property
    def n_sets(self) -> int:
        return len(self.sets)

    @property
    def n_theta(self) -> int:
        return self.params.n_theta

    def check_size(self, n_points: int, what: str = "") -> None:
        """Refuse (:class:`~hmodel.limits.WorkTooLarge`) ``n_points`` material points whose
        cells would not fit in the memory budget of :mod:`hmodel.limits`; ``what`` names the
        request (default: the REV's points and directions)."""
        cells = float(n_points) * float(self.params.n_theta)
        check_memory(cells * self.solver.bytes_per_cell,
                     what or f"a REV of {n_points:,} material point{'s' if n_points != 1 else ''} × "
                             f"{self.params.n_theta:.4g} directions ({self.solver.name} cells)")

    def initial(self, n_points: int = 1) -> RevState:
        """B unloaded material points; with K > 1 parameter sets, the K points (B = K or 1)."""
        K = self.n_sets
        self.check_size(max(n_points, K))
        if K == 1:
            shape = (n_points, self.n_theta)
            return RevState(self.solver.initial(self.params, shape), CellFlags.none(shape),
                            np.zeros((n_points, 3)), np.zeros((n_points, 3)))
        if n_points not in (1, K):
            raise InputError(f"{K} parameter sets and {n_points} material points: give one "
                             "value or as many as the sets")
        shape = (K, self.n_theta)
        cells = np.stack([self.solver.initial(s, (self.n_theta,)).values for s in self.sets])
        return RevState(CellState(cells), CellFlags.none(shape), np.zeros((K, 3)),
                        np.zeros((K, 3)), np.arange(K))

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
        if self._own_meso:
            vsig = self._meso_stress(cells, idx)
        else:
            vsig = np.empty((cells.shape[0], 3))
            average(np.ascontiguousarray(cells.values[..., :8]).reshape(-1, 8), *self._wtrig,
                    self._kn, idx, self.params.radius, vsig)
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

    def solver_fractions(self, state: RevState) -> dict[str, np.ndarray]:
        """The cell solver's own diagnostics (:meth:`hmodel.cell.CellSolver.fractions`) as the
        fraction of each point's cells, name -> (B,)."""
        idx = state.set_index
        out: dict[str, np.ndarray] = {}
        for k in np.unique(idx):
            rows = idx == k
            cells = CellState(state.cells.values[rows])
            for name, hit in self.solver.fractions(self.sets[k], cells).items():
                frac = np.mean(np.reshape(hit, (int(rows.sum()), -1)), axis=1)
                out.setdefault(name, np.full(state.n_points, np.nan))[rows] = frac
        return out

    def _by_set(self, idx: np.ndarray, call):
        """``call(set, rows)`` for each parameter set present in idx (B,), its outputs (arrays
        or tuples of arrays over the rows' points) put back in point order."""
        if self.n_sets == 1:
            return call(self.params, slice(None))
        present = np.unique(idx)
        if len(present) == 1:
            return call(self.sets[present[0]], slice(None))
        parts = [(np.flatnonzero(idx == k), call(self.sets[k], idx == k)) for k in present]

        def merge(pieces):
            out = np.empty((len(idx), *pieces[0][1].shape[1:]), pieces[0][1].dtype)
            for rows, piece in pieces:
                out[rows] = piece
            return out
        if isinstance(parts[0][1], tuple):
            return tuple(merge([(r, p[j]) for r, p in parts]) for j in range(len(parts[0][1])))
        return merge(parts)

    def step(self, state: RevState, deps: np.ndarray) -> RevState:
        """Apply macro strain increments ``deps`` (B, 3) in one cell increment."""
        deps = np.asarray(deps, dtype=float)
        if not np.all(np.isfinite(deps)):
            raise SolverError(f"non-finite strain increment at strain {state.eps.tolist()}")
        dl = self.localize(state.cells, deps)
        idx = state.set_index

        def cell_step(s, rows):
            new, flags = self.solver.step(s, CellState(state.cells.values[rows]), dl[rows, :, 0],
                                          dl[rows, :, 1])
            return new.values, flags.flags
        values, flags = self._by_set(idx, cell_step)
        cells = CellState(values)
        eps = state.eps + deps
        return RevState(cells, CellFlags(flags), eps, self.stress(cells, eps, state.sets), state.sets)
