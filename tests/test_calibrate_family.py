"""Calibrating a cell model trained over a range of materials (a family model): its training
domain bounds the search, and a fit recovers the parameters of curves it made itself."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hmodel import Params
from hmodel.calibrate import fit
from hmodel.calibrate.data import Test
from hmodel.calibrate.model import ISO_STEP
from hmodel.calibrate.space import Space, training_domain
from hmodel.cell import ClosedFormSolver
from hmodel.cli.app import main
from hmodel.errors import InputError
from hmodel.loading import run_biaxial
from hmodel.solvers import get_solver_3d

#: A training domain as a family model stores it (Params units: angles in radians).
DOMAIN = {"kt_kn": (0.2, 1.0), "phi_g": (math.radians(10.0), math.radians(45.0)),
          "alpha0": (math.radians(35.0), math.radians(75.0))}


class FamilyLike(ClosedFormSolver):
    """The closed form with a family model's stored training domain: the calibration sees what
    it sees of a family surrogate (``domain``), with exact curves to recover."""

    name = "family-like"
    domain = DOMAIN


def test_default_bounds_of_a_family_model_are_its_domain():
    s = Space.make(["phi_g", "alpha0", "kn"], None, Params(), DOMAIN)
    b = dict(zip(s.names, s.bounds))
    assert b["phi_g"] == pytest.approx((10.0, 45.0)) and b["alpha0"] == pytest.approx((35.0, 75.0))
    assert b["kn"] == (1e6, 1e11)  # not in the domain (scaled out): the general range
    # bounds inside the domain are kept as given
    s = Space.make(["phi_g"], {"phi_g": (15.0, 40.0)}, Params(), DOMAIN)
    assert s.bounds == ((15.0, 40.0),)


@pytest.mark.parametrize("bounds, word", [({"phi_g": (5.0, 60.0)}, "phi_g=5:60"),
                                          ({"phi_g": (10.0, 46.0)}, "phi_g=10:46"),
                                          ({"kt_kn": (0.1, 0.8)}, "kt_kn=0.1:0.8")])
def test_bounds_outside_the_training_domain_are_refused(bounds, word):
    with pytest.raises(InputError, match=f"--bounds {word} reaches outside the model's training domain"):
        Space.make(list(bounds), bounds, Params(), DOMAIN)


def test_a_fixed_parameter_outside_the_domain_is_refused():
    with pytest.raises(InputError, match=r"kt_kn = 0.1 \(fixed\) lies outside the model's training domain"):
        Space.make(["phi_g"], None, Params(kt_kn=0.1), DOMAIN)
    # no domain (the closed form): any valid material
    assert Space.make(["phi_g"], None, Params(kt_kn=0.1), None).bounds == ((5.0, 60.0),)


def test_cli_refuses_bounds_outside_the_domain_in_one_line(tmp_path, capsys, monkeypatch):
    import hmodel.cli.calibrate as cli_cal

    monkeypatch.setattr(cli_cal, "get_solver", lambda spec: FamilyLike())
    csv = tmp_path / "d.csv"
    csv.write_text("eps11,q\n0,0\n0.01,1e5\n")
    out = tmp_path / "out"
    code = main(["calibrate", "--data", f"drained:100kPa:{csv}", "--fit", "phi_g",
                 "--bounds", "phi_g=5:60", "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and not out.exists()
    assert err == ["hmodel: error: --bounds phi_g=5:60 reaches outside the model's training domain (10–45°)"]


def test_the_shipped_family_model_bounds_the_search_and_recovers_its_own_curves(tmp_path, capsys):
    """The standard cell's shipped family network: the CLI refuses bounds outside its stored
    domain; a fit of φg and α0 finds the material of curves it made itself (φg 27°, α0 52°,
    another material than Table 1.1's, which a single-material network would refuse)."""
    from hmodel.solvers import get_solver

    solver = get_solver("surrogate:family")
    csv = tmp_path / "d.csv"
    csv.write_text("eps11,q\n0,0\n0.01,1e5\n")
    out = tmp_path / "out"
    code = main(["calibrate", "--data", f"drained:100kPa:{csv}", "--solver", "surrogate:family",
                 "--fit", "phi_g", "--bounds", "phi_g=5:60", "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    lo, hi = (math.degrees(v) for v in solver.domain["phi_g"])
    assert code == 1 and not out.exists()
    assert err == [(f"hmodel: error: --bounds phi_g=5:60 reaches outside the model's training domain "
                    f"({lo:.4g}–{hi:.4g}°)")]
    tests = _own_curves(Params(n_theta=36, phi_g=math.radians(27.0), alpha0=math.radians(52.0)), solver)
    cal = fit(tests, ["phi_g", "alpha0"], base=Params(n_theta=36), solver=solver, starts=2)
    assert cal.fitted["phi_g"] == pytest.approx(27.0, abs=0.05)
    assert cal.fitted["alpha0"] == pytest.approx(52.0, abs=0.05)


def _own_curves(truth: Params, solver) -> list[Test]:
    """Drained tests at 100 and 400 kPa to 2 % made by ``solver`` at ``truth``, every other
    row, as a measured test has them (strains since the end of consolidation)."""
    res = run_biaxial([truth], [1e5, 4e5], 0.02, step=1e-3, iso_step=ISO_STEP, solver=solver)
    tests = []
    for b, p0 in enumerate((1e5, 4e5)):
        c, s = res.point(b).stage("consolidation"), res.point(b).stage("shear")
        e = np.concatenate([[0.0], s["eps11"] - c["eps11"][-1]])
        q = np.concatenate([[c["q"][-1]], s["q"]])
        ev = np.concatenate([[0.0], s["eps_v"] - c["eps_v"][-1]])
        tests.append(Test("drained", p0, e[::2], q[::2], ev[::2], name=f"d{b}"))
    return tests


def test_a_family_fit_recovers_the_parameters_of_its_own_curves():
    """Two drained tests made by the model at φg = 27°, α0 = 52° (inside the domain); least
    squares from two starts over the domain's default bounds finds them again."""
    tests = _own_curves(Params(n_theta=36, phi_g=math.radians(27.0), alpha0=math.radians(52.0)), None)
    cal = fit(tests, ["phi_g", "alpha0"], base=Params(n_theta=36), solver=FamilyLike(), starts=2)
    assert dict(zip(cal.space.names, cal.space.bounds))["phi_g"] == pytest.approx((10.0, 45.0))
    assert cal.fitted["phi_g"] == pytest.approx(27.0, abs=0.05)
    assert cal.fitted["alpha0"] == pytest.approx(52.0, abs=0.05)


def test_the_3d_model_is_bounded_by_the_family_stepping_its_hexagons():
    """The 3D model's learned cell is a bi-hexagon whose hexagons the family network steps: its
    domain bounds the search as in 2D. Bounds reaching outside it are refused before any run,
    and the default bounds are the domain, so that a fit of kt_kn with them runs (the general
    range 0.05–2 used to take it outside the domain and stop the fit)."""
    from hmodel.cell.bihex import BiHexSolver
    from hmodel.loading import run_triaxial
    from hmodel.rev import Sphere

    assert training_domain(BiHexSolver(hexagon=FamilyLike())) == DOMAIN
    assert training_domain(BiHexSolver()) is None and training_domain(FamilyLike()) == DOMAIN
    sphere = Sphere(order=9, n_azimuth=2, axis=(1.0, 0.0, 0.0))
    base = Params(sliding_rhs="report")  # the family network's
    res = run_triaxial(base.with_(kt_kn=0.6), [1e5], 0.004, sphere=sphere, step=1e-3, iso_step=ISO_STEP)
    c, s = res.stage("consolidation"), res.stage("shear")
    test = Test("triaxial-drained", 1e5, np.asarray(s["eps11"]) - c["eps11"][-1], np.asarray(s["q"]),
                np.asarray(s["eps_v"]) - c["eps_v"][-1])
    solver = get_solver_3d("surrogate:family")
    lo, hi = solver.hexagon.domain["kt_kn"]
    kw = dict(base=base, solver=solver, sphere=sphere, search_rule=(9, 1), starts=1, max_nfev=3)
    with pytest.raises(InputError, match=r"--bounds kt_kn=0.05:2 reaches outside the model's training domain"):
        fit([test], ["kt_kn"], bounds={"kt_kn": (0.05, 2.0)}, **kw)
    cal = fit([test], ["kt_kn"], **kw)
    assert cal.space.bounds == ((lo, hi),) and not cal.failures
    assert lo < cal.fitted["kt_kn"] < hi
