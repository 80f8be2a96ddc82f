"""Neural surrogates: learning, metrics, normalizations, Coulomb-safe outputs, safe model files."""

import json
import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from hmodel import InputError, Params
from hmodel.data import DatasetSpec, generate
from hmodel.data.sampling import write_split
from hmodel.surrogate import ModelFileError, load, make_formulation, save
from hmodel.surrogate.formulations import OUTPUTS
from hmodel.surrogate.metrics import regression_metrics
from hmodel.surrogate.model import Architecture, Surrogate
from hmodel.surrogate.scalers import METHODS, Affine, fit_scaler
from hmodel.surrogate.training import TrainConfig, train

SPEC = DatasetSpec(kind=2, n_directions=7, alpha0_min=40, alpha0_max=60, alpha0_step=10,
                   max_strain=0.1, start_every=0.02, n_increments=36)


@pytest.fixture(scope="module")
def sample(tmp_path_factory):
    root = tmp_path_factory.mktemp("s")
    ds = generate(SPEC, Params(), root / "d2")
    write_split(ds, root / "sample", 2000, 500, "random", 0)
    return root / "sample"


@pytest.fixture(scope="module")
def model(sample):
    from hmodel.surrogate.training_rows import params_of, read_sample
    cols, info = read_sample(sample, "train")
    s, hist = train(cols, params_of(info), TrainConfig(width=16, depth=2, epochs=40, seed=1))
    return s, hist, cols


def test_tiny_network_overfits_tiny_dataset(sample):
    from hmodel.surrogate.training_rows import params_of, read_sample
    cols, info = read_sample(sample, "train")
    tiny = {k: v[:64] for k, v in cols.items()}
    s, hist = train(tiny, params_of(info), TrainConfig(formulation="report", width=32, depth=2,
                                                       epochs=1500, patience=1500, batch_size=64,
                                                       activation="silu", seed=0))
    assert hist[-1]["train_loss"] < 0.02 * hist[0]["train_loss"]
    pred = s.predict(tiny)
    r2 = regression_metrics(np.column_stack([tiny[k] for k in OUTPUTS]),
                            np.column_stack([pred[k] for k in OUTPUTS]))["r2"]
    assert np.all(r2 > 0.99), r2


def test_metrics_match_scikit_learn():
    from sklearn.metrics import mean_absolute_error, mean_squared_error, r2_score
    rng = np.random.default_rng(3)
    y = rng.normal(size=(200, 3)) * [1, 100, 1e-3]
    p = y + rng.normal(size=y.shape) * [0.1, 5, 1e-4]
    m = regression_metrics(y, p)
    np.testing.assert_allclose(m["r2"], r2_score(y, p, multioutput="raw_values"), rtol=1e-12)
    np.testing.assert_allclose(m["mae"], mean_absolute_error(y, p, multioutput="raw_values"), rtol=1e-12)
    np.testing.assert_allclose(m["rmse"], np.sqrt(mean_squared_error(y, p, multioutput="raw_values")), rtol=1e-12)
    np.testing.assert_allclose(m["max_abs"], np.abs(p - y).max(axis=0))
    assert regression_metrics(np.ones((5, 1)), np.ones((5, 1)))["r2"][0] == 1.0


@settings(max_examples=40, deadline=None)
@given(method=st.sampled_from(METHODS),
       X=arrays(np.float64, st.tuples(st.integers(2, 30), st.integers(1, 5)),
                elements=st.floats(-1e9, 1e9, allow_nan=False, width=64)))
def test_every_normalization_inverts(method, X):
    a = fit_scaler(method, X)
    back = a.inverse(a.transform(X))
    np.testing.assert_allclose(back, X, rtol=1e-9, atol=1e-9 * (1 + np.abs(X).max()))


def test_normalizations_match_scikit_learn():
    from sklearn.preprocessing import MinMaxScaler, RobustScaler, StandardScaler
    X = np.random.default_rng(0).normal(size=(100, 3)) * [1, 10, 1000]
    for method, sk in (("minmax", MinMaxScaler()), ("zscore", StandardScaler()), ("robust", RobustScaler())):
        np.testing.assert_allclose(fit_scaler(method, X).transform(X), sk.fit_transform(X), atol=1e-12)
    u = fit_scaler("unit", X).transform(X)
    np.testing.assert_allclose(np.linalg.norm(u, axis=0), 1.0)
    with pytest.raises(InputError):
        fit_scaler("softmax", X)


