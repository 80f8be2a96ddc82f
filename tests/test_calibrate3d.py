"""Calibration of the 3D H-model on triaxial tests: triaxial tests made by the 3D model at known
parameters are recovered (the truth is the parameter set they were made with), extension is
compression positive, and the 2D model's kinds, files and options are refused with the 3D
model's and the reverse, in one line. What the 2D and the 3D model share (the batched model
equals single runs, the objective vanishes at the truth, a parameter set whose test fails does
not stop the fit) is tested for both in test_calibrate.py."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hmodel import InputError
from hmodel.calibrate import Test, fit, parse_data_spec
from hmodel.calibrate.model import Model, residuals
from hmodel.cell.bihex import BiHexSolver
from hmodel.cli.app import main

#: the search runs at a coarser rule than the tests' (order 9, two azimuths), then refines there
SEARCH = (9, 1)
BOUNDS = {"phi_g": (20.0, 40.0), "alpha0": (40.0, 60.0)}


@pytest.fixture(scope="module")
def case(own_tests):
    """The 3D model's triaxial tests made at known parameters (tests/conftest.py)."""
    return own_tests(3)


@pytest.fixture(scope="module")
def tests(case):
    return list(case.tests)


def test_an_extension_test_is_compression_positive(tests):
    ext = tests[3]
    assert ext.eps11[-1] < 0 and ext.q[-1] < 0 and ext.strain[-1] > 0


def test_noise_free_triaxial_tests_give_back_their_parameters(tests, case):
    cal = fit(tests, ("phi_g", "alpha0"), bounds=BOUNDS, base=case.base, starts=2, search_rule=SEARCH, **case.kw)
    assert cal.fitted["phi_g"] == pytest.approx(28.0, rel=1e-5)
    assert cal.fitted["alpha0"] == pytest.approx(50.0, rel=1e-5)
    assert cal.cost < 1e-10 and not cal.failures and cal.unidentified == []
    # the coarser search's optimum is not the truth (another rule, another model); the
    # refinement at the tests' rule is
    refined = cal.search["refined"]
    assert (cal.search["order"], cal.search["n_azimuth"]) == SEARCH
    assert refined["search_objective"] > 1e3 * refined["objective"]
    record = cal.to_dict()
    assert record["sphere"]["order"] == 9 and record["sphere"]["n_azimuth"] == 2
    assert [t["kind"] for t in record["tests"]][-1] == "triaxial-extension"


def test_one_percent_noise_gives_phi_and_alpha0_within_two_percent(case):
    # 1 % of q and 2e-5 of εv: the fitted values' standard errors are a few tenths of a
    # percent; 2 % is 2D's tolerance and the truth must also lie within 4 standard errors
    noisy = [case.test(k, p0, noise=0.01, noise_ev=2e-5, seed=i) for i, (k, p0) in
             enumerate((("triaxial-drained", 1e5), ("triaxial-drained", 3e5), ("triaxial-extension", 2e5)))]
    cal = fit(noisy, ("phi_g", "alpha0"), bounds=BOUNDS, base=case.base, starts=2, search_rule=None, **case.kw)
    assert cal.search is None
    for name, true in (("phi_g", 28.0), ("alpha0", 50.0)):
        assert cal.fitted[name] == pytest.approx(true, rel=0.02)
        assert 0 < cal.stderr[name] and abs(cal.fitted[name] - true) < 4 * cal.stderr[name]


def _csv(path, header, rows):
    path.write_text(",".join(header) + "\n" + "".join(",".join(repr(float(x)) for x in r) + "\n" for r in rows))
    return path


