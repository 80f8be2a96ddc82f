"""Conformance of a cell solver to the contract of :class:`~hmodel.cell.base.CellSolver`.

:func:`check_cell_solver` runs a solver through every clause the engine relies on, in the
manner of scikit-learn's ``check_estimator``: its declarations (name, lengths per cell, state
kind, tolerance, cost per cell, ...), its unloaded cells, one increment of a batch with the
declared number of lengths, and, where the solver declares them, its batched parameter sets,
its compiled law and that law's tangent. A clause it breaks raises an :class:`AssertionError`
naming the solver and the clause. A new solver (a package of its own registered under
``hmodel.cell_solvers``) calls it from its tests.
"""

from __future__ import annotations

import inspect
import math

import numpy as np

from ..params import Params
from .base import (
    LAW_COMPLIANCE,
    LAW_MESO,
    MECHANISM_PARAMS,
    P_LAW,
    STATE_BIHEXAGON,
    STATE_H_CELL,
    STATE_KINDS,
    CellKernel,
    CellSolver,
)
from .bihex import BIHEX_FIELDS, bihex_step_kernel
from .closed_form import cell_jacobian, step_kernel
from .compliance_kernel import advance_cells as compliance_cells
from .meso_kernel import advance_cells as meso_cells
from .mesostress import meso_vsigma
from .state import FIELDS, CellFlags, CellState

#: The batch of cells every increment is checked on: leading shape S.
SHAPE = (2, 3)
#: Length increments of the check, relative to the unloaded cell's lengths (a compression);
#: the second row of the batch takes half of them.
STRAIN = 1e-4
#: Relative tolerance of learned laws against their solver's step (the same network outputs
#: through another order of operations) and of finite differences of the tangent.
RTOL = 1e-6
#: The same for a learned response, relative to each state field's largest value: float32
#: products of a network differ with the rows they are batched with.
LEARNED_RTOL = 1e-5


class _Check:
    """The failures of one solver, raised as one AssertionError naming it and the clause."""

    def __init__(self, solver):
        self.solver = solver

    def __call__(self, ok: bool, clause: str) -> None:
        if not ok:
            raise AssertionError(f"cell solver {_label(self.solver)}: {clause}")


def _label(solver) -> str:
    name = getattr(solver, "name", None)  # a solver that breaks the contract may declare none
    return repr(name) if isinstance(name, str) else repr(solver)


def check_cell_solver(solver: CellSolver, params: Params | None = None, *, steps: bool = True) -> None:
    """Run ``solver`` through the cell-solver contract; raise AssertionError at the first clause
    it breaks.

    Parameters
    ----------
    solver : CellSolver
    params : Params, optional
        The material of the check (default: the one the solver's cells were trained with,
        :attr:`~CellSolver.trained_params`, else ``Params()``).
    steps : bool
        Whether to step cells (the increment, batched sets, the compiled law against
        :meth:`~CellSolver.step`, the tangent); False checks what needs no increment (a DEM
        solver where YADE is not installed).
    """
    check = _Check(solver)
    check(isinstance(solver, CellSolver), "is not a CellSolver (subclass hmodel.cell.CellSolver)")
    if params is None:
        trained = solver.trained_params
        params = Params.from_dict(trained) if trained else Params()
    check_declarations(solver, params)
    state = check_initial(solver, params)
    kernel = check_kernel(solver, params, state)
    if not steps:
        return
    solver.check_available()
    dls = _increments(solver, params)
    new = check_step(solver, params, state, dls)
    if solver.batches_sets:
        check_sets(solver, params, state, dls)
    if kernel is not None:
        check_compiled_law(solver, params, kernel, state, dls)
        if kernel.exact_tangent and solver.state_kind == STATE_H_CELL:
            check_tangent(solver, params, kernel, new, dls)


