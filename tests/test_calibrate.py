"""Calibration on curves made by hmodel itself at known parameters (identifiability), failures
counted instead of fatal, the batched model against single runs (these two for the 2D and the
3D model alike), and bad input; the 3D model's own cases are in test_calibrate3d.py."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from hmodel import InputError, Params, SolverError
from hmodel.calibrate import Space, Test, fit, parse_data_spec
from hmodel.calibrate.model import Model, residuals
from hmodel.cell import ClosedFormSolver
from hmodel.cli.app import main


@pytest.fixture(scope="module")
def case(own_tests):
    """The 2D model's biaxial tests made at known parameters (tests/conftest.py)."""
    return own_tests(2)


@pytest.fixture(scope="module")
def tests(case):
    return list(case.tests)


def test_noise_free_curves_give_back_their_parameters(tests, case):
    cal = fit(tests, ("phi_g", "alpha0"), base=case.base, starts=3, **case.kw)
    assert cal.fitted["phi_g"] == pytest.approx(28.0, rel=1e-4)
    assert cal.fitted["alpha0"] == pytest.approx(50.0, rel=1e-4)
    assert cal.cost < 1e-8 and not cal.failures and cal.unidentified == []
    assert cal.params.phi_g == pytest.approx(math.radians(28.0), rel=1e-4)  # radians inside
    assert cal.evaluations >= 3


def test_one_percent_noise_on_q_still_gives_phi_and_alpha0_within_two_percent(case):
    noisy = [case.test("drained", p0, noise=0.01, seed=k) for k, p0 in enumerate((1e5, 2e5, 4e5))]
    cal = fit(noisy, ("phi_g", "alpha0", "kt_kn"), base=case.base, starts=4, **case.kw)
    assert cal.fitted["phi_g"] == pytest.approx(28.0, rel=0.02)
    assert cal.fitted["alpha0"] == pytest.approx(50.0, rel=0.02)
    assert cal.fitted["kt_kn"] == pytest.approx(0.5, rel=0.10)
    # the standard errors reflect the noise: positive, and the truth within 4 of them
    for name, true in (("phi_g", 28.0), ("alpha0", 50.0), ("kt_kn", 0.5)):
        assert 0 < cal.stderr[name] and abs(cal.fitted[name] - true) < 4 * cal.stderr[name] + 1e-9


def test_starts_in_worker_processes_give_the_same_calibration(tests, case):
    """The least-squares starts are independent: run in two processes, every start ends where
    it ends in this one, with the same counts; and a bad number of workers is refused."""
    kw = dict(base=case.base.with_(kt_kn=0.4), starts=3, **case.kw)
    one = fit(tests, ("phi_g", "alpha0"), **kw)
    two = fit(tests, ("phi_g", "alpha0"), workers=2, **kw)
    assert [s["end"] for s in two.starts] == [s["end"] for s in one.starts]
    assert [s["evaluations"] for s in two.starts] == [s["evaluations"] for s in one.starts]
    assert two.evaluations == one.evaluations and two.cost == one.cost
    np.testing.assert_array_equal(two.z, one.z)
    with pytest.raises(InputError, match="workers"):
        fit(tests, ("phi_g",), workers=0, **kw)


def test_a_parameter_without_effect_is_flagged_unidentified(tests, case):
    # with an isotropic fabric (alpha_omega = 0) its major direction beta_omega changes nothing
    cal = fit(tests, ("phi_g", "beta_omega"), base=case.true.with_(phi_g=math.radians(30)), starts=1, **case.kw)
    assert cal.unidentified == ["beta_omega"] and cal.condition > 1e3
    assert cal.fitted["phi_g"] == pytest.approx(28.0, rel=1e-3)


