"""The ANN-based H-cell: a trained surrogate behind the cell-solver interface (report ch. 3).

``SurrogateSolver.step(params, state, dl1, dl2)`` replaces eq. 1.7 in the REV: every cell of
every material point is evaluated in one batched NumPy call. Cell length increments are turned
into the database's cell strains (δε = −δl / l0, on the initial lengths); an increment larger
than the ones the network was trained on is split into equal sub-steps (at most
``max_substeps``). What the network sees and how its outputs become the cells' next state is
the formulation's (:mod:`hmodel.surrogate.formulations`): strain-input networks (``report``,
``increment``, :mod:`hmodel.surrogate.formulations.strain`) with the zero-increment correction
and eq. 1.2; the ``compliance`` network (:mod:`hmodel.surrogate.formulations.compliance`), which
sees the state only, evaluated once per state and applied exactly to every trial increment of a
Newton iteration; a ``meso`` network (:mod:`hmodel.surrogate.formulations.meso`), which also
sees the state only. For both, the REV's compiled loading path (:mod:`hmodel.loading.compiled`)
takes the response once per increment from :meth:`SurrogateSolver.kernel` and applies it in its
Newton trials (:func:`hmodel.cell.meso_kernel.meso_increment`,
:func:`hmodel.cell.compliance_kernel.compliance_increment`).
The solver holds what is common: the material check, the networks' evaluation (cached per
state, float32 or float64 as the formulation says), ensembles, the sub-step bound, and the
cells outside the training domain: a formulation's increment names them
(:class:`~hmodel.surrogate.formulations.base.Increment`), the solver counts them and hands them
to its fallback.

Cells whose inputs lie outside the training domain are either handed to the closed-form
solver (``on_outside="fallback"``; a ``meso`` cell, which has none, is extrapolated) or stop
the run (``"error"``); ``counts`` reports how many.

With a gate (``gate=0.99, fallback=ClosedFormSolver()``; ``--gate 0.99 --fallback
closed-form``), the cells whose trust score exceeds that quantile of the held-out rows' scores
are solved by the fallback solver in the same increment, in one batched call. The solver's
``gate`` is the gate object the model's stored trust describes (:mod:`hmodel.surrogate.gate`):
a :class:`~hmodel.surrogate.gate.DistanceGate` (distance to the training data) is decided per
evaluated state (once per increment), its decisions counted in ``counts["gated"]`` and
``counts["gate_checked"]``, and the REV records their fraction (``gated`` in result.csv, via
:meth:`fractions`).

An ensemble (``SurrogateSolver([m1, m2, ...])``, ``--solver surrogate:A+B+C``) of ``meso`` or
``compliance`` models of one formulation (networks trained alike, e.g. with other seeds)
averages the members' increments dz (``meso``) or compliances (``compliance``) before the way
back: independent training errors of the members partly cancel (see the DEM cells page of the
documentation), at the cost of one network per member. A cell is outside the training domain
when it is outside any member's. The gate of an ensemble whose trust is its disagreement
(:func:`hmodel.surrogate.trust.fit_ensemble_trust`), a
:class:`~hmodel.surrogate.gate.DisagreementGate`, scores each cell increment by the spread of
the members' increments (each member's compliances applied to it), so it is decided per
increment, Newton trials included, and counted so.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from functools import cached_property

import numpy as np

from ..cell import CellFlags, CellKernel, CellSolver, CellState
from ..cell.base import STATE_H_CELL, STATE_OWN
from ..cell.state import FIELDS
from ..cell.closed_form import ClosedFormSolver
from ..errors import InputError, SolverError
from ..params import ANGLE_PARAMS, Params
from .formulations.base import Increment
from .formulations.strain import LEAK_REFUSED
from .gate import Gate, gate_for
from .model import Surrogate
from .state_cache import StateCache, distinct_rows

#: Parameters a surrogate is specific to (it was trained on cells with these values).
MATERIAL = ("kn", "kt_kn", "phi_g", "radius", "g2", "sliding_rhs", "volume")
#: Parameters a family network (one with material inputs) scales out: its inputs and
#: outputs are forces in kn·2r and lengths in 2r, so any kn and r give the same scaled response.
SCALED = ("kn", "radius")


def domain_in_params_units(domain: dict) -> dict[str, tuple[float, float]]:
    """A training domain as model files store it (angles in degrees) in the units of the
    :class:`~hmodel.params.Params` fields (angles in radians)."""
    return {k: tuple(math.radians(float(v)) if k in ANGLE_PARAMS else float(v) for v in lohi)
            for k, lohi in domain.items()}


class SurrogateSolver(CellSolver):
    """Implements :class:`hmodel.cell.CellSolver` with a trained :class:`Surrogate` (or an
    ensemble), delegating to its formulation what depends on it; the solver's networks are the
    formulation's :class:`~hmodel.surrogate.formulations.base.Networks`.

    A cell of a strain-input formulation opens where eq. 1.7's closed form would, on the
    continued force increments, and separated grains carry no force (the ``increment``
    network's opening logit, which lost to this rule, is not consulted: docs/notes/
    2026-12-01-engine-shape.md).
    """

    name = "surrogate"
    #: Newton's stress tolerance floor (relative): learned compliances make the response jump by
    #: ~1e-9 of the stress where a cell switches between sticking and sliding (the closed form
    #: is continuous there), which a 1e-10 tolerance can fall into.
    stress_rtol = 1e-7
    #: measured: about 2.7 kB a cell with the shipped network (peak RSS of drained biaxial runs
    #: at nθ = 2·10⁴ and 2·10⁵): the network's inputs, outputs and cached responses
    bytes_per_cell = 4096
    n_lengths = 2
    learned = True
    #: Most sub-steps of the largest trained increment one cell increment may be cut into
    #: (strain-input formulations); a larger request is refused with a SolverError.
    max_substeps = 100

    def __init__(self, model: Surrogate | Sequence[Surrogate], on_outside: str = "fallback",
                 margin: float = 0.0, gate: float | None = None,
                 fallback: CellSolver | None = None):
        if on_outside not in ("fallback", "error"):
            raise InputError(f"on_outside must be fallback or error, got {on_outside!r}")
        self.members = _members(model)
        self.model, self.on_outside, self.margin = self.members[0], on_outside, margin
        self.formulation = self.model.formulation
        if self.formulation.needs_answer:
            raise InputError(LEAK_REFUSED)
        self.fallback = self.closed_form = ClosedFormSolver()
        self.counts = {"cell_updates": 0, "network_cells": 0, "outside": 0, "substeps": 0,
                       "gated": 0, "gate_checked": 0, "fallback_cells": 0}
        #: The gate (:mod:`hmodel.surrogate.gate`) that sends cells to the fallback, or None.
        self.gate: Gate | None = None
        if gate is not None or fallback is not None:
            self._set_gate(gate, fallback)
        # network outputs, outside and gate masks of the batches of states seen last: every
        # Newton trial from a state, and every set's batch of a many-set REV, reuse them
        self._cache = StateCache()
        self._gated: np.ndarray | None = None  # the gate's mask of the states last evaluated
        self._accepted: set[tuple] = set()  # materials (MATERIAL fields) already checked
        #: When a list: every batch of states the gate sends to the fallback is appended to it
        #: (active learning collects them, :mod:`hmodel.studies.refine`).
        self.gated_states: list[np.ndarray] | None = None
        #: Largest cell strain increment of one network step (inf: any, where the network sees
        #: the state only).
        self.max_increment = self.formulation.max_increment(self.model.input_range)

    def __getstate__(self) -> dict:  # a copy in another process starts with an empty cache
        return {**self.__dict__, "_cache": StateCache(), "_gated": None}

    def _set_gate(self, gate: float | None, fallback: CellSolver | None) -> None:
        if gate is None:
            raise InputError("a fallback solver needs a gate (--gate LEVEL, e.g. 0.99)")
        if fallback is None:
            raise InputError("a gate needs a fallback solver (--fallback closed-form)")
        f = self.formulation
        if f.material_inputs:
            raise InputError("gating is for networks of one material; this one takes the material as "
                             "inputs (a family network)")
        if not (f.state_only and f.falls_back):
            raise InputError(f"gating needs a network that sees the H-cell's state only (the "
                             f"compliance formulation, the default model's), so that an exact "
                             f"solver can take the cell over; this is a "
                             f"{self.formulation.name!r} model")
        if fallback.initial(Params()).values.shape[-1] != self.n_state:
            raise InputError(f"the fallback solver {fallback.name!r} keeps other cell states than "
                             f"the surrogate's H-cells")
        self.gate = gate_for(self.members, gate, self.counts)
        self.fallback = fallback

    def fractions(self, params: Params, state: CellState) -> dict[str, np.ndarray]:
        """With a gate: ``gated``, the cells whose next increment the fallback solves."""
        if self.gate is None or self.gate.per_increment:
            return {}  # an ensemble's gate depends on the increment, not known at a state
        v = np.asarray(state.values, float).reshape(-1, self.n_state)
        return {"gated": self.gate.mask(v).reshape(state.shape)}

    def _gate_increments(self, v: np.ndarray, strain: np.ndarray, dl: np.ndarray,
                         outs: list[np.ndarray]) -> np.ndarray:
        """The ensemble's gate: cells whose members' increments under cell strains ``strain``
        and length increments ``dl`` disagree beyond the threshold. Counted per cell increment,
        Newton trials included."""
        afters = self.formulation.member_afters(v, strain, dl, outs)
        gated = self._record_gate(v, self.gate.mask(v, afters))
        self._gated = gated
        return gated

    def _record_gate(self, v: np.ndarray, gated: np.ndarray) -> np.ndarray:
        """Count the gate's decisions on cells ``v`` and keep the gated states when asked to."""
        self.gate.count(gated)
        if self.gated_states is not None and gated.any():
            self.gated_states.append(v[gated].copy())
        return gated

    @property
    def domain(self) -> dict[str, tuple[float, float]] | None:
        """A family network's training domain, ``{name: (lo, hi)}`` in the units of the
        :class:`~hmodel.params.Params` fields (angles in radians, as ``params.phi_g``); None
        for a network of one material. The model file stores it as the command line writes it
        (angles in degrees, ``domain`` in its metadata)."""
        d = self.model.meta.get("domain")
        return domain_in_params_units(d) if d else None

    def check(self, params: Params) -> None:
        """Refuse a material the surrogate was not trained for: one other than its own, or for
        a family network, one outside its training domain (:attr:`domain`; kn and r are scaled
        out, any is accepted)."""
        trained = self.model.meta.get("params") or {}
        # a REV of many parameter sets calls once per set and trial: compare each material once
        key = tuple(getattr(params, k) for k in MATERIAL + ("alpha0",))
        if key in self._accepted:
            return
        mine, domain = params.to_dict(), self.model.meta.get("domain")  # degrees, as the CLI's
        if domain:
            outside = [k for k, (lo, hi) in domain.items() if not _within(mine[k], lo, hi)]
            if outside:
                raise InputError("parameters outside the model's training domain: " + ", ".join(
                    f"{k}={mine[k]:g} (trained {lo:g}–{hi:g})" for k in outside
                    for lo, hi in [domain[k]]))
        free = (set(domain) | set(SCALED)) if domain else set()
        wrong = [k for k in MATERIAL if k in trained and k not in free and not _same(trained[k], mine[k])]
        if wrong:
            raise InputError("the surrogate was trained for other material parameters: " + ", ".join(
                f"{k}={trained[k]} (run: {mine[k]})" for k in wrong))
        self._accepted.add(key)

    @property
    def n_state(self) -> int:
        """Fields of a cell state: the H-cell's 8, or the ``meso`` formulation's summary."""
        return self.formulation.n_state

    @property
    def state_kind(self) -> str:
        """An H-cell, or the ``meso`` formulation's summary (its own meso-stress)."""
        return STATE_H_CELL if self.formulation.state_fields == FIELDS else STATE_OWN

    def field_names(self) -> tuple[str, ...]:
        return self.formulation.state_fields

    @cached_property
    def dem_cells(self) -> bool:
        """Whether the network learned DEM cells: those of the cell solver of its training data
        (the formulation's ``cell``), as that solver declares."""
        from ..solvers import get_solver

        return get_solver(self.formulation.cell).dem_cells

    @property
    def trained_params(self) -> dict | None:
        """The material parameters of the formulation (a ``compliance`` or ``meso`` network's,
        as its model file stores them), or None (a strain-input network keeps its scales only)."""
        return self.formulation.to_dict().get("params") or None

    def initial(self, params: Params, shape: tuple[int, ...] = ()) -> CellState:
        """Unloaded cells in this surrogate's state layout."""
        return self.formulation.initial(params, shape)

    def meso(self, params: Params, state: CellState) -> tuple[np.ndarray, np.ndarray] | None:
        """V sigma and meso-volume of summary states (``meso`` formulation), for the REV; None
        for H-cell surrogates, whose stress is eq. 1.12 of their fields."""
        return self.formulation.meso(np.asarray(state.values, float))

    def initial_cells(self, params: Params, alpha0: np.ndarray) -> CellState:
        """Unloaded cells with their own opening angles (a ``meso`` summary state knows one
        opening angle only, the one the model was trained for)."""
        return self.formulation.initial_cells(params, alpha0)

    def kernel(self, params: Params) -> CellKernel | None:
        """The formulation's compiled increment (a ``meso`` network's learned response or a
        ``compliance`` network's compliances, applied by every Newton trial inside the compiled
        loading path), or None: strain-input networks run through the generic driver, and so
        does a gated solver (its fallback may be another solver, an ensemble's gate is decided
        per trial increment, and the gated fraction is recorded per increment)."""
        if self.gate is not None:
            return None
        kernel_params = self.formulation.kernel_params(params)
        if kernel_params is None:
            return None
        self.check(params)  # its trials never pass through step's check
        if self.formulation.material_inputs:  # a family's response depends on the set's material
            return CellKernel(kernel_params, lambda v: self._responses(v, params))
        return CellKernel(kernel_params, self._responses)

    def _responses(self, v: np.ndarray, params: Params | None = None) -> np.ndarray:
        """The compiled increment's response rows of states ``v`` (of a family network: of the
        material ``params``): the network's outputs for them (cached), the cells outside the
        training domain counted (or the run stopped, ``on_outside="error"``) as :meth:`step`
        does; a formulation that falls back takes the closed form for them inside the kernel."""
        f = self.formulation
        outs, mask = self.outputs(v, params=params)
        n_fall = self.count_outside(mask, f.describe(v))
        if f.falls_back:
            self.counts["fallback_cells"] += n_fall
        return f.responses(v, outs, mask)

    def step(self, params: Params, state: CellState, dl1, dl2) -> tuple[CellState, CellFlags]:
        self.check(params)
        shape, n_state = state.shape, self.n_state
        if state.values.shape[-1] != n_state:
            raise InputError(f"the surrogate's cell states have {n_state} fields, got {state.values.shape[-1]}")
        v = np.ascontiguousarray(state.values.reshape(-1, n_state))
        dl = np.column_stack([np.broadcast_to(dl1, shape).reshape(-1), np.broadcast_to(dl2, shape).reshape(-1)])
        self.counts["cell_updates"] += len(v)
        e1, e2 = -dl[:, 0] / params.l10, -dl[:, 1] / params.l20
        n_sub = self._substeps(max(np.abs(e1).max(initial=0.0), np.abs(e2).max(initial=0.0)))
        values, flags = v, None
        for _ in range(n_sub):
            values, flags = self._network_step(params, values, e1 / n_sub, e2 / n_sub, dl / n_sub)
        self.counts["substeps"] += n_sub
        if not np.all(np.isfinite(values)):
            raise SolverError("the surrogate returned a non-finite cell state")
        return CellState(values.reshape(*shape, n_state)), CellFlags(flags.reshape(*shape, 5))

    @property
    def batches_sets(self) -> bool:
        """Whether :meth:`step_sets` steps the cells of several parameter sets in one network
        call: a family network (its material is an input of every cell) whose formulation steps
        several materials at once (``step_cells_sets``: the meso formulation's), without a gate."""
        f = self.formulation
        return bool(f.material_inputs) and f.steps_sets and self.gate is None

    def step_sets(self, sets: Sequence[Params], index: np.ndarray, state: CellState,
                  *lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`step` of the points of several parameter sets together (point b of the set
        ``sets[index[b]]``; ``state`` and ``lengths`` of shape (B, ...)): the values and flags
        (B, ..., n) after the increment. Each set's cells take the sub-steps :meth:`step` gives
        them alone, and every sub-step is one network call for the cells of all the sets still
        stepping (a calibration's parameter sets, a family network's materials), then each set's
        own way back; a many-set REV (:class:`hmodel.rev.batch.RevBatch`) calls it."""
        present = np.unique(index)
        for k in present:
            self.check(sets[k])
        shape, n_state = state.shape, self.n_state
        v = np.ascontiguousarray(state.values.reshape(-1, n_state))
        row_set = np.repeat(np.asarray(index), len(v) // len(index))
        dl = np.column_stack([np.broadcast_to(x, shape).reshape(-1) for x in lengths])
        l0 = np.array([[s.l10, s.l20] for s in sets])[row_set]
        e = -dl / l0
        self.counts["cell_updates"] += len(v)
        per_set = np.zeros(len(sets), int)
        for k in present:
            per_set[k] = self._substeps(np.abs(e[row_set == k]).max(initial=0.0))
        n_sub = per_set[row_set]
        values, flags = v.copy(), np.zeros((len(v), 5), bool)
        for r in range(per_set.max()):
            go = np.flatnonzero(n_sub > r)  # the cells of the sets with sub-steps left
            n = n_sub[go].astype(float)
            inc = self.formulation.step_cells_sets(self, sets, row_set[go], values[go], e[go, 0] / n, e[go, 1] / n,
                                                   dl[go] / n[:, None])
            self.counts["network_cells"] += inc.network_cells
            self.count_outside(inc.outside, inc.describe)
            values[go], flags[go] = inc.new, inc.flags
        self.counts["substeps"] += int(per_set.sum())
        if not np.all(np.isfinite(values)):
            raise SolverError("the surrogate returned a non-finite cell state")
        return values.reshape(*shape, n_state), flags.reshape(*shape, 5)

    def _network_step(self, params: Params, v: np.ndarray, e1: np.ndarray, e2: np.ndarray,
                      dl: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The formulation's increment of cells ``v``, then the solver's part: the cells outside
        the training domain (or gated) counted, the run stopped (``on_outside="error"``) or
        those cells handed to the fallback solver where the formulation falls back."""
        f = self.formulation
        inc: Increment = f.step_cells(self, params, v, e1, e2, dl)
        self.counts["network_cells"] += inc.network_cells
        mask = inc.outside
        if self.gate is not None and self.gate.per_increment:  # the members disagree on it
            mask = mask | self._gate_increments(v, np.column_stack([e1, e2]), dl, inc.outs)
        if self.count_outside(mask, inc.describe) and f.falls_back:
            self.fall_back(params, v, dl, mask, inc.new, inc.flags)
        return inc.new, inc.flags

    @property
    def max_cell_strain(self) -> float:
        """The largest cell strain increment :meth:`step` takes (``max_substeps`` trained
        increments); the REV's Newton holds its trials within it
        (:func:`hmodel.loading.newton.solver_limits`)."""
        return self.max_substeps * self.max_increment

    def _substeps(self, largest: float) -> int:
        """Sub-steps for a cell strain increment of size ``largest``: a request beyond
        ``max_substeps`` trained increments is no cell increment the network knows (a run-away
        Newton trial, typically) and fails at once instead of being cut into unbounded work."""
        if not math.isfinite(largest):
            raise SolverError(f"the surrogate was asked for a non-finite cell strain increment ({largest})")
        if largest > self.max_cell_strain:
            raise SolverError(
                f"cell strain increment {largest:.3g} is {largest / self.max_increment:.3g} times the "
                f"surrogate's largest trained increment {self.max_increment:.3g} (at most "
                f"{self.max_substeps} sub-steps)")
        return max(1, math.ceil(largest / self.max_increment - 1e-12))

    # -- the formulation's networks (formulations.base.Networks) ----------------------------
    def forward(self, X: np.ndarray) -> np.ndarray:
        """The network's outputs for inputs X, in float64 (strain-input networks, one model)."""
        return self.model.forward(X)

    def outside(self, X: np.ndarray) -> np.ndarray:
        """Rows of X outside the network's training domain by more than the margin."""
        return self.model.outside(X, self.margin)

    def outputs(self, v: np.ndarray, X: np.ndarray | None = None, params: Params | None = None,
                key: tuple | None = None) -> tuple[list[np.ndarray], np.ndarray]:
        """Every member's network outputs and the out-of-domain mask for states ``v`` (inputs
        X, from the state only; None: the formulation's features of ``v`` and, for a family
        network, of the material ``params``, computed only when the states are new); kept
        while the states (and that material) do not change, so that the trial increments of
        one Newton iteration cost no inference. ``key``: what else X depends on, for the cache
        (several sets' materials, :meth:`step_sets`), in place of ``params``'s material."""
        material = key if key is not None else () if params is None else tuple(getattr(params, k) for k in MATERIAL)
        hit = self._cache.get(v, material)
        if hit is not None:
            outs, mask, gated = hit
            self._gated = gated
            return outs, mask | gated
        if X is None:
            X = self.formulation.features(v) if params is None else self.formulation.features(v, params)
        # Equal states are evaluated once: until shear starts, the cells of an isotropic REV
        # hold a handful of distinct states (their directions' cos^2 + sin^2 round to a few
        # values, scattered over the directions), so a consolidation sends a few rows per
        # material point through the network instead of every cell.
        # several sets' materials (``key``) make inputs of equal states differ: those rows are
        # equal only where their inputs are
        rows = distinct_rows(v if key is None else np.ascontiguousarray(X, dtype=float))
        Xu = X if rows is None else X[rows[0]]
        self.counts["network_cells"] += len(Xu)
        f = self.formulation
        # spare columns serve one network's outputs as they are (an ensemble's are combined)
        spare = f.spare_columns if len(self.members) == 1 else 0
        outs = [m.forward(Xu, single=f.single_precision, spare=spare) for m in self.members]
        mask = np.any([m.outside(Xu, self.margin) for m in self.members], axis=0)
        # a gate on the state is decided here, once per state, on the distinct rows
        state_gate = self.gate is not None and not self.gate.per_increment
        gated = self.gate.inputs_mask(Xu) if state_gate else np.zeros(len(Xu), bool)
        if rows is not None:
            row = rows[1]
            outs, mask, gated = [o[row] for o in outs], mask[row], gated[row]
        if state_gate:
            self._record_gate(v, gated)
        self._cache.put(v, (outs, mask, gated), material)
        self._gated = gated
        return outs, mask | gated

    def count_outside(self, mask: np.ndarray, describe: Callable[[int], str]) -> int:
        """Count the cells outside the training domain (``mask`` of :meth:`outputs`: outside or
        gated); stop the run with ``on_outside="error"`` where one is outside and not gated
        (a gated cell has its exact solver). Returns how many cells the fallback takes."""
        gated = self._gated if self._gated is not None and len(self._gated) == len(mask) else False
        n_fall = int(mask.sum())
        mask = mask & ~gated
        n_out = int(mask.sum())
        self.counts["outside"] += n_out
        if n_out and self.on_outside == "error":
            raise SolverError(f"{n_out} cell(s) outside the surrogate's training domain, e.g. "
                              + describe(int(np.flatnonzero(mask)[0])))
        return n_fall

    def fall_back(self, params: Params, v: np.ndarray, dl: np.ndarray, mask: np.ndarray,
                  new: np.ndarray, flags: np.ndarray) -> None:
        """The fallback solver's increment (the closed form's unless a gate names another) for
        the H-cells ``mask``, written into ``new``, ``flags``."""
        self.counts["fallback_cells"] += int(mask.sum())
        cf, cflags = self.fallback.step(params, CellState(v[mask]), dl[mask, 0], dl[mask, 1])
        new[mask], flags[mask] = cf.values, cflags.flags


def _members(model) -> list[Surrogate]:
    """The models of a solver: one, or an ensemble of models of one formulation whose increments
    average (``meso``)."""
    members = list(model) if isinstance(model, Sequence) else [model]
    if not members:
        raise InputError("an ensemble of surrogates needs at least one model")
    first = members[0].formulation
    if len(members) > 1 and not first.ensembles:
        raise InputError(f"an ensemble averages meso or compliance models, got {first.name!r} models")
    for m in members[1:]:
        if m.formulation.to_dict() != first.to_dict():
            raise InputError("the ensemble's models have different formulations (cell solver, material "
                             "or mechanisms): train every member on the same data and settings")
    return members


def _within(value: float, lo: float, hi: float) -> bool:
    """lo <= value <= hi, up to the round-off of a range written in other units."""
    tol = 1e-9 * max(abs(lo), abs(hi), 1.0)
    return lo - tol <= value <= hi + tol


def _same(a, b) -> bool:
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)
    return a == b


