"""The richer cell's learned response gated to its DEM cell (``--fallback dem:MESO``): the DEM
shadow a cell carries is exact, catching up follows the cell's lag, every cell gated is the
DEM-REV itself, and bad combinations are refused in one line."""

from __future__ import annotations

import csv
import math
from dataclasses import replace

import numpy as np
import pytest

from hmodel import Params
from hmodel.cell import CellState
from hmodel.cli.app import main
from hmodel.dem.solver import DEMSolver
from hmodel.errors import InputError
from hmodel.loading import run_biaxial
from hmodel.loading.named_paths import consolidate
from hmodel.rev.rev import Rev
from hmodel.solvers import get_solver
from hmodel.surrogate.modelfile import save
from hmodel.surrogate.shadow import ShadowedSolver
from hmodel.surrogate.shipped import load_shipped
from hmodel.surrogate.solver import gated_solver

PARAMS = Params(sliding_rhs="equilibrium", n_theta=12)
DEM = "dem:hexagon-center:tol=1e-7,max_iter=100000"


def test_the_shipped_richer_cell_gates_to_its_dem_cell():
    solver = gated_solver("surrogate:hexagon-center", 0.9, DEM)  # YADE starts on the first step only
    assert isinstance(solver, ShadowedSolver)
    cells = solver.initial(PARAMS, (3,))
    summary, full, lag = solver.split(cells.values)
    assert full.shape[-1] == DEMSolver(DEM).n_fields and np.all(lag == 0)
    np.testing.assert_allclose(summary, solver.formulation.summary(full), rtol=0, atol=0)


@pytest.mark.parametrize("fallback, words", [("closed-form", "other cells"),
                                             ("dem:hexagon-unequal", "other cells"),
                                             ("dem:standard", "other cells")])
def test_a_fallback_of_other_cells_is_refused(fallback, words):
    with pytest.raises(InputError, match=words):
        gated_solver("surrogate:hexagon-center", 0.9, fallback)


def test_a_model_without_trust_is_refused_in_one_line(tmp_path, capsys):
    model = load_shipped("hexagon-center-0")
    bare = replace(model, meta={k: v for k, v in model.meta.items() if k != "trust"}, trust_reference=None)
    save(bare, tmp_path / "bare.safetensors")
    out = tmp_path / "run"
    assert main(["run", "biaxial", "--p0", "100kPa", "-p", "sliding_rhs=equilibrium", "--solver",
                 f"surrogate:{tmp_path / 'bare.safetensors'}", "--gate", "0.9", "--fallback", DEM,
                 "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "trust" in err[0] and not out.exists()


@pytest.mark.yade
def test_every_cell_gated_is_the_dem_rev():
    """With every cell above the gate, each increment is the DEM cell's from its exact state:
    the gated REV is the DEM-REV, to the DEM's convergence."""
    solver = gated_solver("surrogate:hexagon-center", 0.5, DEM)
    solver.gate.threshold = -math.inf
    params = Params(sliding_rhs="equilibrium", n_theta=6)
    res = run_biaxial(params, [1e5], 0.004, solver=solver, step=1e-3, iso_step=2e-4)
    ref = run_biaxial(params, [1e5], 0.004, solver=get_solver(DEM), step=1e-3, iso_step=2e-4)
    a, b = res.point(0).stage("shear"), ref.point(0).stage("shear")
    assert len(a["q"]) == len(b["q"]) > 3
    np.testing.assert_allclose(a["q"], b["q"], rtol=0, atol=1e-6 * np.abs(b["q"]).max())
    assert solver.counts["gated"] == solver.counts["gate_checked"] > 0


@pytest.mark.yade
def test_a_shadow_catches_up_along_its_lag():
    """Nothing gated: the summary's lengths are the shadow's plus the lag, and catching up is
    the DEM cell driven along the lag in equal sub-steps, stepped here by hand."""
    solver = gated_solver("surrogate:hexagon-center", 0.5, DEM)
    solver.gate.threshold = math.inf
    state = consolidate(Rev(PARAMS, solver), [1e5], step=2e-4)
    v = state.cells.values.reshape(-1, solver.n_state)
    summary, full, lag = solver.split(v)
    assert np.abs(lag).max() > 0 and solver.counts["gated"] == 0
    np.testing.assert_allclose(summary[:, 6:8], full[:, 6:8] + lag, rtol=0, atol=1e-12 * PARAMS.l10)
    caught = solver.caught_up(PARAMS, full, lag)
    n_sub = math.ceil((np.abs(lag) / [PARAMS.l10, PARAMS.l20]).max() / solver.replay_strain - 1e-12)
    dem, by_hand = DEMSolver(DEM), full
    for _ in range(n_sub):
        by_hand = dem.step(PARAMS, CellState(by_hand), lag[:, 0] / n_sub, lag[:, 1] / n_sub)[0].values
    np.testing.assert_array_equal(caught, by_hand)
    np.testing.assert_allclose(caught[:, 6:8], summary[:, 6:8], rtol=0, atol=1e-12 * PARAMS.l10)


@pytest.mark.yade
def test_the_command_line_reports_the_gated_fraction(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", "biaxial", "--p0", "100kPa", "-p", "sliding_rhs=equilibrium", "-p", "n_theta=12",
                 "--axial-strain", "0.004", "--solver", "surrogate:hexagon-center", "--gate", "0.5",
                 "--fallback", DEM, "--out", str(out)]) == 0
    line = [s for s in capsys.readouterr().out.splitlines() if s.startswith("gate 0.5")]
    assert line and "DEM cell increments" in line[0]
    rows = list(csv.DictReader((out / "result.csv").open()))
    gated = [float(r["gated"]) for r in rows]
    assert all(0 <= g <= 1 for g in gated) and max(gated) > 0  # the ensemble's median disagreement


def test_a_run_of_another_material_is_refused_even_where_every_cell_is_gated():
    solver = gated_solver("surrogate:hexagon-center", 0.5, DEM)
    solver.gate.threshold = -math.inf
    other = Params(sliding_rhs="equilibrium", phi_g=math.radians(25.0))
    with pytest.raises(InputError, match="phi_g"):
        solver.step(other, solver.initial(other, (2,)), np.zeros(2), np.zeros(2))