def test_batched_predictions_equal_single_ones(dim, own_tests):
    case = own_tests(dim)
    tests = case.tests
    model = Model(tests, **case.kw)
    assert model.dim == dim
    sets = [case.true, case.true.with_(phi_g=math.radians(33)), case.true.with_(kn=3e8)]
    both = model.predict(sets)
    assert both.ok.all()
    for k, s in enumerate(sets):
        one = model.predict([s])
        for t in range(len(tests)):
            np.testing.assert_allclose(both.q[t][k], one.q[t][0], rtol=1e-9)
            np.testing.assert_allclose(both.eps_v[t][k], one.eps_v[t][0], rtol=1e-9, atol=1e-15)
    # the truth's own curves: zero residual (to the batched Newton's round-off), not another set's
    r = residuals(tests, both)
    assert np.abs(r[0]).max() < {2: 1e-8, 3: 1e-10}[dim] and np.abs(r[1]).max() > 1e-2
    # an undrained test's εv is not fitted (zero by definition), a drained one's is
    assert r.shape[1] == sum(len(t.eps11) for t in tests) + sum(len(t.eps11) for t in tests if not t.kind.undrained)
    # q 10 % high everywhere: 0.1 q / peak q / sqrt(n)
    t = tests[0]
    high = Test(t.kind, t.p0, t.eps11, t.q / 1.1, t.eps_v)
    r = residuals([high], Model((high,), **case.kw).predict([case.true]))[0, :len(t.q)]
    np.testing.assert_allclose(r, 0.1 * high.q / high.q_scale / math.sqrt(len(t.q)), rtol=1e-6,
                               atol=1e-9)


class FailsAboveThirtyFive(ClosedFormSolver):
    """The closed form, failing for friction angles above 35 deg (a stand-in for a run that
    leaves a surrogate's training domain); in 3D the hexagons' solver (the generic driver)."""

    name = "fails-above-35"

    def kernel(self, params):
        return None if params.phi_g > math.radians(35) else super().kernel(params)

    def step(self, params, state, dl1, dl2):
        if params.phi_g > math.radians(35):
            raise SolverError("outside the stand-in's domain")
        return super().step(params, state, dl1, dl2)


def test_failed_parameter_sets_are_counted_not_fatal(dim, own_tests):
    case = own_tests(dim)
    drained = case.tests[:2]
    model = Model(drained, FailsAboveThirtyFive(), **case.kw)
    pred = model.predict([case.true, case.true.with_(phi_g=math.radians(40)), case.true])
    assert pred.ok.tolist() == [True, False, True] and "domain" in pred.failed[1]
    assert np.isnan(pred.q[0][1]).all() and np.isfinite(pred.q[0][[0, 2]]).all()
    # 3D: the search at a coarser rule (one azimuth), then the tests' own
    search = {2: dict(starts=3), 3: dict(starts=2, search_rule=(9, 1))}[dim]
    cal = fit(drained, ("phi_g",), bounds={"phi_g": (20.0, 45.0)}, base=case.true.with_(phi_g=0.5),
              solver=FailsAboveThirtyFive(), **search, **case.kw)
    assert cal.fitted["phi_g"] == pytest.approx(28.0, rel={2: 1e-3, 3: 1e-5}[dim])
    assert cal.failures and all(f["params"]["phi_g"] > 35 for f in cal.failures)


def test_bad_input_is_refused_in_one_line(tmp_path):
    e = np.linspace(0.001, 0.01, 5)
    with pytest.raises(InputError, match="increasing"):
        Test("drained", 1e5, e[::-1], np.ones(5))
    with pytest.raises(InputError, match="non-finite"):
        Test("drained", 1e5, e, np.array([1.0, np.nan, 1, 1, 1]))
    with pytest.raises(InputError, match="drained or undrained"):
        Test("cyclic", 1e5, e, np.ones(5))
    with pytest.raises(InputError, match="cannot fit 'n_theta'"):
        Space.make(["n_theta"])
    with pytest.raises(InputError, match="low < high"):
        Space.make(["phi_g"], {"phi_g": (40.0, 20.0)})
    with pytest.raises(InputError, match="valid range"):
        Space.make(["alpha0"], {"alpha0": (20.0, 60.0)})
    with pytest.raises(InputError, match="not fitted"):
        Space.make(["phi_g"], {"kn": (1e7, 1e9)})
    with pytest.raises(InputError, match="KIND:P0:FILE"):
        parse_data_spec("drained:d100.csv")
    bad = tmp_path / "bad.csv"
    bad.write_text("eps11,sig\n0.001,1\n0.002,2\n")
    with pytest.raises(InputError, match="missing column"):
        parse_data_spec(f"drained:100kPa:{bad}")


