"""No request turns into unbounded work: huge cell increments and run-away Newton trials fail
promptly with a one-line reason, and a bad carried tangent cannot push a trial past the cap."""

from __future__ import annotations

import numpy as np
import pytest

from hmodel import Params
from hmodel.cell import CellState
from hmodel.cell.closed_form import ClosedFormSolver
from hmodel.errors import PointFailure, SolverError
from hmodel.loading.compiled import CompiledSegment
from hmodel.loading.control import Control, Tangent, solve_increment
from hmodel.loading.newton import NewtonSettings, _bound, solver_limits
from hmodel.loading.named_paths import consolidate
from hmodel.rev import Rev
from hmodel.surrogate.shipped import load_shipped
from hmodel.surrogate.solver import SurrogateSolver

SMALL = Params(n_theta=12)


def test_surrogate_refuses_a_huge_cell_increment_before_any_work():
    solver = SurrogateSolver(load_shipped("increment"))
    cells = solver.initial(SMALL, (3,))
    huge = -4e13 * SMALL.l10  # an increment of this size once ran for hours (docs/notes/2026-12-01-engine-shape.md)
    with pytest.raises(SolverError, match=r"times the surrogate's largest trained increment") as err:
        solver.step(SMALL, cells, np.full(3, huge), np.zeros(3))
    assert "\n" not in str(err.value) and f"{solver.max_increment:.3g}" in str(err.value)
    assert solver.counts["substeps"] == 0 and solver.counts["network_cells"] == 0
    with pytest.raises(SolverError, match="non-finite"):
        solver.step(SMALL, cells, np.full(3, np.inf), np.zeros(3))


def test_surrogate_still_cuts_a_large_but_sane_increment_into_substeps():
    solver = SurrogateSolver(load_shipped("increment"))
    cells = solver.initial(SMALL, (3,))
    solver.step(SMALL, cells, np.full(3, -5 * solver.max_increment * SMALL.l10), np.zeros(3))
    assert solver.counts["substeps"] == 5


class Recording(ClosedFormSolver):
    """The closed form, with every cell length increment it is asked for recorded; with
    ``soft`` < 1 the cells see only that fraction of their length increments: a sample that
    has all but lost its stiffness (its tangent nearly singular)."""

    name = "recording"

    def kernel(self, params):  # the generic driver, which calls step
        return None

    def __init__(self, soft: float = 1.0):
        self.soft, self.largest, self.calls = soft, 0.0, 0

    def step(self, params, state, dl1, dl2):
        self.calls += 1
        self.largest = max(self.largest, float(np.abs(dl1).max() / params.l10),
                           float(np.abs(dl2).max() / params.l20))
        return super().step(params, state, self.soft * np.asarray(dl1), self.soft * np.asarray(dl2))


def _consolidated(p0=(1e5, 2e5)):
    return consolidate(Rev(SMALL), list(p0))


def test_newton_on_a_nearly_singular_sample_stops_with_one_line_and_bounded_trials():
    state = _consolidated()
    solver = Recording(soft=1e-12)
    rev = Rev(SMALL, solver)
    # sigma_22 held at half its current value: out of reach within the cap (the cells barely
    # respond; only the macro volume V0 det(I - eps) would lower the stress, by a 50 % extension)
    control = Control.components("ESE", np.column_stack([np.full(2, 1e-3), 0.5 * state.sig[:, 1],
                                                          np.zeros(2)]))
    with pytest.raises(PointFailure, match="diverged") as err:
        solve_increment(rev, state, control, Tangent())
    assert "\n" not in str(err.value)
    assert err.value.points.tolist() == [0, 1]  # the failed points, named for the caller
    # Every trial within the cap: a cell strain e11 c^2 + e22 s^2 + 2 e12 s c is at most
    # sqrt(1 + 2 s^2 c^2) <= sqrt(1.5) times the macro strain increment's norm.
    s = NewtonSettings()
    cap = max(s.max_trial_strain, s.step_multiple * 1e-3)
    assert f"{cap:.3g}" in str(err.value)
    assert solver.largest <= cap * np.sqrt(1.5)
    assert solver.calls <= 2 * (s.max_iter + 4)  # Newton's trials and tangents: no event loop