def check_declarations(solver: CellSolver, params: Params) -> None:
    """The declared capabilities have their types and ranges, and :meth:`~CellSolver.step`
    takes the declared number of lengths."""
    check = _Check(solver)
    check(isinstance(getattr(solver, "name", None), str) and bool(solver.name), "declares no name")
    check(solver.n_lengths in (2, 3), f"n_lengths is {solver.n_lengths!r}, not 2 (H-cells) or 3 (bi-hexagons)")
    check(solver.state_kind in STATE_KINDS, f"state_kind {solver.state_kind!r} is none of {STATE_KINDS}")
    rtol = solver.stress_rtol
    check(isinstance(rtol, (int, float)) and 0.0 <= rtol < 1.0, f"stress_rtol {rtol!r} is not in [0, 1)")
    size = solver.bytes_per_cell
    check(isinstance(size, (int, np.integer)) and size > 0, f"bytes_per_cell {size!r} is not a positive integer")
    check(solver.max_cell_strain > 0, f"max_cell_strain {solver.max_cell_strain!r} is not positive")
    for flag in ("batches_sets", "spread_alpha0", "learned", "dem_cells"):
        check(isinstance(getattr(solver, flag), (bool, np.bool_)), f"{flag} is not a bool")
    check(solver.counts is None or isinstance(solver.counts, dict), "counts is neither None nor a dict")
    check(solver.trained_params is None or isinstance(solver.trained_params, dict),
          "trained_params is neither None nor a dict")
    mechanisms = solver.mechanisms
    check(isinstance(mechanisms, frozenset)
          and all(isinstance(m, str) and m.partition("=")[0] in MECHANISM_PARAMS for m in mechanisms),
          f"mechanisms {mechanisms!r} is not a frozenset of NAME=VALUE of {MECHANISM_PARAMS}")
    domain = solver.domain
    check(domain is None or (isinstance(domain, dict) and all(lo <= hi for lo, hi in domain.values())),
          "domain is neither None nor {name: (lo, hi)}")
    if domain is not None:
        fields = set(params.to_dict())
        check(set(domain) <= fields, f"domain names {sorted(set(domain) - fields)}, not Params fields")
    state = CellState(np.zeros((1, len(solver.field_names()))))
    try:
        inspect.signature(solver.step).bind(params, state, *([0.0] * solver.n_lengths))
    except TypeError:
        check(False, f"step does not take the declared {solver.n_lengths} length increments")


def check_initial(solver: CellSolver, params: Params) -> CellState:
    """Unloaded cells: their layout is the declared one (field names, state kind), the cells
    of :meth:`~CellSolver.initial_cells` at ``params.alpha0`` are those of
    :meth:`~CellSolver.initial`, cells that may start apart (``spread_alpha0``) keep their own
    angle, meso-stress and fractions have their shapes. Returns the cells (:data:`SHAPE`)."""
    check = _Check(solver)
    names = solver.field_names()
    state = solver.initial(params, SHAPE)
    check(isinstance(state, CellState), "initial does not return a CellState")
    values = np.asarray(state.values)
    check(values.shape == (*SHAPE, len(names)) and values.dtype == np.float64,
          f"initial(params, {SHAPE}) has values {values.shape} {values.dtype}, not {(*SHAPE, len(names))} "
          f"float64 (field_names: {len(names)})")
    check(bool(np.all(np.isfinite(values))), "initial cells are not finite")
    check(solver.initial(params).values.shape == (len(names),), "initial(params) is not one cell")
    declared = {STATE_H_CELL: FIELDS, STATE_BIHEXAGON: BIHEX_FIELDS}.get(solver.state_kind)
    check(declared is None or tuple(names) == declared,
          f"a {solver.state_kind} state has the fields {declared}, not {tuple(names)}")
    same = solver.initial_cells(params, np.full(SHAPE, params.alpha0))
    check(np.allclose(same.values, values, rtol=1e-12, atol=0.0),
          "initial_cells at params.alpha0 are not the cells of initial")
    if solver.spread_alpha0:
        angles = params.alpha0 + np.array([-0.05, 0.05])
        apart = solver.initial_cells(params, angles)
        check(np.allclose(apart.values[:, names.index("alpha")], angles, rtol=1e-12, atol=0.0),
              "cells that may start apart (spread_alpha0) do not keep their own opening angle")
    meso = solver.meso(params, state)
    if solver.state_kind == STATE_H_CELL:
        check(meso is None, "an H-cell's meso-stress is eq. 1.12 of its fields: meso must be None")
    else:
        check(meso is not None, f"a {solver.state_kind} state has a meso-stress of its own: meso is None")
        vs, vol = meso
        width = 6 if solver.state_kind == STATE_BIHEXAGON else 3
        check(np.shape(vs) == (*SHAPE, width) and np.shape(vol) == SHAPE,
              f"meso gives {np.shape(vs)} and {np.shape(vol)}, not {(*SHAPE, width)} and {SHAPE}")
        check(bool(np.all(np.asarray(vol) > 0) and np.all(np.isfinite(vs))),
              "meso-volumes are not positive or V sigma not finite")
    for key, hit in solver.fractions(params, state).items():
        check(isinstance(key, str) and np.shape(hit) == SHAPE and np.asarray(hit).dtype == bool,
              f"fraction {key!r} is not a boolean array of the cells' shape {SHAPE}")
    if solver.geometry is not None and solver.state_kind != STATE_BIHEXAGON:
        check(solver.geometry.n_fields == len(names), "the DEM geometry's layout is not the state's")
    return state