def test_space_maps_the_unit_box_onto_the_bounds_and_back():
    s = Space.make(["kn", "phi_g"], {"kn": (1e6, 1e10), "phi_g": (10.0, 50.0)})
    v = s.values(np.array([[0.0, 0.0], [0.5, 0.25], [1.0, 1.0]]))
    np.testing.assert_allclose(v, [[1e6, 10.0], [1e8, 20.0], [1e10, 50.0]])  # kn on a log scale
    np.testing.assert_allclose(s.unit(v), [[0.0, 0.0], [0.5, 0.25], [1.0, 1.0]], atol=1e-12)


def test_cli_writes_the_calibration_and_refuses_bad_input(tmp_path, tests, capsys):
    files = []
    for t in tests:
        f = tmp_path / f"d{int(t.p0 / 1e3)}.csv"
        f.write_text("eps11,q,eps_v\n" + "".join(f"{float(a)!r},{float(b)!r},{float(c)!r}\n"
                                                  for a, b, c in zip(t.eps11, t.q, t.eps_v)))
        files.append(f"drained:{t.p0 / 1e3:g}kPa:{f}")
    out = tmp_path / "cal"
    args = ["calibrate", *sum((["--data", f] for f in files), []), "--fit", "phi_g,alpha0",
            "-p", "n_theta=36", "-p", "sliding_rhs=equilibrium", "--starts", "2", "--out", str(out)]
    assert main(args) == 0
    record = json.loads((out / "calibration.json").read_text())
    assert record["fitted"]["phi_g"] == pytest.approx(28.0, rel=1e-3)
    assert record["params"]["alpha0"] == pytest.approx(50.0, rel=1e-3)  # all parameters, degrees
    assert record["params"]["n_theta"] == 36 and record["fit"] == ["phi_g", "alpha0"]
    assert (out / "fit.png").stat().st_size > 1000 and (out / "fit.csv").read_text().count("\n") > 10
    capsys.readouterr()
    bad = tmp_path / "bad"
    assert main([*args[:-2], "--fit", "phi_g,n_theta", "--out", str(bad)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("hmodel: error:") and "n_theta" in err and "\n" not in err and not bad.exists()


def test_bayes_90_percent_intervals_contain_the_truth(tmp_path, case):
    # 1 % noise on q, 2e-5 on εv: the likelihood's noise is the one the best fit leaves
    noisy = [case.test("drained", p0, noise=0.01, noise_ev=2e-5, seed=k) for k, p0 in enumerate((1e5, 3e5))]
    cal = fit(noisy, ("phi_g", "alpha0"), base=case.base, method="bayes", starts=4, walkers=8, steps=300,
              seed=1, **case.kw)
    post = cal.posterior
    assert 0.01 / 3 < post.noise.q < 0.03 and 2e-5 / 3 < post.noise.eps_v < 6e-5  # about the noise added
    for name, true in (("phi_g", 28.0), ("alpha0", 50.0)):
        s = post.summary[name]
        assert s["q05"] < true < s["q95"] and s["sd"] > 0
    assert 0.1 < post.acceptance < 0.9 and post.samples.shape[1] == 2
    assert post.warning  # 300 steps are fewer than 50 autocorrelation times: said so
    (q_lo, q_hi), _ = cal.band[0]
    best = cal.prediction.q[0][0]  # the least-squares curve lies mostly inside the 90 % band
    assert np.all(q_lo < q_hi) and np.mean((q_lo <= best) & (best <= q_hi)) >= 0.5
    from hmodel.calibrate.report import write
    written = {p.name for p in write(cal, tmp_path / "b")}
    assert {"posterior.csv", "corner.png", "trace.png", "calibration.json"} <= written
    record = json.loads((tmp_path / "b" / "calibration.json").read_text())
    assert set(record["posterior"]) == {"phi_g", "alpha0"} and record["method"] == "bayes"


def test_the_standard_error_of_kn_survives_its_scale(case):
    # kn in N/m is 10^8 times the angles: its standard error must come out in its own units,
    # about its relative sensitivity times kn, not lost to round-off
    noisy = [case.test("drained", p0, noise=0.01, seed=k) for k, p0 in enumerate((1e5, 3e5))]
    cal = fit(noisy, ("kn", "phi_g"), base=case.true, starts=2, **case.kw)
    assert 1e-4 * case.true.kn < cal.stderr["kn"] < 0.5 * case.true.kn
    assert abs(cal.fitted["kn"] - case.true.kn) < 4 * cal.stderr["kn"]


def test_the_uncertainty_of_a_parameter_the_objective_ignores_is_undefined():
    """Standard errors from a Jacobian of known answer: residuals r = (1, -1) and J = (1, 1)ᵀ in
    the unit box give s² = 2, a unit-box variance of 1 and, over φg's range 5–60°, an error of
    55°. A column of zeros (a parameter the objective does not depend on) is unidentified and
    its error undefined (NaN), alone too, where every singular value is 0."""
    from hmodel.calibrate.fitting import _uncertainty

    one = Space.make(["phi_g"])
    se, _, cond, weak = _uncertainty(one, np.array([0.5]), np.array([1.0, -1.0]), np.ones((2, 1)), 2)
    assert se["phi_g"] == pytest.approx(55.0) and cond == 1.0 and weak == []
    se, _, cond, weak = _uncertainty(one, np.array([0.5]), np.array([1.0, -1.0]), np.zeros((2, 1)), 2)
    assert weak == ["phi_g"] and math.isnan(se["phi_g"]) and cond == math.inf
    two = Space.make(["phi_g", "beta_omega"])
    J = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 0.0]])
    se, _, _, weak = _uncertainty(two, np.array([0.5, 0.5]), np.array([1.0, -1.0, 0.0]), J, 3)
    assert weak == ["beta_omega"] and math.isnan(se["beta_omega"]) and se["phi_g"] == pytest.approx(55.0)


