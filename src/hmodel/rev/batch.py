"""What the 2D and the 3D REV share: a batch of material points of one or more parameter sets.

:class:`RevBatch` holds the parameter sets, the work-size guard, the unloaded points, the
dispatch of a call to the points of each set and the cell solver's diagnostics; the 2D
:class:`~hmodel.rev.Rev` and the 3D :class:`~hmodel.rev.rev3d.Rev3D` add their directions,
localization and averaging.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from ..cell import CellFlags, CellState
from ..cell.base import check_mechanisms
from ..errors import InputError, SolverError
from ..limits import check_memory, table_bytes
from ..params import Params
from .state import RevState


class RevBatch:
    """The shared part of a REV. A subclass sets ``sets``, ``params``, ``solver``,
    ``volumes0`` and ``kernels`` and defines :attr:`n_cells`, :meth:`_describe` and
    :meth:`_no_flags`, ``localize`` and ``stress``."""

    #: strain and stress components of its states
    n_components: int
    sets: tuple[Params, ...]
    params: Params
    volumes0: np.ndarray
    kernels: tuple | None

    @property
    def n_cells(self) -> int:
        """Cells per material point."""
        raise NotImplementedError

    def _describe(self, n_points: int) -> str:
        """What a request of ``n_points`` points is, for the size guard's message."""
        raise NotImplementedError

    def _no_flags(self, shape: tuple[int, ...]) -> CellFlags:
        """The flags of unloaded cells of ``shape``."""
        raise NotImplementedError

    @property
    def n_sets(self) -> int:
        return len(self.sets)

    @property
    def volume0(self) -> float:
        """Initial macro volume of the first set's points."""
        return float(self.volumes0[0])

    @property
    def kernel(self):
        """The first set's compiled increment (None: the solver has none)."""
        return None if self.kernels is None else self.kernels[0]

    def kernel_inputs(self) -> tuple[np.ndarray, np.ndarray]:
        """The inputs of the compiled trial of a point (:func:`hmodel.rev.trial.point_trial`),
        the same encoding in 2D and 3D: the cells' geometry rows (G, C, width), one block per
        parameter set (G = K) or one for all (G = 1), and each set's packed cell parameters
        (K, P) (:meth:`hmodel.cell.CellSolver.kernel`). Built once; read-only."""
        return self._kernel_inputs

    @cached_property
    def _kernel_inputs(self) -> tuple[np.ndarray, np.ndarray]:
        if self.kernels is None:
            raise InputError(f"{self.solver.name} cells have no compiled increment: the REV runs on "
                             "the generic driver")
        return (np.ascontiguousarray(self._kernel_geometry()),
                np.ascontiguousarray(np.stack([k.params for k in self.kernels])))

    def _kernel_geometry(self) -> np.ndarray:
        """The geometry rows (G, C, width) of :meth:`kernel_inputs`."""
        raise NotImplementedError

    def check_mechanisms(self) -> None:
        """Refuse (one-line :class:`~hmodel.errors.InputError`) parameter sets that switch on a
        cell mechanism the solver's cells do not implement
        (:func:`hmodel.cell.base.check_mechanisms`): the one place where a REV meets its
        solver's cells."""
        check_mechanisms(self.solver, self.sets)

    def check_size(self, n_points: int, what: str = "", extra_bytes: float = 0.0, rows: int = 0,
                   columns: int = 0) -> None:
        """Refuse (:class:`~hmodel.limits.WorkTooLarge`) ``n_points`` material points whose
        cells would not fit in the memory budget of :mod:`hmodel.limits` together with
        ``extra_bytes`` held beside them (the 3D REV's geometry) and a result table of ``rows``
        rows of ``columns`` values (:func:`~hmodel.limits.table_bytes`); ``what`` names the
        request (default: the REV's points and cells, and the table)."""
        cells = float(n_points) * float(self.n_cells)
        nbytes = cells * self.solver.bytes_per_cell + extra_bytes + table_bytes(rows, columns)
        if not what:
            what = self._describe(n_points) + (f" and a result table of {rows:,} rows" if rows else "")
        check_memory(nbytes, what)

    def initial(self, n_points: int = 1) -> RevState:
        """B unloaded material points; with K > 1 parameter sets, the K points (B = K or 1)."""
        K, C, n = self.n_sets, self.n_cells, self.n_components
        self.check_size(max(n_points, K))
        if K == 1:
            shape = (n_points, C)
            return RevState(self._initial_cells(self.params, shape), self._no_flags(shape),
                            np.zeros((n_points, n)), np.zeros((n_points, n)))
        if n_points not in (1, K):
            raise InputError(f"{K} parameter sets and {n_points} material points: give one "
                             "value or as many as the sets")
        cells = np.stack([self._initial_cells(s, (C,)).values for s in self.sets])
        return RevState(CellState(cells), self._no_flags((K, C)), np.zeros((K, n)),
                        np.zeros((K, n)), np.arange(K))

    def _initial_cells(self, params, shape: tuple[int, ...]) -> CellState:
        """Unloaded cells of one parameter set, shape (..., n_cells): all alike here."""
        return self.solver.initial(params, shape)

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

    def step(self, state: RevState, deps: np.ndarray) -> RevState:
        """Apply macro strain increments ``deps`` (B, n) in one cell increment: localization
        (eq. 1.1), the cell solver on each set's points (its ``n_lengths`` length increments),
        averaging (eq. 1.15)."""
        deps = np.asarray(deps, dtype=float)
        if not np.all(np.isfinite(deps)):
            raise SolverError(f"non-finite strain increment at strain {state.eps.tolist()}")
        dl = self.localize(state.cells, deps)

        def cell_step(s, rows):
            lengths = [dl[rows, :, k] for k in range(self.solver.n_lengths)]
            new, flags = self.solver.step(s, CellState(state.cells.values[rows]), *lengths)
            return new.values, flags.flags
        if self.n_sets > 1 and self.solver.batches_sets:
            # a family network takes every set's cells in one call (its material is an input)
            values, flags = self.solver.step_sets(self.sets, state.set_index, state.cells,
                                                  *(dl[..., k] for k in range(self.solver.n_lengths)))
        else:
            values, flags = self._by_set(state.set_index, cell_step)
        self._renew(state, values, flags, dl)
        cells = CellState(values)
        eps = state.eps + deps
        return RevState(cells, CellFlags(flags), eps, self.stress(cells, eps, state.sets), state.sets)

    #: ``renewal="mix"`` of the generic path, on the points of one set: the REV's compiled
    #: rebirths (``kernels.renew_mix``, ``kernels3d.renew_mix3d``), called with the cells at the
    #: start, the stepped cells and flags, the set's geometry rows, δl1 and 2r
    _mix_kernel = None

    def _renew(self, state: RevState, values: np.ndarray, flags: np.ndarray, dl: np.ndarray) -> None:
        """The REV's own part of a cell mechanism, in place on the cells ``values`` and ``flags``
        just stepped from ``state`` by the length increments ``dl``: ``renewal="mix"`` reborn the
        opened cells of each set that asks for it at the mean box of their point's cells, as the
        fused trial does (it needs a REV quantity, so the cell solver cannot)."""
        for k in self._mix_sets:
            s = self.sets[k]
            rows = np.flatnonzero(state.set_index == k)
            if len(rows):
                geo = self.kernel_inputs()[0]  # built once; one block for all sets, or one each
                v, f = values[rows], flags[rows]
                self._mix_kernel(state.cells.values[rows], v, f, geo[k if len(geo) > 1 else 0],
                                 dl[rows, :, 0], 2.0 * s.radius)
                values[rows], flags[rows] = v, f

    @cached_property
    def _mix_sets(self) -> tuple[int, ...]:
        """The parameter sets with ``renewal="mix"``: a calibration batch of many sets without
        it pays no scan of its points per set on every step."""
        return tuple(k for k, s in enumerate(self.sets) if s.renewal == "mix")

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
