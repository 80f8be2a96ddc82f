"""Active learning (hmodel surrogate refine): the gated states are collected, their increments
solved by the exact solver, the model fine-tuned and measured, round by round, resumably."""

import json
from types import SimpleNamespace

import numpy as np
import pyarrow.parquet as pq
import pytest

from hmodel import InputError, Params
from hmodel.cell import CellState
from hmodel.cell.closed_form import ClosedFormSolver
from hmodel.data import DatasetSpec, generate
from hmodel.data.sampling import write_split
from hmodel.studies.refine import RefineConfig, refine
from hmodel.surrogate import modelfile
from hmodel.surrogate.training import TrainConfig, train
from hmodel.surrogate.training_rows import params_of, read_sample
from hmodel.surrogate.gate import scores, threshold
from hmodel.surrogate.trust import fit_trust

PATHS = ["--paths", "drained", "--axial-strain", "0.01", "--step", "2e-3", "--iso-step", "1e-3",
         "-p", "n_theta=12"]


@pytest.fixture(scope="module")
def start(tmp_path_factory, small_sample):
    """A deliberately poor compliance network (one narrow layer, few epochs) with a trust score,
    and its training sample (tests/conftest.py): ``start.model``, ``start.sample``."""
    cols, info = read_sample(small_sample, "train")
    s, _ = train(cols, params_of(info), TrainConfig(formulation="compliance", width=8, depth=1, epochs=4,
                                                    device="cpu"))
    s.meta["params"] = info["params"]
    s, _ = fit_trust(s, cols, read_sample(small_sample, "test")[0], reference=256, k=4)
    model = modelfile.save(s, tmp_path_factory.mktemp("al") / "m.safetensors")
    return SimpleNamespace(model=model, sample=small_sample)


def _run(start, out, *extra):
    from hmodel.cli.app import main
    return main(["surrogate", "refine", str(start.model), "--data", str(start.sample),
                 "--out", str(out), "--rounds", "2", "--gate", "0.5", "--states", "40", "--increments", "6",
                 "--epochs", "3", *PATHS, *extra])


def test_rounds_add_exact_rows_from_gated_states(start, tmp_path):
    out = tmp_path / "r"
    assert _run(start, out) == 0
    rounds = [json.loads((out / f"round-{r}" / "summary.json").read_text())["summary"] for r in range(3)]
    assert [r["round"] for r in rounds] == [0, 1, 2]
    assert rounds[2]["exact_rows"] == rounds[1]["rows_added"] + rounds[2]["rows_added"] > 0
    assert 0 < rounds[1]["gated_fraction"] <= 1 and rounds[1]["fallback_cells"] > 0
    assert (out / "rounds.png").is_file() and (out / "rounds.csv").read_text().count("\n") == 4
    params = Params(n_theta=12)
    rows = {k: np.concatenate([pq.read_table(out / "round-1" / "rows" / f"{p}.parquet")[k].to_numpy()
                               for p in ("train", "test")])
            for k in ("deps1", "deps2", "d1", "d2", "alpha", "N1", "N2", "T1", "l1", "l2",
                      "alpha_next", "N1_next", "N2_next", "T1_next", "l1_next")}
    assert len(rows["deps1"]) == rounds[1]["rows_added"] == 6 * rounds[1]["gated_states"]
    # every row is the closed form's own increment from its state (stepped here independently)
    before = np.column_stack([rows[k] for k in ("d1", "d2", "alpha", "N1", "N2", "T1", "l1", "l2")])
    l10, l20 = 2 + 4 * np.cos(params.alpha0), 4 * np.sin(params.alpha0)  # eq. 1.2, d = 2r = 2
    new, _ = ClosedFormSolver().step(params, CellState(before), -l10 * rows["deps1"], -l20 * rows["deps2"])
    for j, k in ((2, "alpha_next"), (3, "N1_next"), (4, "N2_next"), (5, "T1_next"), (6, "l1_next")):
        np.testing.assert_allclose(new.values[:, j], rows[k], rtol=1e-12, atol=1e-9 * np.abs(rows[k]).max())
    # ... and every state is one the starting model's gate sent to the exact solver
    m0 = modelfile.load(start.model)
    states = np.unique(before, axis=0)
    assert np.all(scores(m0, m0.formulation.features(states)) > threshold(m0, 0.5))
    # the refined model learned from them: another model than the start, with its own trust reference
    m2 = modelfile.load(out / "model.safetensors")
    assert m2.meta["refined"]["round"] == 2 and m2.meta["trust"]["reference_rows"] == 256
    assert not np.allclose(m2.weights[0][0], m0.weights[0][0])


def test_an_interrupted_run_resumes_at_its_round(start, tmp_path, monkeypatch):
    from hmodel.studies import refine as mod

    out, calls, real = tmp_path / "r", [], mod.train

    def once(*a, **k):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(*a, **k)

    monkeypatch.setattr(mod, "train", once)
    assert _run(start, out) == 130
    assert (out / "round-1" / "summary.json").is_file() and not (out / "round-2" / "summary.json").exists()
    first = (out / "round-1" / "summary.json").read_text()
    calls.clear()
    monkeypatch.setattr(mod, "train", lambda *a, **k: (calls.append(1), real(*a, **k))[1])
    assert _run(start, out) == 0
    assert len(calls) == 1 and (out / "round-1" / "summary.json").read_text() == first
    calls.clear()
    assert _run(start, out, "--states", "30") == 0  # other settings: every round is redone
    assert len(calls) == 2