def test_a_lone_parameter_without_effect_is_unidentified_not_exact(tests, case):
    # an isotropic fabric: its major direction changes nothing, and it is the only one fitted
    cal = fit(tests, ("beta_omega",), base=case.true, starts=1, **case.kw)
    assert cal.unidentified == ["beta_omega"] and math.isnan(cal.stderr["beta_omega"])
    record = cal.to_dict()
    assert record["stderr"] == {"beta_omega": None} and record["unidentified"] == ["beta_omega"]


def test_a_value_on_its_bound_is_flagged():
    s = Space.make(["kt_kn", "phi_g", "kn"])
    z = s.unit(np.array([1.977, 30.0, 1.1e6]))  # 1.2 % of kt_kn's range below 2, 0.8 % of kn's decades
    assert s.at_bound(z) == {"kt_kn": "upper", "kn": "lower"}
    assert s.at_bound(s.unit(np.array([1.9, 58.0, 1e10]))) == {}  # 5 %, 3.6 %, 20 % away
    assert s.bound("kt_kn", "upper") == 2.0 and s.bound("kn", "lower") == 1e6


def test_a_fit_that_ends_on_a_bound_says_so(tmp_path, tests, capsys):
    """φg is 28° in the tests and searched within 30–40°: it ends at 30, which the summary,
    a warning and calibration.json say; the fit inside the bounds says nothing of the kind."""
    files = []
    for t in tests:
        f = tmp_path / f"d{int(t.p0 / 1e3)}.csv"
        f.write_text("eps11,q,eps_v\n" + "".join(f"{float(a)!r},{float(b)!r},{float(c)!r}\n"
                                                  for a, b, c in zip(t.eps11, t.q, t.eps_v)))
        files += ["--data", f"drained:{t.p0 / 1e3:g}kPa:{f}"]
    args = ["calibrate", *files, "--fit", "phi_g", "-p", "n_theta=36", "-p", "sliding_rhs=equilibrium",
            "-p", "alpha0=50", "-p", "kt_kn=0.5", "--starts", "1"]
    assert main([*args, "--bounds", "phi_g=30:40", "--out", str(tmp_path / "a")]) == 0
    out, err = capsys.readouterr()
    assert "phi_g = 30 ± " in out and "(at its lower bound 30)" in out
    assert err.startswith("hmodel: warning: phi_g ended at its lower bound 30: the best fit may lie beyond it")
    record = json.loads((tmp_path / "a" / "calibration.json").read_text())
    assert record["at_bound"] == {"phi_g": {"side": "lower", "bound": 30.0}}
    assert main([*args, "--bounds", "phi_g=20:40", "--out", str(tmp_path / "b")]) == 0
    out, err = capsys.readouterr()
    assert "bound" not in out and err == ""
    assert json.loads((tmp_path / "b" / "calibration.json").read_text())["at_bound"] == {}