def load_solver(spec: str, on_outside: str = "fallback") -> SurrogateSolver:
    """``surrogate`` (the shipped default), ``surrogate:NAME`` (a shipped model or ensemble),
    ``surrogate:PATH`` or an ensemble ``surrogate:PATH+PATH+...``."""
    from .modelfile import load
    from .shipped import model_paths

    return SurrogateSolver([load(p) for p in model_paths(spec.partition(":")[2] or "shipped")], on_outside)


def gated_solver(spec: "str | CellSolver", gate: float | None = None,
                     fallback: "str | CellSolver | None" = None) -> CellSolver:
    """:func:`hmodel.solvers.get_solver`, with an uncertainty gate where ``gate`` or ``fallback`` is given: the
    learned cells whose trust score exceeds the ``gate`` quantile are solved by ``fallback``
    (see :class:`hmodel.surrogate.solver.SurrogateSolver`). Both or neither are required."""
    from ..solvers import get_solver

    solver = get_solver(spec)
    if gate is None and fallback is None:
        return solver
    if gate is None:
        raise InputError("a fallback solver needs a gate (--gate LEVEL, e.g. 0.99)")
    if fallback is None:
        raise InputError("a gate needs a fallback solver (--fallback closed-form)")
    if not isinstance(solver, SurrogateSolver):
        raise InputError(f"--gate and --fallback are for learned cell solvers (surrogate[:MODEL]), "
                         f"got {solver.name!r}")
    exact = get_solver(fallback)
    if solver.formulation.richer:  # a DEM cell kept in step (shadow.py)
        from .shadow import ShadowedSolver

        return ShadowedSolver(solver, exact, gate)
    return SurrogateSolver(solver.members, solver.on_outside, solver.margin,
                           gate=gate, fallback=exact)


def gate_summary(solver) -> str:
    """One line: how many learned cell states the gate sent to the fallback solver."""
    line = f"{solver.gate.summary()} solved by {solver.fallback.name}"
    if "dem_increments" in solver.counts:
        line += f" ({solver.counts['dem_increments']:,} DEM cell increments with the catch-ups)"
    return line
