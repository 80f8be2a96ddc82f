"""Macro comparison of cell solvers and the reproduce report (small sizes)."""

import numpy as np
import pytest

from hmodel import Params
from hmodel.cli.app import main
from hmodel.compare import deviations, run_path, standard_paths
from hmodel.loading.result import COLUMNS, PathResult
from hmodel.surrogate.shipped import load_shipped
from hmodel.surrogate.solver import SurrogateSolver

SMALL = Params(n_theta=36)


def test_a_solver_against_itself_deviates_by_zero():
    for spec in standard_paths(0.01):
        a, _ = run_path(SMALL, spec, "closed-form", 1e-3, 1e-4)
        b, _ = run_path(SMALL, spec, "closed-form", 1e-3, 1e-4)
        for d in deviations(a, b):
            assert d["q_max_dev_rel"] == 0 and d["eps_v_max_dev"] == 0 and d["rows"] == len(a.point(d["point"]))


def _table(point, stage, q, p, eps_v) -> PathResult:
    """A result table of hand-written rows: q, p, eps_v per row (stresses and strains follow)."""
    q, p, ev = (np.asarray(x, float) for x in (q, p, eps_v))
    cols = {c: np.zeros(len(q)) for c in COLUMNS}
    cols.update(point=np.asarray(point), stage=np.asarray(stage, dtype=object), step=np.arange(1, len(q) + 1),
                eps11=ev / 2, eps22=ev / 2, sig11=p + q / 2, sig22=p - q / 2, p=p, q=q, eps_v=ev)
    return PathResult(cols)


def test_deviations_report_known_differences():
    """Hand-made results with known differences, rows matched stage by stage. Point 0: the other
    solver reaches p0 one consolidation row later, then its shear q is 10 % higher and its eps_v
    2e-4 larger; peak |q| = 40 kPa. Point 1: isotropic (q = 0), so Δq is relative to peak p."""
    C, S = "consolidation", "shear"
    ref = _table([0] * 7 + [1] * 2, [C] * 3 + [S] * 4 + [C] * 2,
                 q=[0, 0, 0, 1e4, 2e4, 4e4, 3e4, 0, 0], p=[1e5, 2e5, 3e5] + [3e5] * 4 + [1e5, 2e5],
                 eps_v=[1e-3, 2e-3, 3e-3, 3.1e-3, 3.2e-3, 3.3e-3, 3.4e-3, 1e-3, 2e-3])
    other = _table([0] * 8 + [1] * 2, [C] * 4 + [S] * 4 + [C] * 2,
                   q=[0, 0, 0, 0, 1.1e4, 2.2e4, 4.4e4, 3.3e4, 1e3, 3e3],
                   p=[1e5, 2e5, 3e5, 3.2e5] + [3e5] * 4 + [1e5, 2e5],
                   eps_v=[1e-3, 2e-3, 3e-3, 3.5e-3, 3.3e-3, 3.4e-3, 3.5e-3, 3.6e-3, 0.95e-3, 1.95e-3])
    d0, d1 = deviations(ref, other)
    assert d0["rows"] == 7 and d0["peak_q"] == pytest.approx(4e4)
    assert d0["q_max_dev_rel"] == pytest.approx(4e3 / 4e4, rel=1e-12)  # 10 % of the peak row
    assert d0["q_rms_dev_rel"] == pytest.approx(np.sqrt((1 + 4 + 16 + 9) * 1e6 / 7) / 4e4, rel=1e-12)
    assert d0["eps_v_max_dev"] == pytest.approx(2e-4, rel=1e-9)
    assert d0["eps_v_rms_dev"] == pytest.approx(2e-4 * np.sqrt(4 / 7), rel=1e-9)
    assert d1["rows"] == 2 and d1["peak_q"] == pytest.approx(2e5)
    assert d1["q_max_dev_rel"] == pytest.approx(3e3 / 2e5, rel=1e-12)
    assert d1["eps_v_max_dev"] == pytest.approx(5e-5, rel=1e-9)


