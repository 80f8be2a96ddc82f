"""Every registered cell solver against the cell-solver contract (hmodel.cell.conformance), and
a minimal solver of this file that declares little and lives on the defaults.

The registered solvers are those of the ``hmodel.cell_solvers`` entry points (the closed form,
every shipped surrogate, every DEM mesostructure and the DEM bi-hexagon), the 3D bi-hexagons
and the gated solvers; a DEM solver is stepped where YADE is installed (``yade``) and checked
without increments everywhere.
"""

from __future__ import annotations

import numpy as np
import pytest

from hmodel import Params
from hmodel.cell import FIELDS, BiHexSolver, CellFlags, CellSolver, CellState
from hmodel.cell.base import STATE_H_CELL, STATE_OWN
from hmodel.cell.conformance import check_cell_solver
from hmodel.cell.mesostructure import CONSTRUCTORS
from hmodel.rev import Rev
from hmodel.solvers import PREFIXED, available, get_solver
from hmodel.surrogate.shipped import ENSEMBLES, SHIPPED
from hmodel.surrogate.solver import gated_solver

#: The specs of every registered solver, by entry point.
REGISTERED = {
    "closed-form": ["closed-form"],
    "surrogate": ["surrogate"] + [f"surrogate:{n}" for n in (*SHIPPED, *ENSEMBLES)],
    "dem": [f"dem:{m}" for m in CONSTRUCTORS] + list(PREFIXED),
}
DEM = REGISTERED["dem"]
def _spec_params(spec: str):
    return spec


def test_every_entry_point_is_checked():
    assert set(available()) == set(REGISTERED)


@pytest.mark.parametrize("spec", [_spec_params(s) for k in ("closed-form", "surrogate") for s in REGISTERED[k]])
def test_registered_solver_keeps_the_contract(spec):
    check_cell_solver(get_solver(spec))


@pytest.mark.parametrize("spec", DEM)
def test_dem_solver_declares_the_contract(spec):
    """Declarations, unloaded cells and meso-stress need no YADE."""
    solver = get_solver(spec)
    assert solver.dem_cells and not solver.learned
    check_cell_solver(solver, steps=False)


@pytest.mark.yade
@pytest.mark.parametrize("spec", DEM)
def test_dem_solver_keeps_the_contract(spec):
    check_cell_solver(get_solver(spec))


@pytest.mark.parametrize("make", [
    BiHexSolver,
    lambda: BiHexSolver(hexagon=get_solver("surrogate:equilibrium")),
    lambda: gated_solver("surrogate:default", 0.99, "closed-form"),
    lambda: gated_solver("surrogate:ensemble", 0.99, "closed-form"),
], ids=["bihexagon", "learned-bihexagon", "gated", "gated-ensemble"])
def test_3d_and_gated_solvers_keep_the_contract(make):
    check_cell_solver(make())


@pytest.mark.yade
def test_a_richer_cell_gated_to_its_dem_cell_keeps_the_contract():
    shadowed = gated_solver("surrogate:hexagon-center", 0.5, "dem:hexagon-center")
    check_cell_solver(shadowed)
    assert shadowed.counts["dem_increments"] > 0  # the gate sent cells to YADE


class Stretching(CellSolver):
    """The least a solver declares: a name, its unloaded cells and an increment (the cells'
    lengths follow their increments, nothing else moves)."""

    name = "stretching"

    def initial(self, params, shape=()):
        return CellState.initial(params, shape)

    def step(self, params, state, dl1, dl2):
        v = np.array(state.values, float)
        v[..., 6] += dl1
        v[..., 7] += dl2
        return CellState(v), CellFlags(np.zeros((*v.shape[:-1], 5), bool))


def test_a_minimal_solver_keeps_the_contract_on_the_defaults():
    solver, params = Stretching(), Params(n_theta=12)
    check_cell_solver(solver, params)
    assert (solver.n_lengths, solver.state_kind, solver.stress_rtol, solver.max_cell_strain) == (2, STATE_H_CELL, 0.0, np.inf)
    assert not (solver.batches_sets or solver.spread_alpha0 or solver.learned or solver.dem_cells)
    assert solver.counts is solver.domain is solver.trained_params is solver.geometry is None
    assert solver.field_names() == FIELDS and solver.fractions(params, solver.initial(params)) == {}
    rev = Rev(params, solver)  # no compiled law: the generic driver; eq. 1.12 of its fields
    assert rev.kernel is None
    state = rev.step(rev.initial(1), np.array([[1e-4, 0.0, 0.0]]))
    assert np.allclose(state.cells.l1, rev.initial(1).cells.l1 - 1e-4 * rev.initial(1).cells.l1 * rev.directions.cos2)


class TwoLengthsDeclaredThree(Stretching):
    n_lengths = 3


class Impure(Stretching):
    def step(self, params, state, dl1, dl2):
        new, flags = super().step(params, state, dl1, dl2)
        return CellState(new.values * (1 + 1e-12 * np.random.default_rng().random())), flags


class OwnStressDeclaredHCell(Stretching):
    def meso(self, params, state):
        return np.zeros((*state.shape, 3)), np.ones(state.shape)


class OwnStateUndeclared(Stretching):
    state_kind = STATE_OWN


class Coupled(Stretching):
    def step(self, params, state, dl1, dl2):
        new, flags = super().step(params, state, dl1, dl2)
        return CellState(new.values + 1e-3 * len(new.values)), flags


class Nameless(Stretching):
    name = ""


@pytest.mark.parametrize("solver, clause", [
    (TwoLengthsDeclaredThree(), "does not take the declared 3 length increments"),
    (Impure(), "not a function of the cells"),
    (OwnStressDeclaredHCell(), "meso must be None"),
    (OwnStateUndeclared(), "has a meso-stress of its own"),
    (Coupled(), "depends on the other cells"),
    (Nameless(), "declares no name"),
])
def test_the_check_names_the_clause_a_solver_breaks(solver, clause):
    with pytest.raises(AssertionError, match=clause):
        check_cell_solver(solver, Params())