def check_kernel(solver: CellSolver, params: Params, state: CellState) -> CellKernel | None:
    """The compiled law, where :meth:`~CellSolver.kernel` declares one: packed parameters, and
    for a learned law, its law and the response rows of the cells' states."""
    check = _Check(solver)
    kernel = solver.kernel(params)
    if kernel is None:
        return None
    check(isinstance(kernel, CellKernel), "kernel returns neither None nor a CellKernel")
    p = kernel.params
    check(isinstance(p, np.ndarray) and p.ndim == 1 and p.dtype == np.float64 and bool(np.all(np.isfinite(p))),
          "the compiled law's packed parameters are not a finite float64 vector")
    check(kernel.exact_tangent == (not kernel.learned), "only the closed form's law has exact tangents")
    if kernel.learned:
        check(p.size > P_LAW and p[P_LAW] in (LAW_MESO, LAW_COMPLIANCE),
              f"a learned law names its law at index {P_LAW} (LAW_MESO or LAW_COMPLIANCE)")
        resp = kernel.responses(_flat(state))
        check(np.ndim(resp) == 2 and len(resp) == math.prod(SHAPE) and bool(np.all(np.isfinite(resp))),
              "the learned law's responses are not one finite row per cell")
    return kernel


def check_step(solver: CellSolver, params: Params, state: CellState, dls: list[np.ndarray]) -> CellState:
    """One increment with the declared number of lengths: shapes, finite states that moved, the
    same answer for the same request (Newton's trials need ``step`` pure) whether the lengths
    are broadcast or given per cell, and each cell's answer its own (a sub-batch gives its
    rows). Returns the cells after it."""
    check = _Check(solver)
    new, flags = solver.step(params, state, *dls)
    check(isinstance(new, CellState) and isinstance(flags, CellFlags), "step does not return (CellState, CellFlags)")
    values = np.asarray(new.values)
    check(values.shape == state.values.shape, f"step returns states {values.shape}, not {state.values.shape}")
    check(bool(np.all(np.isfinite(values))), "step returns states that are not finite")
    check(np.asarray(flags.flags).shape[:-1] == SHAPE and np.asarray(flags.flags).dtype == bool,
          f"step returns flags {np.asarray(flags.flags).shape} that are not booleans of the cells' shape")
    check(not np.array_equal(values, state.values), "a compression increment leaves the cells as they were")
    again, flags2 = solver.step(params, state, *(np.broadcast_to(d, SHAPE).copy() for d in dls))
    check(np.array_equal(again.values, values) and np.array_equal(flags2.flags, flags.flags),
          "step is not a function of the cells and their increments (the same request answered otherwise)")
    part, _ = solver.step(params, CellState(np.ascontiguousarray(state.values[1:])), *(d[1:] for d in dls))
    check(np.allclose(part.values, values[1:], rtol=RTOL, atol=0.0),
          "a cell's increment depends on the other cells of the batch")
    return new


def check_sets(solver: CellSolver, params: Params, state: CellState, dls: list[np.ndarray]) -> None:
    """Batched parameter sets (``batches_sets``): :meth:`~CellSolver.step_sets` of two
    materials gives each point what :meth:`~CellSolver.step` gives it with its own."""
    check = _Check(solver)
    other = params
    for name, (lo, hi) in (solver.domain or {}).items():
        if name != "alpha0":  # the cells start at the set's α0: move the contact law only
            other = other.with_(**{name: 0.5 * (lo + hi)})
    check(other != params, "batches_sets declared without a training domain to draw a second material from")
    sets, index = [params, other], np.array([0, 1])
    start = np.stack([state.values[0], solver.initial(other, SHAPE[1:]).values])
    values, flags = solver.step_sets(sets, index, CellState(start), *dls)
    for b, s in enumerate(sets):
        alone, _ = solver.step(s, CellState(np.ascontiguousarray(start[b:b + 1])), *(d[b:b + 1] for d in dls))
        # a network's float32 products differ with the batch they are in: round-off of each
        # field's scale, not of each value
        scale = np.abs(alone.values).max(axis=tuple(range(alone.values.ndim - 1)))
        check(np.allclose(values[b:b + 1], alone.values, rtol=RTOL, atol=0.0) if not solver.learned else
              np.all(np.abs(values[b:b + 1] - alone.values) <= LEARNED_RTOL * scale),
              f"step_sets does not give parameter set {b} what step gives it alone")


