"""A richer cell's learned response gated to its DEM cell, which it keeps in step.

The ``meso`` surrogate of a richer cell (:mod:`hmodel.surrogate.formulations.meso`) carries an 11-field
summary of the cell; a DEM cell cannot restart from it (the grain centres and the tangential
forces of the inner contacts are not in it: rebuilt from the summary, the DEM increments are
three times as far from the true ones as the network's, see the DEM cells page). So that an exact
DEM solver can take a cell over, the gated solver's state carries, beside the summary:

- the cell's full DEM state (:mod:`hmodel.cell.geometry`) as of the last increment the DEM
  solved for it (its *shadow*), and
- the length increments the network has applied since (its *lag*, 2 fields).

A cell whose trust score (:mod:`hmodel.surrogate.trust`) exceeds the gate is solved by the DEM
cell in the same increment: its shadow first catches up with the lag, in equal sub-steps of at
most :attr:`ShadowedSolver.replay_strain` of cell strain (the chord of the cell's strain path
since its last DEM increment), then takes the increment, and its summary becomes the DEM
cell's.
Every other cell takes the network's increment on its summary, and its lag grows. The lengths
of a cell follow the REV's strain in both (eq. 1.2), so the shadow's lengths plus the lag are
the summary's. ``step`` stays a function of (state, increment), as Newton's iterations require.

A gated cell's summary jumps from the network's to the DEM cell's: the network's drift since
the last DEM increment is corrected then, which is what keeps a gated ANN-REV near the DEM-REV.
"""

from __future__ import annotations

import math

import numpy as np

from ..cell import CellFlags, CellSolver, CellState
from ..cell.base import STATE_OWN
from ..errors import InputError
from ..params import Params
from .state_cache import StateCache
from .gate import gate_for


