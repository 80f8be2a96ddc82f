"""A calibrated cell model checked at its optimum against another cell solver (``--check``)."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from test_calibrate_family import _own_curves  # closed-form curves as measured tests

from hmodel import Params
from hmodel.calibrate import fit
from hmodel.calibrate.check import check_at, deviation
from hmodel.calibrate.model import Model
from hmodel.cell import ClosedFormSolver
from hmodel.cli.app import main
from hmodel.errors import SolverError

TRUTH = Params(n_theta=36, phi_g=math.radians(27.0), alpha0=math.radians(52.0))


def test_deviation_of_hand_made_curves():
    q_ref = np.array([0.0, 50.0, 100.0, -120.0])  # peak |q| 120
    q = q_ref + np.array([0.0, 6.0, -12.0, 0.0])
    ev_ref = np.array([0.0, 1e-3, 2e-3, 3e-3])
    ev = ev_ref + np.array([0.0, 0.0, -5e-4, 2e-4])
    d = deviation(q, ev, q_ref, ev_ref)
    assert d["max_dq"] == pytest.approx(12.0 / 120.0)
    assert d["rms_dq"] == pytest.approx(math.sqrt((36.0 + 144.0) / 4) / 120.0)
    assert d["max_deps_v"] == pytest.approx(5e-4)
    assert deviation(q_ref, ev_ref, q_ref, ev_ref) == {"max_dq": 0.0, "rms_dq": 0.0, "max_deps_v": 0.0}


def _write_tests(folder) -> list[str]:
    """Drained tests at 100 and 400 kPa to 2 % made by the closed form at TRUTH, as CLI data."""
    specs = []
    for t in _own_curves(TRUTH, None):
        path = folder / f"{t.name}.csv"
        np.savetxt(path, np.c_[t.eps11, t.q, t.eps_v], delimiter=",", header="eps11,q,eps_v", comments="")
        specs += ["--data", f"drained:{t.p0:g}:{path}"]
    return specs


def test_a_solver_checked_against_itself_has_no_deviation(tmp_path):
    from hmodel.calibrate.data import parse_data_spec

    specs = _write_tests(tmp_path)
    tests = [parse_data_spec(s) for s in specs[1::2]]
    cal = fit(tests, ["phi_g"], base=TRUTH, starts=1)
    chk = check_at(cal.tests, cal.params, cal.prediction, ClosedFormSolver())
    assert not chk.failed and [d["max_dq"] for d in chk.deviations] == [0.0, 0.0]


def test_a_different_solver_is_measured_where_its_curves_differ(tmp_path):
    """The check solver at other parameters than the calibrated model's: the deviation is the
    distance between two closed-form runs computed here independently."""
    from hmodel.calibrate.data import parse_data_spec

    tests = [parse_data_spec(s) for s in _write_tests(tmp_path)[1::2]]
    other = TRUTH.with_(phi_g=math.radians(30.0))
    mine = Model(tuple(tests)).predict([other])  # the "calibrated model": φg 30°
    chk = check_at(tests, TRUTH, mine, ClosedFormSolver())  # the check: φg 27°
    truth = Model(tuple(tests)).predict([TRUTH])
    for k in range(2):
        expect = np.abs(mine.q[k][0] - truth.q[k][0]).max() / np.abs(truth.q[k][0]).max()
        assert chk.deviations[k]["max_dq"] == pytest.approx(expect, rel=1e-12) and expect > 0.02


class Refusing(ClosedFormSolver):
    """A cell solver that refuses every increment, as a DEM cell does that does not converge."""

    name = "refusing"

    def kernel(self, params):
        return None  # the generic driver, which calls step

    def step(self, *args, **kwargs):
        raise SolverError("refused on purpose")


def test_a_check_solver_that_fails_is_recorded_not_fatal(tmp_path):
    from hmodel.calibrate.data import parse_data_spec

    tests = [parse_data_spec(s) for s in _write_tests(tmp_path)[1::2]]
    mine = Model(tuple(tests)).predict([TRUTH])
    chk = check_at(tests, TRUTH, mine, Refusing())
    assert "refused on purpose" in chk.failed and chk.to_dict()["failed"] == chk.failed


def test_the_cli_checks_a_surrogate_fit_against_the_cell_it_learned(tmp_path, capsys):
    """The shipped family network of the standard cell, calibrated on closed-form curves and
    checked against the closed form: a small nonzero miss, check.csv consistent with the record,
    and the warning once the tolerance is below it."""
    specs = _write_tests(tmp_path)
    base = [*specs, "--solver", "surrogate:family", "--fit", "phi_g,alpha0", "-p", "n_theta=36",
            "--starts", "2", "--check", "closed-form"]
    assert main(["calibrate", *base, "--out", str(tmp_path / "a")]) == 0
    out, err = capsys.readouterr()
    rec = json.loads((tmp_path / "a" / "calibration.json").read_text())["check"]
    worst = max(t["max_dq"] for t in rec["tests"].values())
    assert rec["solver"] == "closed-form" and 0 < worst < 0.02
    assert "check at the optimum against closed-form" in out and "warning" not in out + err
    with open(tmp_path / "a" / "check.csv") as fh:
        rows = list(csv.DictReader(fh))
    for name, t in rec["tests"].items():
        qm = np.array([float(r["q_model"]) for r in rows if r["test"] == name])
        qc = np.array([float(r["q_check"]) for r in rows if r["test"] == name])
        assert np.abs(qm - qc).max() / np.abs(qc).max() == pytest.approx(t["max_dq"], rel=1e-9)
    assert main(["calibrate", *base, "--check-tol", "0", "--out", str(tmp_path / "b")]) == 0
    assert "hmodel: warning: that is more than --check-tol 0 %" in capsys.readouterr().err


def test_the_cli_refuses_a_bad_check_before_fitting(tmp_path, capsys):
    specs = _write_tests(tmp_path)
    for extra, word in ((["--check", "no-such-solver"], "no-such-solver"),
                        (["--check-tol", "0.02"], "--check-tol applies to --check"),
                        (["--check", "closed-form", "--check-tol", "-1"], "--check-tol must be")):
        out = tmp_path / "o"
        code = main(["calibrate", *specs, "--fit", "phi_g", "--out", str(out), *extra])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 1 and not out.exists() and len(err) == 1 and word in err[0], err