def check_compiled_law(solver: CellSolver, params: Params, kernel: CellKernel, state: CellState,
                       dls: list[np.ndarray]) -> None:
    """The compiled law applied to the cells (the compiled loading path's trial) gives what
    :meth:`~CellSolver.step` gives: exactly for the closed form's, to :data:`RTOL` for a learned
    response."""
    check = _Check(solver)
    values = _flat(state)
    dl = np.ascontiguousarray(np.stack([np.broadcast_to(d, SHAPE).reshape(-1) for d in dls], axis=-1))
    ref = np.asarray(solver.step(params, state, *dls)[0].values).reshape(values.shape)
    if not kernel.learned:
        out = np.empty_like(values)
        flags = np.empty((len(values), 5 if solver.n_lengths == 2 else 11), np.bool_)
        run = step_kernel if solver.n_lengths == 2 else bihex_step_kernel
        check(run(values, dl, kernel.params, out, flags) < 0, "the compiled law fails an increment step solves")
        check(np.array_equal(out, ref), "the closed form's compiled law is not step's increment")
        return
    check(solver.n_lengths == 2, "a learned compiled law steps 2D cells")
    resp = np.ascontiguousarray(kernel.responses(values))
    if kernel.params[P_LAW] == LAW_MESO:
        out, _, ok = meso_cells(values, dl, kernel.params, resp)
    else:
        out, flags = np.empty_like(values), np.empty((len(values), 5), np.bool_)
        ok = compliance_cells(values, dl, resp, kernel.params, out, flags) < 0
    check(bool(ok), "the learned compiled law fails an increment step solves")
    check(np.allclose(out, ref, rtol=RTOL, atol=RTOL * np.abs(ref).max()),
          "the learned compiled law is not step's increment")


def check_tangent(solver: CellSolver, params: Params, kernel: CellKernel, state: CellState,
                  dls: list[np.ndarray]) -> None:
    """The exact tangent of a closed-form law (``kernel.exact_tangent``): each cell's Jacobian
    of (V σnn, V σtt) in the length increments (:func:`hmodel.cell.closed_form.cell_jacobian`)
    is the central difference of :meth:`~CellSolver.step`'s."""
    check = _Check(solver)
    v = _flat(state)[0]
    dl = [float(np.broadcast_to(d, SHAPE).reshape(-1)[0]) for d in dls]
    ok, *jac = cell_jacobian(*v, *dl, kernel.params)
    check(bool(ok), "the tangent's increment fails")
    one = CellState(v[None])
    for k in range(2):
        h = 1e-4 * abs(dl[k])
        plus, minus = list(dl), list(dl)
        plus[k] += h
        minus[k] -= h
        fd = (meso_vsigma(params, solver.step(params, one, *plus)[0])[0]
              - meso_vsigma(params, solver.step(params, one, *minus)[0])[0]) / (2 * h)
        exact = np.array([jac[k], jac[2 + k]])
        check(np.allclose(exact, fd, rtol=RTOL, atol=RTOL * np.abs(fd).max()),
              f"the exact tangent along dl{k + 1} is {exact}, its central difference {fd}")


def _increments(solver: CellSolver, params: Params) -> list[np.ndarray]:
    """The check's length increments (S-shaped): :data:`STRAIN` of the unloaded lengths
    (l1 along l10, the others along l20), half of it on the batch's second row."""
    rows = np.array([[1.0], [0.5]]) * np.ones(SHAPE)
    lengths = [params.l10] + [params.l20] * (solver.n_lengths - 1)
    return [-STRAIN * length * rows for length in lengths]


def _flat(state: CellState) -> np.ndarray:
    values = np.asarray(state.values, float)
    return np.ascontiguousarray(values.reshape(-1, values.shape[-1]))


__all__ = ["check_cell_solver", "check_compiled_law", "check_declarations", "check_initial", "check_kernel",
           "check_sets", "check_step", "check_tangent"]