class ShadowedSolver(CellSolver):
    """Implements :class:`hmodel.cell.CellSolver`: a ``meso`` :class:`SurrogateSolver` of a
    richer cell, gated at level ``gate`` to the DEM solver ``fallback`` of the same cells (see
    the module docstring). ``counts`` adds, to the surrogate's, ``gated`` and ``gate_checked``
    (cell states, once per increment), ``fallback_cells`` (cell increments the DEM solved,
    Newton trials included) and ``dem_increments`` (with the replay's sub-steps)."""

    #: Largest cell strain of one DEM sub-step when a shadow catches up with its lag: as
    #: accurate as smaller sub-steps for fewer DEM calls (measured: docs/notes, 2026-12-02,
    #: the richer cell).
    replay_strain = 4e-3
    learned = True
    dem_cells = True
    #: the summary, the full DEM state and the lag: a layout of its own
    state_kind = STATE_OWN

    def __init__(self, surrogate, fallback, gate: float):
        f = surrogate.formulation
        if not f.richer:
            raise InputError("a DEM fallback keeps a richer cell's meso surrogate in step; "
                             f"this is a {f.name!r} model of {f.cell}")
        geometry = fallback.geometry
        if geometry is None or (geometry.mesostructure, geometry.options) != (f.geometry.mesostructure,
                                                                              f.geometry.options):
            raise InputError(f"the fallback solver {fallback.name!r} solves other cells than the "
                             f"surrogate's ({f.cell})")
        self.surrogate, self.fallback, self.formulation = surrogate, fallback, f
        self.model = surrogate.model
        #: The gate (:mod:`hmodel.surrogate.gate`): a distance gate, decided per state, or an
        #: ensemble's disagreement, decided per increment; it counts in the surrogate's counts.
        self.gate = gate_for(surrogate.members, gate, surrogate.counts)
        self.name = surrogate.name
        self.stress_rtol = max(surrogate.stress_rtol, fallback.stress_rtol)
        # every cell carries both solvers' states
        self.bytes_per_cell = surrogate.bytes_per_cell + fallback.bytes_per_cell
        self.n_lengths = 2
        self.n_summary, self.n_full = f.n_state, geometry.n_fields
        self.n_state = self.n_summary + self.n_full + 2
        self.counts = surrogate.counts
        self.counts.update(gated=0, gate_checked=0, fallback_cells=0, dem_increments=0)
        self._cache, self._caught, self._made = StateCache(), StateCache(), StateCache()
        #: When a list: every batch of gated cells, their DEM states caught up with their lag,
        #: is appended to it (active learning collects them).
        self.gated_states: list[np.ndarray] | None = None

    def __getstate__(self) -> dict:
        return {**self.__dict__, "_cache": StateCache(), "_caught": StateCache(), "_made": StateCache()}

    def __repr__(self) -> str:
        return f"ShadowedSolver({self.name!r}, gate={self.gate.level:g}, fallback={self.fallback.name!r})"

    def check(self, params: Params) -> None:
        """Refuse a material the surrogate was not trained for."""
        self.surrogate.check(params)

    @property
    def trained_params(self) -> dict | None:
        """The surrogate's (:attr:`SurrogateSolver.trained_params`)."""
        return self.surrogate.trained_params

    # -- state layout -----------------------------------------------------------------------
    def field_names(self) -> tuple[str, ...]:
        """The summary's fields, the full DEM state's, then the lag of the two lengths."""
        return self.formulation.state_fields + self.fallback.field_names() + ("lag_l1", "lag_l2")

    def split(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Summary (..., 11), full DEM state (..., n_full) and lag (..., 2) of states."""
        a, b = self.n_summary, self.n_summary + self.n_full
        return values[..., :a], values[..., a:b], values[..., b:]

    def _join(self, full: np.ndarray) -> np.ndarray:
        """States whose summary is their full DEM state's and whose lag is zero."""
        flat = full.reshape(-1, self.n_full)
        summary = self.formulation.summary(flat)
        out = np.hstack([summary, flat, np.zeros((len(flat), 2))])
        return out.reshape(*full.shape[:-1], self.n_state)

    def initial(self, params: Params, shape: tuple[int, ...] = ()) -> CellState:
        return CellState(self._join(self.fallback.initial(params, shape).values))

    def initial_cells(self, params: Params, alpha0: np.ndarray) -> CellState:
        self.formulation.initial_cells(params, alpha0)  # refuses another opening angle
        return CellState(self._join(self.fallback.initial_cells(params, alpha0).values))

    def meso(self, params: Params, state: CellState) -> tuple[np.ndarray, np.ndarray]:
        return self.formulation.meso(np.asarray(state.values, float)[..., :self.n_summary])

    def kernel(self, params: Params):
        """None: the generic loading path, whose trials pass through :meth:`step`."""
        return None

    # -- the gate -----------------------------------------------------------------------------
    def _gated(self, params: Params, summary: np.ndarray, dl: np.ndarray) -> np.ndarray:
        """The gate's decision on cell increments ``dl`` from summary states: per increment,
        Newton trials included, from the members' states after it (an ensemble's disagreement);
        or once per batch of states (the distance gate)."""
        if self.gate.per_increment:
            return self.gate.decide(summary, self._afters(params, summary, dl))
        return self._gated_states(summary)

    def _gated_states(self, summary: np.ndarray) -> np.ndarray:
        """The distance gate's mask of summary states, counted once per batch of states."""
        hit = self._cache.get(summary)
        if hit is not None:
            return hit
        gated = self.gate.decide(summary)
        self._cache.put(summary, gated)
        return gated

    def _afters(self, params: Params, summary: np.ndarray, dl: np.ndarray) -> list[np.ndarray]:
        """Every member's summary states after the length increments ``dl``."""
        f = self.formulation
        outs, _ = self.surrogate.outputs(summary, f.features(summary))
        strain = np.column_stack([-dl[:, 0] / params.l10, -dl[:, 1] / params.l20])
        return f.member_afters(summary, strain, dl, outs)

    def fractions(self, params: Params, state: CellState) -> dict[str, np.ndarray]:
        """``gated``: with the distance gate, the cells whose next increment the DEM solves;
        with an ensemble's (decided per increment), the cells the DEM solved in the increment
        that made ``state`` (none for a state no increment of this solver made)."""
        if self.gate.per_increment:
            v = np.ascontiguousarray(np.asarray(state.values, float).reshape(-1, self.n_state))
            made = self._made.get(v)
            return {"gated": (np.zeros(len(v), bool) if made is None else made).reshape(state.shape)}
        v = np.asarray(state.values, float)
        summary = v.reshape(-1, self.n_state)[:, :self.n_summary]
        return {"gated": self._gated_states(np.ascontiguousarray(summary)).reshape(state.shape)}

    # -- solver interface ---------------------------------------------------------------------
    def step(self, params: Params, state: CellState, dl1, dl2) -> tuple[CellState, CellFlags]:
        self.check(params)  # also where every cell goes to the DEM
        shape = state.shape
        v = np.asarray(state.values, float).reshape(-1, self.n_state)
        if v.shape[1] != self.n_state:
            raise InputError(f"the gated surrogate's cell states have {self.n_state} fields, got {v.shape[1]}")
        dl = np.column_stack([np.broadcast_to(dl1, shape).reshape(-1), np.broadcast_to(dl2, shape).reshape(-1)])
        summary, full, lag = self.split(v)
        summary = np.ascontiguousarray(summary)
        gated = self._gated(params, summary, dl)
        new, flags = v.copy(), np.zeros((len(v), 5), bool)
        net = ~gated
        if net.any():
            s, fl = self.surrogate.step(params, CellState(summary[net]), dl[net, 0], dl[net, 1])
            new[net, :self.n_summary] = s.values
            new[net, -2:] = lag[net] + dl[net]
            flags[net] = fl.flags
        if gated.any():
            caught = self.caught_up(params, full[gated], lag[gated])
            st, fl = self.fallback.step(params, CellState(caught), dl[gated, 0], dl[gated, 1])
            self.counts["fallback_cells"] += len(caught)
            self.counts["dem_increments"] += len(caught)
            new[gated] = self._join(st.values)
            flags[gated] = fl.flags
        if self.gate.per_increment:  # for fractions(): which cells made this state in DEM
            self._made.put(new, gated)
        return CellState(new.reshape(*shape, self.n_state)), CellFlags(flags.reshape(*shape, 5))

    def caught_up(self, params: Params, full: np.ndarray, lag: np.ndarray) -> np.ndarray:
        """DEM cells ``full`` (n, n_full) driven by their lags ``lag`` (n, 2) in equal sub-steps
        of at most :attr:`replay_strain` of cell strain: the exact cells at the gate (kept for
        the Newton trials from them; appended to :attr:`gated_states` when first made)."""
        key = np.hstack([full, lag])
        hit = self._caught.get(key)
        if hit is not None:
            return hit
        strain = np.abs(lag) / np.array([params.l10, params.l20])
        n_sub = math.ceil(strain.max(initial=0.0) / self.replay_strain - 1e-12)
        values = full
        for _ in range(n_sub):
            values = self.fallback.step(params, CellState(values), lag[:, 0] / n_sub, lag[:, 1] / n_sub)[0].values
        self.counts["dem_increments"] += len(full) * n_sub
        self._caught.put(key, values)
        if self.gated_states is not None:
            self.gated_states.append(values.copy())
        return values