def _random_surrogate(seed: int, width=16, depth=2) -> Surrogate:
    rng = np.random.default_rng(seed)
    p = Params()
    form = make_formulation("increment", p)
    sizes = [8] + [width] * depth + [5]
    weights = [(rng.normal(size=(o, i)) * 2, rng.normal(size=o)) for i, o in zip(sizes[:-1], sizes[1:])]
    one = lambda n: Affine("zscore", np.zeros(n), np.ones(n))  # noqa: E731
    return Surrogate(form, Architecture(width, depth, "tanh"), one(8), Affine("zscore", np.zeros(5), np.full(5, 3.0)), weights)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_increment_formulation_never_violates_coulomb(seed):
    s = _random_surrogate(seed)
    rng = np.random.default_rng(seed + 1)
    n = 2000
    F = 4e8
    cols = {"deps1": rng.normal(0, 0.01, n), "deps2": rng.normal(0, 0.01, n),
            "alpha": rng.uniform(0.5, 1.5, n), "l1": rng.uniform(2, 5, n), "l2": rng.uniform(2, 4, n),
            "N1": F * rng.uniform(0, 0.1, n), "N2": F * rng.uniform(0, 0.1, n),
            "T1": F * rng.uniform(-0.05, 0.05, n)}
    out = s.predict(cols)
    assert np.all(out["N1_next"] >= 0) and np.all(out["N2_next"] >= 0)
    assert np.all(np.abs(out["T1_next"]) <= Params().tan_phi * out["N1_next"] * (1 + 1e-12))


def test_model_file_round_trips_exactly(model, tmp_path, sample):
    s, _, cols = model
    path = save(s, tmp_path / "m.safetensors")
    back = load(path)
    for (W, b), (W2, b2) in zip(s.weights, back.weights):
        np.testing.assert_array_equal(W, W2)
        np.testing.assert_array_equal(b, b2)
    p1, p2 = s.predict(cols), back.predict(cols)
    for k in OUTPUTS:
        np.testing.assert_array_equal(p1[k], p2[k])
    assert back.meta["config"]["width"] == 16 and back.formulation == s.formulation
    np.testing.assert_array_equal(back.input_range, s.input_range)
    X = s.formulation.inputs(cols)
    assert not back.outside(X).any()
    far = X[:1].copy()
    far[0, 5] = 10 * s.input_range[1, 5]  # N1 ten times the largest trained
    assert back.outside(far).all()
    save(back, tmp_path / "again.safetensors")
    np.testing.assert_array_equal(load(tmp_path / "again.safetensors").predict(cols)["N1_next"], p1["N1_next"])
    # metadata carried over from another model never overrides the file's own description
    back.meta["architecture"] = {"width": 99, "depth": 9, "activation": "relu", "n_layers": 10}
    assert load(save(back, tmp_path / "third.safetensors")).architecture == s.architecture


def test_loading_never_unpickles(model, tmp_path, monkeypatch):
    s, _, _ = model
    path = save(s, tmp_path / "m.safetensors")

    def forbidden(*a, **k):
        raise AssertionError("unpickling attempted")
    monkeypatch.setattr(pickle, "loads", forbidden)
    monkeypatch.setattr(pickle, "load", forbidden)
    monkeypatch.setattr(pickle, "Unpickler", forbidden)
    import numpy.lib.format as npformat
    monkeypatch.setattr(npformat, "read_array", forbidden)  # no allow_pickle .npy path either
    load(path)


@pytest.mark.parametrize("damage", ["flip-weight", "truncate", "edit-metadata", "version", "empty", "pickle"])
def test_damaged_model_files_are_refused(model, tmp_path, damage):
    s, _, _ = model
    path = save(s, tmp_path / "m.safetensors")
    data = bytearray(path.read_bytes())
    hlen = int.from_bytes(data[:8], "little")
    header = json.loads(data[8:8 + hlen])
    if damage == "flip-weight":
        data[-20] ^= 0x01
        path.write_bytes(bytes(data))
    elif damage == "truncate":
        path.write_bytes(bytes(data[: len(data) - 100]))
    elif damage == "edit-metadata":
        meta = json.loads(header["__metadata__"]["hmodel"])
        meta["metrics"] = "excellent"
        header["__metadata__"]["hmodel"] = json.dumps(meta, sort_keys=True)
        new = json.dumps(header).encode()
        new += b" " * (-len(new) % 8)
        path.write_bytes(len(new).to_bytes(8, "little") + new + bytes(data[8 + hlen:]))
    elif damage == "version":  # re-signed, so that only the version is wrong
        _resign(path, lambda meta: meta.update(format_version=99))
    elif damage == "empty":
        path.write_bytes(b"")
    else:
        path.write_bytes(pickle.dumps({"weights": [1, 2, 3]}))
    with pytest.raises(ModelFileError):
        load(path)