class Ceiled(Recording):
    """:class:`Recording` that takes cell strain increments up to ``max_cell_strain`` only, as a
    learned cell does (:attr:`hmodel.surrogate.solver.SurrogateSolver.max_cell_strain`)."""

    max_cell_strain = 4e-3


def test_newton_holds_its_trials_within_what_the_cell_solver_takes():
    """The nearly singular sample above asks for trials up to the cap (0.1); a cell solver that
    takes cell strains up to 4e-3 only is never asked for more (the cap lowered to
    solver_limits' ceiling), and the increment fails as before: diverged, one line."""
    state = _consolidated()
    control = Control.components("ESE", np.column_stack([np.full(2, 1e-3), 0.5 * state.sig[:, 1],
                                                          np.zeros(2)]))
    free, ceiled = Recording(soft=1e-12), Ceiled(soft=1e-12)
    for solver in (free, ceiled):
        with pytest.raises(PointFailure, match="diverged"):
            solve_increment(Rev(SMALL, solver), state, control, Tangent())
    assert free.largest > 10 * Ceiled.max_cell_strain  # without the ceiling: far beyond
    assert Ceiled.max_cell_strain / 4 < ceiled.largest <= Ceiled.max_cell_strain
    assert solver_limits(ceiled) == (0.0, pytest.approx(4e-3 / (2 * np.sqrt(2))))
    assert solver_limits(ClosedFormSolver())[1] == np.inf
    shipped = SurrogateSolver(load_shipped("hexagon-center-1"))
    assert shipped.max_cell_strain == pytest.approx(shipped.max_substeps * shipped.max_increment)
    # the ceiling never cuts the strain rows themselves: a strain increment beyond it is asked as is
    big = Control.components("EEE", np.column_stack([np.full(2, 3e-3), np.zeros(2), np.zeros(2)]))
    ceiled.largest = 0.0
    solve_increment(Rev(SMALL, ceiled), state, big, Tangent())
    assert ceiled.largest >= 3e-3 * 0.99


def _sign_flipped_tangent(rev, state, control):
    t = Tangent()
    solve_increment(rev, state, control, t)  # a first increment, to have a real tangent
    return -t.K


def test_a_sign_flipped_carried_tangent_is_survived_by_both_drivers():
    state = _consolidated()
    end = np.column_stack([np.full(2, 5e-3), state.sig[:, 1], np.zeros(2)])
    control = Control.components("ESE", np.column_stack([np.full(2, 1e-3), state.sig[:, 1], np.zeros(2)]))
    rev = Rev(SMALL)
    reference = solve_increment(rev, state, control, Tangent())
    solver = Recording()
    generic = solve_increment(Rev(SMALL, solver), state, control,
                              Tangent(_sign_flipped_tangent(rev, state, control)))
    np.testing.assert_allclose(generic.sig, reference.sig, rtol=1e-8, atol=1e-6)
    assert solver.largest <= NewtonSettings().max_trial_strain * np.sqrt(1.5)
    # the compiled kernel, from the same flipped tangent (its first of five increments)
    runner = CompiledSegment(rev, state, (False, True, False), np.eye(3), state.sig, end, 5,
                             Tangent(_sign_flipped_tangent(rev, state, control)))
    rec = runner.run(1, 2)
    np.testing.assert_allclose(rec[0, :, 3:6], reference.sig, rtol=1e-8, atol=1e-6)


def test_bound_scales_back_onto_the_ball_only_outside_it():
    x = np.array([3.0, 4.0, 0.0])
    assert _bound(x, 1.0) and np.allclose(x, [0.6, 0.8, 0.0])
    y = np.array([0.1, 0.0, 0.0])
    assert not _bound(y, 1.0) and y[0] == 0.1


def test_dem_solver_refuses_a_length_increment_as_long_as_the_cell():
    from hmodel.dem.solver import DEMSolver
    solver = DEMSolver("dem:standard")
    params = Params(sliding_rhs="equilibrium", n_theta=6)
    cells: CellState = solver.initial(params, (2,))
    # refused before YADE is looked for or started
    with pytest.raises(SolverError, match="at most the cell's length"):
        solver.step(params, cells, np.array([-1e13, 0.0]), np.zeros(2))


def test_the_suite_runs_under_a_per_test_timeout(request):
    # a hang fails one test by name instead of eating CI's time (pyproject's pytest options)
    assert request.config.pluginmanager.hasplugin("timeout")
    assert float(request.config.getini("timeout")) > 0