def test_deviations_of_a_shifted_copy_of_a_run():
    """A drained run against a copy whose shear rows have q raised by 3 % of each point's peak
    |q| and eps_v by 1e-4: those are the maxima, and the RMS follows from the row counts."""
    spec = {s.name: s for s in standard_paths(0.01)}["drained"]
    ref, _ = run_path(SMALL, spec, "closed-form", 1e-3, 1e-4)
    cols = {k: v.copy() for k, v in ref.columns.items()}
    shear = cols["stage"] == "shear"
    for b in range(ref.n_points):
        m = shear & (cols["point"] == b)
        cols["q"][m] += 0.03 * np.abs(ref.point(b)["q"]).max()
    cols["eps_v"][shear] += 1e-4
    devs = deviations(ref, PathResult(cols, ref.meta))
    assert len(devs) == 3
    for d in devs:
        r = ref.point(d["point"])
        frac = np.sqrt(np.count_nonzero(r["stage"] == "shear") / len(r))
        assert d["rows"] == len(r)
        assert d["q_max_dev_rel"] == pytest.approx(0.03, rel=1e-9)
        assert d["q_rms_dev_rel"] == pytest.approx(0.03 * frac, rel=1e-9)
        assert d["eps_v_max_dev"] == pytest.approx(1e-4, rel=1e-6)
        assert d["eps_v_rms_dev"] == pytest.approx(1e-4 * frac, rel=1e-6)


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

    class FailsLater(ClosedFormSolver):  # through the generic driver, failing after `limit` calls
        name, calls, limit = "fails-later", 0, float("inf")

        def kernel(self, params):
            return None

        def step(self, params, state, dl1, dl2):
            self.calls += 1
            if self.calls > self.limit:
                raise SolverError("stopped on purpose")
            return super().step(params, state, dl1, dl2)

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


@pytest.mark.parametrize("step", [2e-4, 1e-3, 2e-3])
def test_shipped_surrogate_in_the_rev_reproduces_the_closed_form(step):
    """Every comparison path, as `hmodel compare` runs it (nθ = 360, to 10 %), at the increments
    2e-4, 1e-3 and 2e-3: no failure, |Δq| ≤ 1 % of peak q and |Δεv| ≤ 1e-3, and no cell outside
    the training domain (no closed-form fallback). Before the previous increment became Newton's
    first trial, unloading-reloading at 1e-3 ran away at the reload point."""
    from hmodel.compare import compare_path
    solver = SurrogateSolver(load_shipped(), on_outside="error")
    for spec in standard_paths(0.1):
        _, res, devs, st = compare_path(Params(), spec, solver, step, 1e-4)
        assert st["status"] == "ok"
        for d in devs:
            assert d["q_max_dev_rel"] <= 0.01 and d["eps_v_max_dev"] <= 0.001, (spec.name, d)
    assert solver.counts["outside"] == 0 and solver.counts["network_cells"] > 0


@pytest.mark.slow
def test_surrogate_runs_are_finished_or_reported_as_failed():
    """The report-scale 'increment' model is poor under shear, so only the isotropic path (every
    cell closed, no sliding) must finish and stay close to the closed form; every other path
    either finishes or fails with a one-line reason."""
    from hmodel.compare import compare_path
    solver = SurrogateSolver(load_shipped("increment"))
    status = {}
    for spec in standard_paths(0.005):
        ref, res, devs, st = compare_path(SMALL, spec, solver, 1e-3, 1e-4)
        status[spec.name] = st["status"]
        if res is None:
            reason = st["status"].removeprefix("failed: ")
            assert st["status"].startswith("failed: ") and reason.strip() and "\n" not in reason, st
        else:
            assert st["status"] == "ok" and np.all(np.isfinite(res["sig11"])) and len(devs) == len(spec.p0)
        if spec.name == "isotropic":
            iso = devs
    assert status["isotropic"] == "ok", status
    assert all(d["q_max_dev_rel"] <= 0.01 and d["eps_v_max_dev"] <= 1e-3 for d in iso), iso
    assert solver.counts["cell_updates"] > 0