def test_the_2d_model_and_the_3d_model_are_not_mixed(tmp_path, tests, case):
    e = np.linspace(0.001, 0.01, 5)
    biaxial = Test("drained", 1e5, e, np.linspace(1e4, 5e4, 5), e)
    with pytest.raises(InputError, match="mix the 2D model's kinds .drained. with the 3D"):
        fit([biaxial, tests[0]], ("phi_g",))
    with pytest.raises(InputError, match="3D model's: the tests are 2D"):
        fit([biaxial], ("phi_g",), sphere=case.kw["sphere"])
    with pytest.raises(InputError, match="is a 3D cell: the tests are 2D"):
        Model((biaxial,), BiHexSolver())
    with pytest.raises(InputError, match="alpha_omega is the 2D model's"):
        fit(tests, ("phi_g", "alpha_omega"), **case.kw)
    # the files: 3D columns with a 2D kind, 2D columns with a 3D kind
    three = _csv(tmp_path / "t.csv", ["eps_a", "q", "eps_v", "s33"], [(a, 1e4, 0, 1e5) for a in e])
    two = _csv(tmp_path / "b.csv", ["eps11", "eps22", "q"], [(a, -a, 1e4) for a in e])
    with pytest.raises(InputError, match="2D model's biaxial test but the file has 3D column.s. eps_a, s33"):
        parse_data_spec(f"drained:100kPa:{three}")
    with pytest.raises(InputError, match="3D model's triaxial test but the file has 2D column.s. eps22"):
        parse_data_spec(f"triaxial-drained:100kPa:{two}")
    assert parse_data_spec(f"triaxial-drained:100kPa:{three}").eps11.tolist() == e.tolist()
    # the signs: extension is eps11 < 0; a tension-positive compression test is named as such
    with pytest.raises(InputError, match="non-positive and decreasing"):
        Test("triaxial-extension", 1e5, e, -np.ones(5))
    with pytest.raises(InputError, match="compression positive .* tension positive"):
        Test("triaxial-drained", 1e5, -e, -np.ones(5))
    with pytest.raises(InputError, match="drained or undrained .2D. or triaxial-drained"):
        parse_data_spec(f"triaxial:100kPa:{three}")


def test_cli_writes_a_3d_calibration_and_refuses_the_other_model_in_one_line(tmp_path, tests, capsys):
    specs = []
    for k, t in enumerate(tests[:2] + tests[3:]):
        f = _csv(tmp_path / f"t{k}.csv", ["eps_a", "q", "eps_v"], zip(t.eps11, t.q, t.eps_v))
        specs += ["--data", f"{t.kind}:{t.p0 / 1e3:g}kPa:{f}"]
    out = tmp_path / "cal"
    args = ["calibrate", *specs, "--fit", "phi_g,alpha0", "--bounds", "phi_g=20:40", "--bounds",
            "alpha0=40:60", "--order", "9", "--azimuths", "2", "--search-rule", "9:1", "--starts", "1"]
    # the Bayesian method too (a short chain: that it runs in 3D, not its statistics)
    assert main([*args, "--method", "bayes", "--walkers", "4", "--steps", "12", "--check", "closed-form",
                 "--out", str(out)]) == 0
    record = json.loads((out / "calibration.json").read_text())
    # the check runs the calibration's own directions: the same solver gives the same curves
    assert [t["max_dq"] for t in record["check"]["tests"].values()] == [0.0, 0.0, 0.0]
    assert record["fitted"]["phi_g"] == pytest.approx(28.0, rel=1e-4)
    assert set(record["posterior"]) == {"phi_g", "alpha0"} and (out / "posterior.csv").exists()
    assert record["params"]["sliding_rhs"] == "equilibrium"  # the 3D commands' default
    assert record["sphere"]["order"] == 9 and record["search"]["n_azimuth"] == 1
    assert (out / "fit.png").stat().st_size > 1000
    assert "triaxial-extension" in (out / "fit.csv").read_text()
    capsys.readouterr()
    b = tmp_path / "b.csv"
    _csv(b, ["eps11", "q", "eps_v"], [(a, 1e4 * a, 0.0) for a in np.linspace(0.001, 0.01, 5)])
    for bad_args in ([*args, "-p", "n_theta=36"],                              # a 2D parameter
                     ["calibrate", "--data", f"drained:100kPa:{b}", "--order", "9"],   # a 3D option
                     ["calibrate", *specs[:2], "--data", f"drained:100kPa:{b}"]):      # both models
        bad = tmp_path / "bad"
        assert main([*bad_args, "--out", str(bad)]) == 1
        err = capsys.readouterr().err.strip()
        assert err.startswith("hmodel: error:") and "\n" not in err and not bad.exists()