def _resign(path, edit) -> None:
    """Edit a model file's metadata with ``edit(meta)`` and recompute its checksum, as anyone
    can: the checksum detects accidents, not a careful forger."""
    from safetensors.numpy import load_file

    from hmodel.surrogate.modelfile import _digest
    data = path.read_bytes()
    hlen = int.from_bytes(data[:8], "little")
    header = json.loads(data[8:8 + hlen])
    meta = json.loads(header["__metadata__"]["hmodel"])
    edit(meta)
    header["__metadata__"]["hmodel"] = json.dumps(meta, sort_keys=True)
    header["__metadata__"]["checksum"] = _digest(load_file(str(path)), header["__metadata__"]["hmodel"])
    new = json.dumps(header).encode()
    new += b" " * (-len(new) % 8)
    path.write_bytes(len(new).to_bytes(8, "little") + new + data[8 + hlen:])


def _one_more_layer(meta):  # depth and n_layers agree with each other, not with the tensors
    meta["architecture"]["n_layers"] += 1
    meta["architecture"]["depth"] += 1


@pytest.mark.parametrize("edit, words", [
    (_one_more_layer, ("inconsistent", "metadata name 4 layers", "tensors hold 3")),
    (lambda meta: meta["formulation"].update(name="magic"), ("inconsistent", "unknown formulation 'magic'")),
], ids=["one-more-layer", "unknown-formulation"])
def test_resigned_model_file_with_inconsistent_metadata_is_refused(model, tmp_path, capsys, edit, words):
    from hmodel.cli.app import main
    s, _, _ = model
    path = save(s, tmp_path / "m.safetensors")
    _resign(path, edit)
    with pytest.raises(InputError) as err:
        load(path)
    assert isinstance(err.value, ModelFileError) and "\n" not in str(err.value)
    assert all(w in str(err.value) for w in words), str(err.value)
    code = main(["run", "iso", "--p0", "100kPa", "--param", "n_theta=6", "--solver", f"surrogate:{path}",
                 "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1 and err.startswith("hmodel: error:") and words[1] in err, err
    assert not (tmp_path / "o").exists()

def test_training_is_reproducible(sample):
    from hmodel.surrogate.training_rows import params_of, read_sample
    cols, info = read_sample(sample, "train")
    cfg = TrainConfig(width=8, depth=2, epochs=5, seed=4)
    a, _ = train(cols, params_of(info), cfg)
    b, _ = train(cols, params_of(info), cfg)
    for (W, _), (W2, _) in zip(a.weights, b.weights):
        np.testing.assert_array_equal(W, W2)


@pytest.mark.parametrize("bad", [dict(loss="huber"), dict(width=0), dict(activation="sine"),
                                 dict(val_fraction=1.0), dict(lr=0.0), dict(epochs=0)])
def test_bad_training_options(bad):
    with pytest.raises(InputError):
        TrainConfig(**bad)


def test_surrogate_cli(sample, tmp_path, capsys):
    from hmodel.cli.app import main
    m = tmp_path / "m.safetensors"
    assert main(["surrogate", "train", str(sample), "--out", str(m), "--epochs", "3",
                 "--width", "8", "--depth", "2"]) == 0
    assert load(m).meta["training_data"]["source_checksum"]
    assert main(["surrogate", "evaluate", str(m), "--data", str(sample), "--data",
                 str(sample.parent / "d2"), "--rows", "500", "--out", str(tmp_path / "ev")]) == 0
    text = (tmp_path / "ev" / "metrics.csv").read_text()
    assert "increment" in text and "state after" in text and "dataset 2" in text
    assert len(list((tmp_path / "ev").glob("parity-*.png"))) == 2
    assert main(["surrogate", "sweep", str(sample.parent / "d2"), "--depths", "1,2", "--losses", "mae,mse",
                 "--sizes", "300,600", "--test", "200", "--epochs", "2", "--out", str(tmp_path / "sw")]) == 0
    assert (tmp_path / "sw" / "sweep.csv").read_text().count("\n") == 1 + 2 * 2 * 2
    capsys.readouterr()
    for bad, word in ((["surrogate", "train", str(sample), "--out", str(tmp_path / "x.pt")], "safetensors"),
                      (["surrogate", "train", str(sample), "--out", str(m), "--loss", "huber"], "loss"),
                      (["surrogate", "train", str(tmp_path), "--out", str(m)], "sample folder"),
                      (["surrogate", "evaluate", str(tmp_path / "none.safetensors"), "--data", str(sample),
                        "--out", str(tmp_path / "e2")], "does not exist")):
        assert main(bad) != 0
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and word in err[0], err


@pytest.mark.parametrize("activation", ["tanh", "relu", "silu", "gelu", "elu"])
def test_numpy_forward_matches_torch(activation):
    """The NumPy forward pass (blocks, in-place activations and scaling) is PyTorch's MLP, in
    float64 to round-off and in float32 to its precision, over more rows than one block."""
    import torch
    from hmodel.surrogate.model import BLOCK_ROWS
    rng = np.random.default_rng(0)
    sizes = [5, 24, 17, 7]
    weights = [(rng.normal(size=(o, i)) / np.sqrt(i), rng.normal(size=o)) for i, o in zip(sizes, sizes[1:])]
    s = Surrogate(make_formulation("report", Params()), Architecture(24, 2, activation),
                  Affine("zscore", rng.normal(size=5), rng.uniform(0.5, 2, 5)),
                  Affine("zscore", rng.normal(size=7), rng.uniform(0.5, 2, 7)), weights)
    layers = []
    for k, (W, b) in enumerate(weights):
        lin = torch.nn.Linear(W.shape[1], W.shape[0]).double()
        lin.weight.data, lin.bias.data = torch.from_numpy(W), torch.from_numpy(b)
        layers += [lin] + ([{"tanh": torch.nn.Tanh(), "relu": torch.nn.ReLU(), "silu": torch.nn.SiLU(),
                             "gelu": torch.nn.GELU(), "elu": torch.nn.ELU()}[activation]]
                           if k < len(weights) - 1 else [])
    X = rng.normal(size=(2 * BLOCK_ROWS + 3, 5)) * 3
    with torch.no_grad():
        ref = s.y_scaler.inverse(torch.nn.Sequential(*layers)(torch.from_numpy(s.x_scaler.transform(X))).numpy())
    np.testing.assert_allclose(s.forward(X), ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    np.testing.assert_allclose(s.forward(X, single=True), ref, rtol=0, atol=2e-6 * np.abs(ref).max())
    assert s.forward(X[:0]).shape == (0, 7)


def test_secant_weights_turn_increment_errors_into_secant_errors():
    from hmodel.surrogate.formulations.meso_rollout import secant_weights
    e = np.array([[3.0, 4.0], [0.3, 0.4], [0.0, 0.0], [0.03, 0.04]])  # |e| = 5, 0.5, 0, 0.05
    w = secant_weights(e, 0.1)
    np.testing.assert_allclose(w, [1 / 25, 4.0, 100.0, 100.0])
    # the same secant error weighs the same, whatever the increment's size
    dz_err = np.linalg.norm(e[:2], axis=1) * 0.01
    np.testing.assert_allclose(w[:2] * dz_err ** 2, 1e-4)
    with pytest.raises(InputError, match="secant_floor"):
        TrainConfig(formulation="meso", secant_floor=-1.0)
    with pytest.raises(InputError, match="meso"):
        TrainConfig(formulation="increment", secant_floor=1e-4)


def test_forward_is_bitwise_the_same_on_any_number_of_threads():
    """Inference runs every product on one BLAS thread and splits large batches into the same
    blocks across threads: its outputs are bit for bit those of one block at a time on one
    thread, whatever BLAS was allowed, and no product inside runs on more threads."""
    from threadpoolctl import threadpool_info, threadpool_limits

    from hmodel.surrogate.model import BLOCK_ROWS, SPLIT_ROWS
    from hmodel.surrogate.shipped import load_shipped

    s = load_shipped()
    lo, hi = s.input_range
    X = lo + (hi - lo) * np.random.default_rng(0).uniform(size=(SPLIT_ROWS + BLOCK_ROWS // 2, len(lo)))
    seen = []
    inner = s._forward

    def spy(*args):
        seen.append(max((i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"), default=1))
        return inner(*args)

    for single in (False, True):
        with threadpool_limits(1):  # reference: one block at a time on one thread
            ref = np.concatenate([inner(X[i:i + BLOCK_ROWS], single, 0) for i in range(0, len(X), BLOCK_ROWS)])
        s._forward = spy
        for threads in (1, 2, 4):
            with threadpool_limits(threads, user_api="blas"):
                np.testing.assert_array_equal(s.forward(X, single=single), ref)  # split across threads
                np.testing.assert_array_equal(s.forward(X[:360], single=single), ref[:360])  # one thread
        del s._forward
    assert seen and set(seen) == {1}
    assert pickle.loads(pickle.dumps(s)).forward(X[:7]).tolist() == s.forward(X[:7]).tolist()


def test_every_formulation_declares_what_the_solver_and_training_read():
    """Every registered formulation is a Formulation: what the solver and the training code read
    of it is declared, with an H-cell formulation's defaults where it keeps them."""
    from hmodel.surrogate.formulations import FORMULATIONS, Formulation

    p = Params()
    forms = {name: make_formulation(name, p) for name in FORMULATIONS}
    forms["meso-rich"] = make_formulation("meso", p, "dem:hexagon-center")
    assert all(isinstance(f, Formulation) for f in forms.values())
    cols = {"deps1": np.zeros(2)}
    for name in ("report", "increment", "report-leak", "compliance"):
        f = forms[name]
        assert (f.richer, f.cell, f.falls_back, f.n_state, f.outputs) == (False, "closed-form", True, 8, OUTPUTS)
        assert f.augment(cols) is cols and f.meso(np.zeros((2, 8))) is None
        assert f.fits("dem:standard") and not f.fits("dem:hexagon-center")
        assert f.needs_answer == (name == "report-leak")
        assert f.state_only == f.ensembles == (name == "compliance")
    with pytest.raises(TypeError, match="not those of a state alone"):
        forms["increment"].features(np.zeros((2, 8)))
    h, rich = forms["meso"], forms["meso-rich"]
    assert h.state_only and h.ensembles and not h.falls_back and not h.richer and rich.richer
    assert rich.fits("dem:hexagon-center") and not rich.fits("closed-form")
    assert h.outputs == OUTPUTS + ("Vs_nn_next", "Vs_tt_next") and h.n_state == 11


def test_a_formulation_steps_cells_through_the_networks_interface_only():
    """A formulation's increment asks its networks for outputs and nothing else (no counts, no
    fallback of the solver's): the solver's step is the formulation's Increment where no cell
    leaves the training domain, and the solver keeps the counts."""
    from hmodel.cell import CellState
    from hmodel.cell.closed_form import ClosedFormSolver
    from hmodel.surrogate.formulations.base import Increment
    from hmodel.surrogate.shipped import load_shipped
    from hmodel.surrogate.solver import SurrogateSolver

    for name in ("increment", "default"):
        m = load_shipped(name)
        p = Params.from_dict(m.meta["params"])
        solver = SurrogateSolver(m)

        class Networks:  # exactly base.Networks: evaluation, nothing of the solver's state
            def __init__(self, model):
                self.m = model

            def forward(self, X):
                return self.m.forward(X)

            def outside(self, X):
                return self.m.outside(X, 0.0)

            def outputs(self, v, X=None):
                f = self.m.formulation
                X = f.features(v) if X is None else X
                return [self.m.forward(X, single=f.single_precision, spare=f.spare_columns)], self.m.outside(X, 0.0)

        th = np.linspace(-0.5, 2.0, 7)
        dl = np.column_stack([-p.l10 * 2e-4 * np.cos(th), -p.l20 * 2e-4 * np.sin(th)])
        st = ClosedFormSolver().step(p, CellState.initial(p, (7,)), dl[:, 0], dl[:, 1])[0]  # distinct states
        inc = m.formulation.step_cells(Networks(m), p, st.values, -dl[:, 0] / p.l10, -dl[:, 1] / p.l20, dl)
        assert isinstance(inc, Increment) and not inc.outside.any()
        new, flags = solver.step(p, st, dl[:, 0], dl[:, 1])
        np.testing.assert_array_equal(new.values, inc.new)
        np.testing.assert_array_equal(flags.flags, inc.flags)
        assert solver.counts["cell_updates"] == 7 and solver.counts["network_cells"] == 7
