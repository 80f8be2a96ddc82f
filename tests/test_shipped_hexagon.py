"""The shipped surrogate of a richer DEM cell (``surrogate:hexagon-center``): it runs without
YADE, refuses another material, and where YADE is installed it follows the DEM-REV it learned."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from hmodel import Params
from hmodel.cli.app import main
from hmodel.loading import run_biaxial
from hmodel.solvers import get_solver
from hmodel.surrogate.shipped import load_shipped, model_paths, shipped_path
from hmodel.surrogate.gate import check_members

PARAMS = Params(sliding_rhs="equilibrium", n_theta=12)
DEM = "dem:hexagon-center:tol=1e-7,max_iter=100000"


def test_the_name_resolves_to_a_small_meso_ensemble_with_its_trust():
    paths = model_paths("hexagon-center")
    assert paths == [shipped_path("hexagon-center-0"), shipped_path("hexagon-center-1")]
    assert sum(p.stat().st_size for p in paths) < 500_000
    first, second = (load_shipped(n) for n in ("hexagon-center-0", "hexagon-center-1"))
    for model in (first, second):
        assert model.formulation.name == "meso" and model.formulation.cell_step == 2.5e-4
        assert model.meta["params"]["sliding_rhs"] == "equilibrium"
    check_members([first, second])  # the trust was measured on these two, in this order


def test_runs_without_yade_and_holds_its_stress_control(monkeypatch):
    monkeypatch.setenv("HMODEL_YADE", "/nonexistent/yade")  # a DEM call would fail
    res = run_biaxial(PARAMS, [1e5, 2e5], 0.01, solver=get_solver("surrogate:hexagon-center"),
                      step=1e-3, iso_step=2e-4)
    for b, p0 in enumerate((1e5, 2e5)):
        shear = res.point(b).stage("shear")
        assert np.all(np.isfinite(shear["q"])) and shear["q"][-1] > 0.2 * p0
        np.testing.assert_allclose(shear["sig22"], p0, rtol=1e-6)
    # a denser confinement carries a larger deviator at the same strain
    assert res.point(1).stage("shear")["q"][-1] > res.point(0).stage("shear")["q"][-1]


def test_another_material_is_refused(tmp_path, capsys):
    assert main(["run", "biaxial", "--p0", "100kPa", "--solver", "surrogate:hexagon-center",
                 "--out", str(tmp_path / "x")]) == 1
    err = capsys.readouterr().err
    assert "sliding_rhs" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()


@pytest.mark.slow
@pytest.mark.yade
def test_compare_against_the_dem_rev_it_learned(tmp_path):
    """The documented comparison from the command line, on a short undrained path: within 2 %
    of the DEM-REV's peak q (the issue's accuracy target for the richer cell)."""
    assert main(["compare", "--reference", DEM, "--solver", "surrogate:hexagon-center",
                 "-p", "sliding_rhs=equilibrium", "-p", "n_theta=12", "--paths", "undrained",
                 "--axial-strain", "0.01", "--iso-step", "2e-4", "--out", str(tmp_path / "c")]) == 0
    rows = list(csv.DictReader((tmp_path / "c" / "deviations.csv").open()))
    assert rows and rows[0]["reference"].startswith("dem:hexagon-center") and rows[0]["status"] == "ok"
    assert 0 < float(rows[0]["q_max_dev_rel"]) < 0.02
