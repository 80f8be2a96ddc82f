"""The trust score of learned cells and the uncertainty gate."""

import math
from dataclasses import replace

import numpy as np
import pytest

from hmodel import InputError, Params
from hmodel.cell import ClosedFormSolver
from hmodel.cli.app import main
from hmodel.loading import run_biaxial
from hmodel.surrogate import modelfile
from hmodel.surrogate.shipped import load_shipped
from hmodel.surrogate.solver import SurrogateSolver, gated_solver
from hmodel.surrogate.gate import DistanceGate, scores, threshold
from hmodel.surrogate.trust import LEVELS, TOP, ranking

SMALL = Params(n_theta=36)


def test_ranking_of_a_perfect_a_random_and_a_reversed_score():
    rng = np.random.default_rng(0)
    error = rng.lognormal(0.0, 1.5, 200_000)
    e2 = np.sort(error ** 2)[::-1]
    perfect = ranking(error, error)
    for r in perfect:  # the top rows by score are the top rows by error
        n = r["rows"]
        assert r["share_of_squared_error"] == pytest.approx(e2[:n].sum() / e2.sum(), rel=1e-12)
        assert r["spearman"] == pytest.approx(1.0)
    for r in ranking(rng.uniform(size=error.size), error):  # no information: shares ~ f
        assert r["share_of_error"] == pytest.approx(r["top_fraction"], rel=0.25, abs=2e-3)
    assert all(r["share_of_error"] < r["top_fraction"] for r in ranking(-error, error))


def _with_reference(model, ref, level_scores):
    """The model with a given trust reference (normalized inputs) and held-out quantiles."""
    meta = {**model.meta, "trust": {"k": 1, "quantiles": {"levels": LEVELS.tolist(),
                                                          "scores": level_scores}}}
    return replace(model, meta=meta, trust_reference=np.asarray(ref, float))


def test_the_score_is_the_distance_to_the_nearest_reference_rows(tmp_path):
    model = load_shipped()
    n_in = len(model.x_scaler.offset)
    ref = np.zeros((3, n_in))
    ref[1, 0], ref[2, 1] = 1.0, 2.0
    m = _with_reference(model, ref, np.linspace(0, 1, len(LEVELS)).tolist())
    # inputs whose normalized form is (0.5, 0, ...) and (0, 0, 3, ...): distances 0.5 and 3
    z = np.zeros((2, n_in))
    z[0, 0], z[1, 2] = 0.5, 3.0
    X = model.x_scaler.inverse(z)
    np.testing.assert_allclose(m.x_scaler.transform(X), z, atol=1e-12)
    np.testing.assert_allclose(scores(m, X), [0.5, 3.0], rtol=1e-12)
    assert threshold(m, 0.5) == pytest.approx(np.interp(0.5, LEVELS, np.linspace(0, 1, len(LEVELS))))
    path = modelfile.save(m, tmp_path / "t.safetensors")
    back = modelfile.load(path)
    np.testing.assert_array_equal(back.trust_reference, ref)
    np.testing.assert_allclose(scores(back, X), [0.5, 3.0], rtol=1e-12)


def _gated(level_scores):
    """The shipped model gated at 0.99 with a reference far from every cell (every score is
    about 1e3) and the given held-out quantiles."""
    model = load_shipped()
    far = np.full((4, len(model.x_scaler.offset)), 1e3)
    return SurrogateSolver(_with_reference(model, far, level_scores), gate=0.99,
                           fallback=ClosedFormSolver())


def test_a_gate_that_holds_every_cell_gives_the_closed_form_and_says_so():
    exact = run_biaxial(SMALL, [2e5], 0.01)
    gated = run_biaxial(SMALL, [2e5], 0.01, solver=_gated([0.0] * len(LEVELS)))
    np.testing.assert_allclose(gated["q"], exact["q"], rtol=1e-6, atol=1e-3)
    assert np.all(gated["gated"] == 1.0)


def test_a_gate_that_holds_no_cell_changes_nothing():
    solver = _gated([1e9] * len(LEVELS))
    # a gated solver runs in the generic driver: the ungated one too, to compare like with like
    plain = run_biaxial(SMALL, [2e5], 0.01, solver=SurrogateSolver(load_shipped()), compiled=False)
    gated = run_biaxial(SMALL, [2e5], 0.01, solver=solver)
    np.testing.assert_array_equal(gated["q"], plain["q"])
    assert np.all(gated["gated"] == 0.0) and solver.counts["gated"] == 0
    assert isinstance(solver.gate, DistanceGate) and not solver.gate.per_increment
    assert solver.gate.summary() == f"gate 0.99: 0 of {solver.counts['gate_checked']:,} cell states (0 %)"
    assert solver.counts["gate_checked"] > 0 and "gated" not in plain.columns


def test_gate_input_errors(tmp_path, capsys):
    with pytest.raises(InputError, match="needs a fallback"):
        gated_solver("surrogate", 0.99, None)
    with pytest.raises(InputError, match="needs a gate"):
        gated_solver("surrogate", None, "closed-form")
    with pytest.raises(InputError, match="learned cell solvers"):
        gated_solver("closed-form", 0.99, "closed-form")
    plain = load_shipped()
    plain = replace(plain, trust_reference=None, meta={k: v for k, v in plain.meta.items() if k != "trust"})
    untrusted = modelfile.save(plain, tmp_path / "untrusted.safetensors")
    with pytest.raises(InputError, match="no trust reference"):
        gated_solver(f"surrogate:{untrusted}", 0.99, "closed-form")
    with pytest.raises(InputError, match="quantile level"):
        SurrogateSolver(load_shipped(), gate=1.5, fallback=ClosedFormSolver())
    with pytest.raises(InputError, match="compliance"):
        gated_solver("surrogate:increment", 0.99, "closed-form")
    assert main(["compare", "--gate", "0.99", "--paths", "drained", "--out", str(tmp_path / "c")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "fallback" in err and not (tmp_path / "c").exists()


def test_top_fractions_are_the_documented_ones():
    assert TOP == (0.001, 0.01, 0.05, 0.1) and math.isclose(LEVELS[-1], 1.0)


def test_the_command_line_gate_reports_its_fraction(tmp_path, capsys):
    model = load_shipped()
    far = np.full((4, len(model.x_scaler.offset)), 1e3)
    path = modelfile.save(_with_reference(model, far, [0.0] * len(LEVELS)), tmp_path / "far.safetensors")
    assert main(["run", "biaxial", "--axial-strain", "0.005", "-p", "n_theta=18", "--solver",
                 f"surrogate:{path}", "--gate", "0.99", "--fallback", "closed-form",
                 "--out", str(tmp_path / "r")]) == 0
    assert "(100 %) solved by closed-form" in capsys.readouterr().out
    header = (tmp_path / "r" / "result.csv").read_text().splitlines()[0].split(",")
    assert header[-1] == "gated"
