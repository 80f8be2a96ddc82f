"""Macro comparison of cell solvers and the reproduce report (small sizes)."""

import numpy as np
import pytest

from hmodel import Params
from hmodel.cli.app import main
from hmodel.compare import deviations, run_path, standard_paths
from hmodel.surrogate.shipped import load_shipped
from hmodel.surrogate.solver import SurrogateSolver

SMALL = Params(n_theta=36)


def test_a_solver_against_itself_deviates_by_zero():
    for spec in standard_paths(0.01):
        a, _ = run_path(SMALL, spec, "closed-form", 1e-3, 1e-4)
        b, _ = run_path(SMALL, spec, "closed-form", 1e-3, 1e-4)
        for d in deviations(a, b):
            assert d["q_max_dev_rel"] == 0 and d["eps_v_max_dev"] == 0 and d["rows"] == len(a.point(d["point"]))


def test_paths_do_what_they_say():
    specs = {s.name: s for s in standard_paths(0.02)}
    r, _ = run_path(SMALL, specs["oedometric"], "closed-form", 1e-3, 1e-4)
    sh = r.stage("shear")
    np.testing.assert_allclose(sh["eps22"], sh["eps22"][0], atol=1e-15)
    r, _ = run_path(SMALL, specs["unload-reload"], "closed-form", 1e-3, 1e-4)
    e = r.stage("shear")["eps11"]
    assert np.any(np.diff(e) < 0) and e[-1] > e.max() - 1e-12  # unloads, then reloads past it
    r, _ = run_path(SMALL, specs["rotation"], "closed-form", 1e-3, 1e-4)
    assert np.abs(r["eps12"]).max() > 0.009 and np.abs(r["sig12"]).max() > 0


def test_a_failed_run_keeps_its_rows_up_to_the_failure():
    """run_path's SolverError carries the rows recorded before it (``partial``): the same rows
    as a run of the same solver that does not fail, up to the failure."""
    from hmodel.cell.closed_form import ClosedFormSolver
    from hmodel.errors import SolverError

    class FailsLater:  # the closed form through the generic driver, failing after `limit` calls
        name, calls, limit = "fails-later", 0, float("inf")

        def step(self, params, state, dl1, dl2):
            self.calls += 1
            if self.calls > self.limit:
                raise SolverError("stopped on purpose")
            return ClosedFormSolver().step(params, state, dl1, dl2)

    spec = {s.name: s for s in standard_paths(0.02)}["undrained"]
    counted = FailsLater()
    full, _ = run_path(SMALL, spec, counted, 1e-3, 1e-4)
    failing = FailsLater()
    failing.limit = counted.calls // 2
    with pytest.raises(SolverError, match="on purpose") as err:
        run_path(SMALL, spec, failing, 1e-3, 1e-4)
    part = err.value.partial
    assert 0 < len(part) < len(full)
    np.testing.assert_allclose(part["q"], full["q"][:len(part)], rtol=1e-9, atol=1e-6)


@pytest.mark.parametrize("paths", [("drained", "undrained"), ("unload-reload", "rotation")])
def test_shipped_surrogate_in_the_rev_reproduces_the_closed_form(paths):
    # Issue target: |Δq| ≤ 1 % of peak q and |Δεv| ≤ 0.1 % strain; no closed-form fallback.
    from hmodel.compare import compare_path
    solver = SurrogateSolver(load_shipped(), on_outside="error")
    for spec in (s for s in standard_paths(0.02) if s.name in paths):
        _, res, devs, st = compare_path(SMALL, spec, solver, 1e-3, 1e-4)
        assert st["status"] == "ok"
        for d in devs:
            assert d["q_max_dev_rel"] <= 0.01 and d["eps_v_max_dev"] <= 0.001, (spec.name, d)
    assert solver.counts["outside"] == 0 and solver.counts["network_cells"] < solver.counts["cell_updates"]


@pytest.mark.parametrize("opening", ["rule", "classifier"])
def test_surrogate_runs_are_finished_or_reported_as_failed(opening):
    from hmodel.compare import compare_path
    solver = SurrogateSolver(load_shipped("increment"), opening=opening)
    for spec in standard_paths(0.005):
        ref, res, devs, st = compare_path(SMALL, spec, solver, 1e-3, 1e-4)
        if res is None:
            assert st["status"].startswith("failed: ") and len(st["status"]) > 10
        else:
            assert st["status"] == "ok" and np.all(np.isfinite(res["sig11"])) and len(devs) == len(spec.p0)
    assert solver.counts["cell_updates"] > 0


def test_compare_and_reproduce_commands(tmp_path, capsys, monkeypatch):
    assert main(["compare", "--solver", "surrogate", "--paths", "drained,oedometric", "--axial-strain",
                 "0.005", "--param", "n_theta=18", "--out", str(tmp_path / "c")]) == 0
    text = (tmp_path / "c" / "deviations.csv").read_text()
    assert "drained" in text and "oedometric" in text and "speed_ratio" in text
    import hmodel.reproduce as rp
    monkeypatch.setattr(rp, "QUICK", rp.Plan(True, 18, 0.004, 1e-3, 3, "45:45:1"))
    assert main(["reproduce", "--quick", "--out", str(tmp_path / "r")]) == 0
    html = (tmp_path / "r" / "report.html").read_text()
    for part in ("Fig. 1.7", "Training database", "Surrogate accuracy", "against the closed form", "Timings"):
        assert part in html
    n_ok = sum(1 for line in (tmp_path / "r" / "deviations.csv").read_text().splitlines()[1:]
               if ",ok," in line)
    assert html.count("data:image/png;base64") >= 2 + (1 if n_ok else 0)
    for f in ("deviations.csv", "timings.csv", "surrogate-metrics.csv", "fig-1-7.csv"):
        assert (tmp_path / "r" / f).exists()
    assert not (tmp_path / "r.work").exists()
    capsys.readouterr()
    assert main(["compare", "--paths", "spiral", "--out", str(tmp_path / "x")]) != 0
    assert "spiral" in capsys.readouterr().err


def test_full_reproduce_trains_its_own_surrogate(tmp_path, monkeypatch):
    import hmodel.reproduce as rp
    import hmodel.surrogate.shipped as sh
    monkeypatch.setattr(rp, "FULL", rp.Plan(False, 12, 0.003, 1e-3, 3, "45:45:1", 4000))
    monkeypatch.setattr(sh, "DEFAULT_TRAINING", sh.TrainConfig(formulation="compliance", width=8, depth=2,
                                                                activation="silu", epochs=3))
    assert main(["reproduce", "--out", str(tmp_path / "r")]) == 0
    html = (tmp_path / "r" / "report.html").read_text()
    assert "Trained here" in html and "compliance" in html
    from hmodel.surrogate import load
    model = load(tmp_path / "r" / "surrogate.safetensors")
    assert model.meta["config"]["epochs"] == 3 and model.meta["training_data"]["source_checksum"]
