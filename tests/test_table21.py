"""The Table 2.1 study: the report's pooled scores, its published input convention (the answer
leak), and a sweep that resumes where it was interrupted."""

import json

import numpy as np
import pytest
from sklearn.linear_model import LinearRegression
from sklearn.metrics import mean_absolute_error, mean_squared_error, r2_score

from hmodel import InputError, Params
from hmodel.data import Dataset, DatasetSpec, generate
from hmodel.surrogate import make_formulation
from hmodel.surrogate.metrics import pooled_metrics
from hmodel.surrogate.solver import SurrogateSolver
from hmodel.surrogate.training import TrainConfig, train

SPEC = DatasetSpec(kind=2, n_directions=5, alpha0_min=40, alpha0_max=50, alpha0_step=10,
                   max_strain=0.06, start_every=0.02, n_increments=24)
SPEC1 = DatasetSpec(kind=1, n_directions=5, alpha0_min=40, alpha0_max=50, alpha0_step=10, max_strain=0.05)


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("t21")
    generate(SPEC, Params(), root / "d2"), generate(SPEC1, Params(), root / "d1")
    return root / "d2", root / "d1"


def test_pooled_scores_are_scikit_learns_defaults():
    """The report's printout is scikit-learn's: R² averaged over the three forces, MAE and RMSE
    over all force values; checked against scikit-learn itself on a case with known errors."""
    rng = np.random.default_rng(3)
    y = np.column_stack([rng.uniform(0.5, 1.5, 400), rng.uniform(0, 1e8, (400, 3))])
    p = y + np.column_stack([np.full(400, 0.01), rng.normal(0, [1e6, 3e6, 5e5], (400, 3))])
    m = pooled_metrics(y, p)
    assert m["mae_angle"] == pytest.approx(0.01) and m["rmse_angle"] == pytest.approx(0.01)
    assert m["r2_angle"] == pytest.approx(r2_score(y[:, 0], p[:, 0]))
    assert m["r2_force"] == pytest.approx(r2_score(y[:, 1:], p[:, 1:]))
    assert m["mae_force"] == pytest.approx(mean_absolute_error(y[:, 1:], p[:, 1:]))
    assert m["rmse_force"] == pytest.approx(np.sqrt(mean_squared_error(y[:, 1:], p[:, 1:])))
    assert m["r2_force"] < 1.0 and m["max_angle"] == pytest.approx(y[:, 0].max() + 0.01)


def test_the_published_inputs_hold_the_answer(data):
    """With the forces after the increment among the inputs, a linear map recovers N1' exactly;
    from the state before, it cannot (the increment is nonlinear)."""
    ds = Dataset.open(data[0])
    cols = ds.read()
    params = Params.from_dict(ds.manifest["params"])
    fit = {}
    for name in ("report", "report-leak"):
        X = make_formulation(name, params).inputs(cols)
        fit[name] = LinearRegression().fit(X, cols["N1_next"]).score(X, cols["N1_next"])
    assert fit["report-leak"] == pytest.approx(1.0, abs=1e-9)
    assert fit["report"] < 0.999


def test_a_leaked_model_cannot_step_cells(data):
    ds = Dataset.open(data[0])
    cols = ds.read(rows=np.arange(200))
    s, _ = train(cols, Params.from_dict(ds.manifest["params"]),
                 TrainConfig(formulation="report-leak", epochs=1, width=4, depth=1, device="cpu"))
    with pytest.raises(InputError, match="forces after the increment"):
        SurrogateSolver(s)


def test_sweep_scores_both_datasets_and_resumes(data, tmp_path, monkeypatch, capsys):
    from hmodel.cli.app import main
    from hmodel.studies import sweep

    ds, d1 = data
    args = ["surrogate", "sweep", str(ds), "--depths", "1", "--losses", "mae,mse", "--sizes", "300",
            "--test", "200", "--epochs", "2", "--inputs", "before,after", "--normalization",
            "minmax,robust", "--dataset1", str(d1), "--device", "cpu", "--out", str(tmp_path / "sw")]
    calls, real = [], sweep.train

    def interrupted(*a, **k):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(*a, **k)

    monkeypatch.setattr(sweep, "train", interrupted)
    assert main(args) == 130
    assert not (tmp_path / "sw").exists()  # nothing half-written, only the runs kept aside
    calls.clear()
    monkeypatch.setattr(sweep, "train", lambda *a, **k: (calls.append(1), real(*a, **k))[1])
    assert main(args) == 0
    assert "resuming: 2 finished" in capsys.readouterr().out
    assert len(calls) == 2 * 2 * 2 - 2
    lines = (tmp_path / "sw" / "sweep.csv").read_text().splitlines()
    head = lines[0].split(",")
    assert len(lines) == 1 + 8 and {"d1_r2_force", "d2_mae_angle", "inputs"} <= set(head)
    assert {r.split(",")[head.index("formulation")] for r in lines[1:]} == {"report", "report-leak"}
    assert not list(tmp_path.glob(".sw.partial.jsonl"))
    assert json.loads((tmp_path / "sw" / "config.json").read_text())["inputs"] == "before,after"
    assert main(args[:-2] + ["--formulation", "increment", "--out", str(tmp_path / "x")]) != 0
    assert "published input convention" in capsys.readouterr().err


@pytest.mark.slow
def test_reproduce_shows_the_table_beside_the_report(tmp_path):
    """The full reproduce's Table 2.1 step, at a tiny scale: both conventions, both test sets,
    and the report's Fig. 2.7 numbers beside our Model 1."""
    from hmodel.studies.reproduce import FULL, table21
    from hmodel.studies.sweep import REPORT_FIG_2_7

    assert FULL.table21_sizes == (6_000, 60_000, 600_000)  # the report's sizes in the full run
    d2 = DatasetSpec(kind=2, n_directions=13, alpha0_min=40, alpha0_max=60, alpha0_step=5, max_strain=0.1,
                     start_every=0.01)  # 109,200 rows: enough for Model 1's 60k
    rows, files = table21(tmp_path, (60_000,), minutes=0.03, depths=(3,), d1_spec=SPEC1, d2_spec=d2,
                          n_test=300)
    assert {(r["inputs"], r["depth"], r["loss"]) for r in rows} == {
        (i, 3, loss) for i in ("before", "after") for loss in ("mae", "mse")} and len(rows) == 4
    for name, write in files.items():
        write(tmp_path / name)
    fig = (tmp_path / "fig-2-7.csv").read_text().splitlines()
    assert len(fig) == 1 + sum(len(v) for v in REPORT_FIG_2_7.values()) and "nan" not in "".join(fig).lower()
    assert "0.9996026" in (tmp_path / "fig-2-7.csv").read_text() and (tmp_path / "table-2-1.png").is_file()
