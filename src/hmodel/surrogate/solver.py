"""The ANN-based H-cell: a trained surrogate behind the cell-solver interface (report ch. 3).

``SurrogateSolver.step(params, state, dl1, dl2)`` replaces eq. 1.7 in the REV: every cell of
every material point is evaluated in one batched NumPy call. Cell length increments are turned
into the database's cell strains (δε = −δl / l0, on the initial lengths); an increment larger
than the ones the network was trained on is split into equal sub-steps. The network's answer
for a zero increment is subtracted from its answer (see :meth:`SurrogateSolver._predict`). The network predicts
α′, N1′, N2′, T1′; the lengths follow the strain, and d1, d2 follow from α′ and the lengths by
eq. 1.2 (d1 = l2 / (2 sin α), d2 = l1 − 2 d1 cos α), so the state stays geometrically
consistent. With the ``compliance`` formulation (:mod:`hmodel.surrogate.compliance`) the
network sees the state only: it is evaluated once per state, and every trial increment of a
Newton iteration is an exact, compiled application of the learned compliances. A ``meso``
network also sees the state only; the REV's loading paths then run in the compiled driver
(:mod:`hmodel.loading.compiled`), which takes :meth:`SurrogateSolver.meso_response` once per
increment and applies it in :func:`hmodel.cell.meso_kernel.meso_increment`.

Cells whose inputs lie outside the training domain are either handed to the closed-form
solver (``on_outside="fallback"``) or stop the run (``"error"``); ``counts`` reports how many.

An ensemble (``SurrogateSolver([m1, m2, ...])``, ``--solver surrogate:A+B+C``) of ``meso``
models of one formulation (networks trained alike, e.g. with other seeds) averages the members'
increments dz before the way back: independent training errors of the members partly cancel
(see the DEM cells page of the documentation), at the cost of one network per member. A cell is
outside the training domain when it is outside any member's.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..cell import FIELDS, CellFlags, CellKernel, CellState, initial_cells
from ..cell.closed_form import ClosedFormSolver
from ..errors import InputError, SolverError
from ..params import Params
from ..cell.meso_kernel import advance_cells, kernel_params, pack_outputs, pack_responses
from .model import Surrogate

#: Parameters a surrogate is specific to (it was trained on cells with these values).
MATERIAL = ("kn", "kt_kn", "phi_g", "radius", "g2", "sliding_rhs", "volume")


class SurrogateSolver:
    """Implements :class:`hmodel.cell.CellSolver` with a trained :class:`Surrogate`."""

    name = "surrogate"
    #: Newton's stress tolerance floor (relative): learned compliances make the response jump by
    #: ~1e-9 of the stress where a cell switches between sticking and sliding (the closed form
    #: is continuous there), which a 1e-10 tolerance can fall into.
    stress_rtol = 1e-7
    #: Most sub-steps of the largest trained increment one cell increment may be cut into
    #: (strain-input formulations); a larger request is refused with a SolverError.
    max_substeps = 100

    def __init__(self, model: Surrogate | Sequence[Surrogate], on_outside: str = "fallback",
                 margin: float = 0.0, opening: str = "rule"):
        if on_outside not in ("fallback", "error"):
            raise InputError(f"on_outside must be fallback or error, got {on_outside!r}")
        if opening not in ("rule", "classifier"):
            raise InputError(f"opening must be rule or classifier, got {opening!r}")
        self.members = _members(model)
        self.model, self.on_outside, self.margin, self.opening = self.members[0], on_outside, margin, opening
        self.closed_form = ClosedFormSolver()
        self.counts = {"cell_updates": 0, "network_cells": 0, "outside": 0, "substeps": 0}
        # (states, network outputs, outside mask) of the last two batches of states seen: a
        # Newton iteration's state and the copies its finite-difference tangent probes.
        self._cache: list[tuple] = []
        self._checked = None
        r = self.model.input_range
        # Largest trained strain increment: the bound of the deps1, deps2 inputs (strain-input
        # formulations; the compliance formulation is exact for any increment of its regime).
        f = self.model.formulation
        if r is None or f.name in ("compliance", "meso"):  # exact / homogeneous in the increment
            self.max_increment = math.inf
        else:
            self.max_increment = float(np.abs(r[:, :2]).max())

    def check(self, params: Params) -> None:
        """Refuse a material the surrogate was not trained for."""
        trained = self.model.meta.get("params")
        if not trained or params is self._checked:  # Params are frozen: once per object
            return
        mine = params.to_dict()
        wrong = [k for k in MATERIAL if k in trained and not _same(trained[k], mine[k])]
        if wrong:
            raise InputError("the surrogate was trained for other material parameters: " + ", ".join(
                f"{k}={trained[k]} (run: {mine[k]})" for k in wrong))
        self._checked = params

    @property
    def n_state(self) -> int:
        """Fields of a cell state: the H-cell's 8, or the ``meso`` formulation's summary."""
        return getattr(self.model.formulation, "n_state", len(FIELDS))

    def initial(self, params: Params, shape: tuple[int, ...] = ()) -> CellState:
        """Unloaded cells in this surrogate's state layout."""
        f = self.model.formulation
        return f.initial(shape) if f.name == "meso" else CellState.initial(params, shape)

    def meso(self, params: Params, state: CellState) -> tuple[np.ndarray, np.ndarray] | None:
        """V sigma and meso-volume of summary states (``meso`` formulation), for the REV; None
        for H-cell surrogates, whose stress is eq. 1.12 of their fields."""
        f = self.model.formulation
        return f.meso(np.asarray(state.values, float)) if f.name == "meso" else None

    def initial_cells(self, params: Params, alpha0: np.ndarray) -> CellState:
        """Unloaded cells with their own opening angles; a ``meso`` summary state knows one
        opening angle only, the one the model was trained for (``params.alpha0``)."""
        alpha0 = np.asarray(alpha0, float)
        if self.model.formulation.name != "meso":
            return initial_cells(params, alpha0)
        if not np.allclose(alpha0, params.alpha0, rtol=0.0, atol=1e-12):
            raise InputError("a meso surrogate's cells start at the opening angle it was trained "
                             f"for (alpha0 = {np.degrees(params.alpha0):.6g} deg)")
        return self.initial(params, alpha0.shape)

    def kernel(self, params: Params) -> CellKernel | None:
        """A ``meso`` network sees the state only: one evaluation per increment gives the
        response that every Newton trial then applies in the compiled kernel
        (:func:`hmodel.cell.meso_kernel.meso_increment`). Strain-input and compliance
        networks run through the generic driver (None)."""
        if self.model.formulation.name != "meso":
            return None
        self.check(params)
        return CellKernel(kernel_params(self.model.formulation, params),
                          lambda values: self.meso_response(params, values, packed=True))

    def step(self, params: Params, state: CellState, dl1, dl2) -> tuple[CellState, CellFlags]:
        self.check(params)
        shape, n_state = state.shape, self.n_state
        if state.values.shape[-1] != n_state:
            raise InputError(f"the surrogate's cell states have {n_state} fields, got {state.values.shape[-1]}")
        v = np.ascontiguousarray(state.values.reshape(-1, n_state))
        dl = np.column_stack([np.broadcast_to(dl1, shape).reshape(-1), np.broadcast_to(dl2, shape).reshape(-1)])
        self.counts["cell_updates"] += len(v)
        if self.model.formulation.name == "compliance":
            values, flags = self._advance(params, v, dl)
        else:
            one = self._one_meso if self.model.formulation.name == "meso" else self._one
            e1, e2 = -dl[:, 0] / params.l10, -dl[:, 1] / params.l20
            n_sub = self._substeps(max(np.abs(e1).max(initial=0.0), np.abs(e2).max(initial=0.0)))
            values, flags = v, None
            for _ in range(n_sub):
                values, flags = one(params, values, e1 / n_sub, e2 / n_sub, dl / n_sub)
            self.counts["substeps"] += n_sub
        if not np.all(np.isfinite(values)):
            raise SolverError("the surrogate returned a non-finite cell state")
        return CellState(values.reshape(*shape, n_state)), CellFlags(flags.reshape(*shape, 5))

    def _substeps(self, largest: float) -> int:
        """Sub-steps for a cell strain increment of size ``largest``: a request beyond
        ``max_substeps`` trained increments is no cell increment the network knows (a run-away
        Newton trial, typically) and fails at once instead of being cut into unbounded work."""
        if not math.isfinite(largest):
            raise SolverError(f"the surrogate was asked for a non-finite cell strain increment ({largest})")
        if largest > self.max_substeps * self.max_increment:
            raise SolverError(
                f"cell strain increment {largest:.3g} is {largest / self.max_increment:.3g} times the "
                f"surrogate's largest trained increment {self.max_increment:.3g} (at most "
                f"{self.max_substeps} sub-steps)")
        return max(1, math.ceil(largest / self.max_increment - 1e-12))

    def _one_meso(self, params, v, e1, e2, dl):
        """``meso`` formulation: one learned increment of the summary state, in the compiled
        way back (``MesoFormulation.advance`` in one pass; tested against it)."""
        new, flags, _ = advance_cells(v, np.ascontiguousarray(dl, float),
                                      kernel_params(self.model.formulation, params),
                                      self.meso_response(params, v, packed=True))
        return new, flags

    def meso_response(self, params: Params, v: np.ndarray, packed: bool = False):
        """The learned response (``MesoFormulation.response``; an ensemble's mean) of summary
        states v (n, 11), which every trial increment from these states applies; with ``packed``,
        its rows for the compiled trial (:func:`~hmodel.cell.meso_kernel.pack_responses`;
        one network's outputs are those rows already, followed by cos and sin of alpha in two
        spare columns). There is no closed form to fall back to: cells outside the training
        domain stop the run (``on_outside="error"``) or are extrapolated and counted."""
        self.check(params)
        f = self.model.formulation
        X = f.features(v)
        outs, out = self._network(v, X)
        self.counts["outside"] += int(out.sum())
        if out.any() and self.on_outside == "error":
            i = int(np.flatnonzero(out)[0])
            raise SolverError(f"{int(out.sum())} cell(s) outside the surrogate's training domain, e.g. "
                              + ", ".join(f"{k}={x:.4g}" for k, x in zip(f.input_names, X[i])))
        width = f.n_outputs
        if packed and len(outs) == 1:
            wide = outs[0] if outs[0].shape[1] == width + 2 else None
            return pack_outputs(outs[0][:, :width], len(f.learned), v, wide)
        response = f.mean_response([f.response(o[:, :width]) for o in outs])
        return pack_responses(response, v) if packed else response

    def _advance(self, params, v, dl):
        """Compliance formulation: one exact increment with the learned compliances of the states."""
        outs, out_mask = self._network(v, self.model.formulation.features(v))
        new, flags = self.model.formulation.advance(v, dl, outs[0])  # compliance: no spare columns
        self._outside(params, v, dl, out_mask, new, flags,
                      lambda i: ", ".join(f"{k}={v[i, j]:.4g}" for j, k in enumerate(FIELDS)))
        return new, flags

    def _network(self, v, X):
        """Every member's network outputs and the out-of-domain mask for states ``v`` (inputs
        X, from the state only); kept while the states do not change, so that the trial
        increments of one Newton iteration cost no inference."""
        for seen, outs, mask in self._cache:
            if seen.shape == v.shape and np.array_equal(seen, v):
                return outs, mask
        # A state equal to the one before it is evaluated once: the cells of an isotropic REV
        # are all alike until shear starts (a sizeable share of a drained test's network rows),
        # and finding them costs two comparisons per field.
        first = np.ones(len(v), bool)
        first[1:] = np.any(v[1:] != v[:-1], axis=1)
        Xu = X if first.all() else X[first]
        self.counts["network_cells"] += len(Xu)
        # float32 for meso models (checked against float64 on every compared DEM-REV path);
        # compliance models stay float64: in float32 the shipped one stalled on unload-reload
        single = self.model.formulation.name == "meso"
        # one meso network: two spare columns, where meso_response(packed=True) puts cos and sin
        spare = 2 if single and len(self.members) == 1 else 0
        outs = [m.forward(Xu, single=single, spare=spare) for m in self.members]
        mask = np.any([m.outside(Xu, self.margin) for m in self.members], axis=0)
        if not first.all():
            row = np.cumsum(first) - 1
            outs, mask = [o[row] for o in outs], mask[row]
        self._cache = [(v.copy(), outs, mask)] + self._cache[:1]
        return outs, mask

    def _outside(self, params, v, dl, mask, new, flags, describe):
        """Count the cells outside the training domain; stop or hand them to the closed form."""
        n_out = int(mask.sum())
        self.counts["outside"] += n_out
        if not n_out:
            return
        if self.on_outside == "error":
            raise SolverError(f"{n_out} cell(s) outside the surrogate's training domain, e.g. "
                              + describe(int(np.flatnonzero(mask)[0])))
        cf, cflags = self.closed_form.step(params, CellState(v[mask]), dl[mask, 0], dl[mask, 1])
        new[mask], flags[mask] = cf.values, cflags.flags

    def _one(self, params, v, e1, e2, dl):
        cols = {"deps1": e1, "deps2": e2, "d1": v[:, 0], "d2": v[:, 1], "alpha": v[:, 2],
                "N1": v[:, 3], "N2": v[:, 4], "T1": v[:, 5], "l1": v[:, 6], "l2": v[:, 7]}
        X = self.model.formulation.inputs(cols)
        self.counts["network_cells"] += len(v)
        pred = self._predict(cols, X)
        a = pred["alpha_next"]
        l1, l2 = v[:, 6] + dl[:, 0], v[:, 7] + dl[:, 1]
        b1 = l2 / (2.0 * np.sin(a))  # eq. 1.2
        b2 = l1 - 2.0 * b1 * np.cos(a)
        new = np.column_stack([b1, b2, a, pred["N1_next"], pred["N2_next"], pred["T1_next"], l1, l2])
        two_r = 2.0 * params.radius
        opened = (pred["N1_next"] == 0) & (pred["N2_next"] == 0)
        if self.opening == "rule":  # separated grains carry no force (docs/model.md step 3)
            opened |= (b1 > two_r) | (b2 > two_r)
            for k in (3, 4, 5):
                new[opened, k] = 0.0
        flags = np.column_stack([
            (np.abs(pred["T1_next"]) >= params.tan_phi * pred["N1_next"] * (1 - 1e-9)) & ~opened,
            opened, opened, l1 <= two_r, l2 <= two_r])
        self._outside(params, v, dl, self.model.outside(X, self.margin), new, flags, lambda i: ", ".join(
            f"{k}={cols[k][i]:.4g}" for k in ("deps1", "deps2", "alpha", "l1", "l2", "N1", "N2", "T1")))
        return new, flags

    def _predict(self, cols, X):
        """Network prediction with the zero-increment correction: the network's answer for a
        zero strain increment is subtracted, so that a cell without strain keeps its state and
        the network's bias does not accumulate over the thousands of increments of a path."""
        f, m = self.model.formulation, self.model
        X0 = X.copy()
        X0[:, :2] = 0.0
        Y, Y0 = m.forward(X), m.forward(X0)
        if f.name == "report":
            before = np.column_stack([cols[k] for k in ("alpha", "N1", "N2", "T1")])
            return f.decode(cols, before + Y - Y0)
        s_in = f.mobilized_friction(cols["N1"], cols["T1"])
        Y = Y.copy()
        Y[:, :3] -= Y0[:, :3]
        Y[:, 3] = s_in + Y[:, 3] - Y0[:, 3]
        if self.opening == "rule":
            # Opening decided as eq. 1.7's closed form does, on the continued force increments
            # (regressed on closed cells only): a force that would turn negative opens the cell.
            trial1, trial2 = cols["N1"] + f.force_scale * Y[:, 1], cols["N2"] + f.force_scale * Y[:, 2]
            Y[:, 4] = np.where((trial1 < 0) | (trial2 < 0), 1.0, -1.0)
        return f.decode(cols, Y)


def _members(model) -> list[Surrogate]:
    """The models of a solver: one, or an ensemble of ``meso`` models of one formulation."""
    members = list(model) if isinstance(model, Sequence) else [model]
    if not members:
        raise InputError("an ensemble of surrogates needs at least one model")
    first = members[0].formulation
    if len(members) > 1 and first.name != "meso":
        raise InputError(f"an ensemble averages increments of meso-formulation models, got {first.name!r} models")
    for m in members[1:]:
        if m.formulation.to_dict() != first.to_dict():
            raise InputError("the ensemble's models have different formulations (cell solver, material "
                             "or mechanisms): train every member on the same data and settings")
    return members


def _same(a, b) -> bool:
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)
    return a == b


def load_solver(spec: str, on_outside: str = "fallback") -> SurrogateSolver:
    """``surrogate`` (the shipped default), ``surrogate:NAME`` (a shipped model),
    ``surrogate:PATH`` or an ensemble ``surrogate:PATH+PATH+...``."""
    from .modelfile import load
    from .shipped import model_path

    return SurrogateSolver([load(model_path(ref)) for ref in spec.partition(":")[2].split("+")], on_outside)