@pytest.mark.parametrize("extra, word", [
    (["--solver", "dem:standard"], "YADE"),
    (["-p", "kn=1e9"], "other material"),
    (["--paths", "nowhere"], "unknown path"),
    (["--gate", "1.5"], "quantile"),
])
def test_bad_input_is_one_line_and_writes_nothing(start, tmp_path, monkeypatch, capsys, extra, word):
    monkeypatch.setenv("HMODEL_YADE", str(tmp_path / "no-yade"))
    out = tmp_path / "r"
    assert _run(start, out, *extra) != 0
    err = capsys.readouterr().err.strip()
    assert err.startswith("hmodel: error:") and word in err and "\n" not in err
    assert not out.exists()


def test_a_model_without_trust_cannot_be_refined(start, tmp_path):
    s = modelfile.load(start.model)
    bare = type(s)(s.formulation, s.architecture, s.x_scaler, s.y_scaler, s.weights,
                   {k: v for k, v in s.meta.items() if k != "trust"}, s.input_range)
    with pytest.raises(InputError, match="trust"):
        refine(bare, start.sample, Params(n_theta=12), RefineConfig(paths=("drained",)), tmp_path / "r")


@pytest.mark.yade
def test_dem_cells_answer_the_gate(start, tmp_path):
    """With YADE, the exact rows come from DEM H-cells (dem:standard), recorded as such."""
    out = tmp_path / "r"
    from hmodel.cli.app import main
    assert main(["surrogate", "refine", str(start.model), "--data", str(start.sample),
                 "--out", str(out), "--rounds", "1", "--gate", "0.5", "--states", "3", "--increments", "4",
                 "--epochs", "2", "--solver", "dem:standard", *PATHS]) == 0
    manifest = json.loads((out / "round-1" / "rows" / "manifest.json").read_text())
    assert manifest["options"]["solver"] == "dem:standard" and manifest["method"] == "active"
    summary = json.loads((out / "round-1" / "summary.json").read_text())["summary"]
    assert summary["rows_added"] == 12 and summary["fallback_cells"] > 0


@pytest.mark.slow
@pytest.mark.yade
def test_a_richer_cells_rows_are_dem_increments_from_its_gated_cells(tmp_path):
    """With YADE, a meso ensemble of the hexagon-center cell gated to its DEM cell: the new rows
    carry the full DEM state, and each is the DEM cell's own increment from its start state,
    stepped here by hand."""
    from hmodel.cli.app import main
    from hmodel.dem.solver import DEMSolver
    from hmodel.surrogate.trust import fit_ensemble_trust

    dem = "dem:hexagon-center:tol=1e-7,max_iter=100000"
    params = Params(sliding_rhs="equilibrium")
    spec = DatasetSpec(kind=2, n_directions=4, theta_min=-60, theta_max=150, alpha0_min=45, alpha0_max=45,
                       alpha0_step=1, max_strain=0.004, step=0.001, start_every=0.002, magnitude=0.002,
                       magnitude_min=0.0, n_increments=6, substeps=1, solver=dem, from_unloaded=True)
    ds = generate(spec, params, tmp_path / "d", workers=1)
    write_split(ds, tmp_path / "sample", ds.n_rows // 2, ds.n_rows // 4, "random", 0)
    cols, info = read_sample(tmp_path / "sample", "train")
    members = []
    for seed in (0, 1):
        m, _ = train(cols, params_of(info), TrainConfig(formulation="meso", width=8, depth=1, epochs=3, seed=seed,
                                                        device="cpu", cell_step=1e-3), cell=dem)
        m.meta["params"] = info["params"]
        members.append(m)
    members, _ = fit_ensemble_trust(members, read_sample(tmp_path / "sample", "test")[0])
    for k, m in enumerate(members):
        modelfile.save(m, tmp_path / f"m{k}.safetensors")
    out = tmp_path / "r"
    assert main(["surrogate", "refine", f"{tmp_path / 'm0.safetensors'}+{tmp_path / 'm1.safetensors'}",
                 "--data", str(tmp_path / "sample"), "--out", str(out), "--rounds", "1", "--gate", "0.5",
                 "--states", "3", "--increments", "4", "--epochs", "1", "--solver", dem, "--reference", dem,
                 "--paths", "undrained", "--axial-strain", "0.003", "--step", "1e-3", "--iso-step", "2e-4",
                 "-p", "n_theta=6", "-p", "sliding_rhs=equilibrium"]) == 0
    rows, info = read_sample(out / "round-1" / "rows", "train")
    test, _ = read_sample(out / "round-1" / "rows", "test")
    rows = {k: np.concatenate([rows[k], test[k]]) for k in rows if k in test}
    solver = DEMSolver(dem)
    assert rows["state_extra"].shape[1] == solver.n_fields - 8 and len(rows["deps1"]) == 12
    fields = ("d1", "d2", "alpha", "N1", "N2", "T1", "l1", "l2")
    before = np.column_stack([rows[k] for k in fields] + [rows["state_extra"]])
    after = np.column_stack([rows[k + "_next"] for k in fields] + [rows["state_extra_next"]])
    l10, l20 = params.l10, params.l20
    by_hand, _ = solver.step(params, CellState(before), -rows["deps1"] * l10, -rows["deps2"] * l20)
    np.testing.assert_allclose(by_hand.values, after, rtol=0, atol=1e-9 * np.abs(after).max())