def test_the_most_common_failure_reasons_are_printed(tmp_path, tests, capsys, monkeypatch, case):
    import dataclasses

    import hmodel.cli.calibrate as cli_cal

    monkeypatch.setattr(cli_cal, "get_solver", lambda spec: FailsAboveThirtyFive())
    t = tests[0]
    f = tmp_path / "d.csv"
    f.write_text("eps11,q\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(t.eps11, t.q)))
    assert main(["calibrate", "--data", f"drained:100kPa:{f}", "--fit", "phi_g", "--bounds", "phi_g=20:45",
                 "-p", "n_theta=36", "-p", "sliding_rhs=equilibrium", "-p", "alpha0=50", "-p", "kt_kn=0.5",
                 "--starts", "3", "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    failed = json.loads((tmp_path / "o" / "calibration.json").read_text())["failures"]
    assert failed and f"failed, most often: {len(failed)} × outside the stand-in's domain" in out
    # messages that differ only in the values they name are one reason
    cal = fit(tests, ("phi_g",), base=case.true, starts=1, **case.kw)
    cal = dataclasses.replace(cal, failures=[{"error": "kt_kn=1.47 outside the domain"},
                                             {"error": "Newton failed"},
                                             {"error": "kt_kn=1.9 outside the domain"}])
    assert cal.failure_reasons() == [(2, "kt_kn=1.47 outside the domain"), (1, "Newton failed")]


def test_strains_in_percent_stresses_in_kpa_and_a_p0_without_unit_are_refused(tmp_path):
    e = np.linspace(0.01, 0.96, 96)  # a test to 0.96 % written in percent
    with pytest.raises(InputError, match=r"eps11 reaches 0.96, .* looks like a percentage .* divide the strain"):
        Test("drained", 1e5, e, 1e5 * e)
    Test("drained", 1e5, 0.49 * e / e[-1], 1e5 * e)  # 49 %: large, but a strain
    with pytest.raises(InputError, match=r"q peaks at 96 Pa, 0.00096 of p0 = 100 kPa: that looks like kPa"):
        Test("drained", 1e5, e / 100, 100 * e)
    Test("drained", 1e5, e / 100, 1.1e3 * e)  # q a hundredth of p0
    f = tmp_path / "t.csv"
    f.write_text("eps11,q\n" + "".join(f"{float(a)!r},{2e5 * float(a)!r}\n" for a in e / 100))
    for bare in ("100", "1e3", "9999"):
        with pytest.raises(InputError, match=f"p0 {bare} has no unit and would be .* Pa: give its unit"):
            parse_data_spec(f"drained:{bare}:{f}")
    assert parse_data_spec(f"drained:10000:{f}").p0 == 1e4  # Pa, as documented
    assert parse_data_spec(f"drained:100Pa:{f}").p0 == 100.0  # the unit said: as asked