@pytest.mark.slow
def test_compare_and_reproduce_commands(tmp_path, capsys, monkeypatch):
    assert main(["compare", "--solver", "surrogate", "--paths", "drained,oedometric", "--axial-strain",
                 "0.005", "--param", "n_theta=18", "--out", str(tmp_path / "c")]) == 0
    assert "after a warm-up run" in capsys.readouterr().out
    text = (tmp_path / "c" / "deviations.csv").read_text()
    assert "drained" in text and "oedometric" in text and "speed_ratio" in text
    import hmodel.studies.reproduce as rp
    monkeypatch.setattr(rp, "QUICK", rp.Plan(True, 18, 0.004, 1e-3, 3, "45:45:1"))
    assert main(["reproduce", "--quick", "--out", str(tmp_path / "r")]) == 0
    html = (tmp_path / "r" / "report.html").read_text()
    for part in ("Fig. 1.7", "Training database", "Surrogate accuracy", "against the closed form", "Timings"):
        assert part in html
    # it reads as a report: the learned cell named once, options as a table, figures captioned
    # with what they show, the comparison's columns explained beside them
    import re
    assert "surrogate surrogate" not in html and "{'" not in html and "{&#x27;" not in html
    assert "the shipped surrogate, compliance formulation" in html and "<td>--directions</td>" in html
    captions = re.findall(r"<figcaption>(.*?)</figcaption>", html)
    assert captions and all(not c.endswith(".png") and len(c) > 60 for c in captions)
    assert "in the report (§3.1)" in html and "never tried" in html and "without a closed form" in html
    # the speed column says what ran, on how many threads, and how busy the machine was
    assert "load average" in html and "surrogate: compiled kernel on 1 Numba thread, network on 1 BLAS thread" in html
    assert "closed form: compiled kernel on" in (tmp_path / "r" / "deviations.csv").read_text()
    n_ok = sum(1 for line in (tmp_path / "r" / "deviations.csv").read_text().splitlines()[1:]
               if ",ok," in line)
    assert html.count("data:image/png;base64") >= 2 + (1 if n_ok else 0)
    timings = (tmp_path / "r" / "timings.csv").read_text()
    assert "warm-up of the closed form" in timings and "warm-up of surrogate" in timings
    for f in ("deviations.csv", "timings.csv", "surrogate-metrics.csv", "fig-1-7.csv"):
        assert (tmp_path / "r" / f).exists()
    assert not (tmp_path / "r.work").exists()
    capsys.readouterr()
    assert main(["compare", "--paths", "spiral", "--out", str(tmp_path / "x")]) != 0
    assert "spiral" in capsys.readouterr().err
    assert main(["compare", "--reference", "nonsense", "--out", str(tmp_path / "y")]) != 0
    assert "nonsense" in capsys.readouterr().err and not (tmp_path / "y").exists()


def test_compare_against_another_reference(tmp_path):
    """--reference names the solver the deviations are taken from: the closed form against
    itself deviates by nothing, and the surrogate against the closed form by what it deviates
    the other way round (the same curves, normalized by the other peak)."""
    import csv

    common = ["--paths", "drained", "--axial-strain", "0.004", "--param", "n_theta=18"]
    assert main(["compare", "--solver", "closed-form", "--reference", "closed-form", *common,
                 "--out", str(tmp_path / "same")]) == 0
    same = list(csv.DictReader((tmp_path / "same" / "deviations.csv").open()))
    assert same and all(float(r["q_max_dev_rel"]) == 0.0 and r["reference"] == "closed-form" for r in same)
    assert main(["compare", "--solver", "surrogate", *common, "--out", str(tmp_path / "a")]) == 0
    assert main(["compare", "--solver", "closed-form", "--reference", "surrogate", *common,
                 "--out", str(tmp_path / "b")]) == 0
    a = list(csv.DictReader((tmp_path / "a" / "deviations.csv").open()))
    b = list(csv.DictReader((tmp_path / "b" / "deviations.csv").open()))
    assert b[0]["reference"] == "surrogate"
    for ra, rb in zip(a, b):
        qa, qb = float(ra["q_max_dev_rel"]), float(rb["q_max_dev_rel"])
        assert qa > 0 and qb == pytest.approx(qa, rel=0.05)


@pytest.mark.slow
def test_full_reproduce_trains_its_own_surrogate(tmp_path, monkeypatch):
    import hmodel.studies.reproduce as rp
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
