"""The ``meso`` formulation (surrogates of richer cells through a summary state), without YADE."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from hmodel import Params
from hmodel.cell import CellSolver, CellState
from hmodel.cell.base import STATE_OWN
from hmodel.cell.closed_form import ClosedFormSolver
from hmodel.cell.mesostress import meso_vsigma
from hmodel.compare import deviations, run_path, standard_paths
from hmodel.data import DatasetSpec, generate
from hmodel.data.sampling import write_split
from hmodel.errors import InputError
from hmodel.surrogate.formulations.registry import make_formulation
from hmodel.surrogate.formulations.meso import STATE_FIELDS, MesoFormulation
from hmodel.surrogate.modelfile import load, save
from hmodel.surrogate.solver import SurrogateSolver
from hmodel.surrogate.training import TrainConfig, train_on_sample
from hmodel.surrogate.training_rows import read_sample

PARAMS = Params(sliding_rhs="equilibrium", n_theta=12)


class SummaryOfClosedForm(CellSolver):
    """The closed form behind the meso formulation's summary-state interface: what a perfect
    meso surrogate would be."""

    name = "summary-of-closed-form"
    stress_rtol = 0.0
    bytes_per_cell = 1024
    n_lengths = 2
    state_kind = STATE_OWN

    def __init__(self, form: MesoFormulation):
        self.form, self.cf = form, ClosedFormSolver()

    def initial(self, params, shape=()):
        return self.form.initial(params, shape)

    def initial_cells(self, params, alpha0):
        return self.initial(params, np.shape(alpha0))

    def fractions(self, params, state):
        return {}

    def kernel(self, params):  # the generic driver
        return None

    def meso(self, params, state):
        return self.form.meso(np.asarray(state.values))

    def step(self, params, state, dl1, dl2):
        v = state.values
        new, flags = self.cf.step(params, CellState(np.ascontiguousarray(v[..., :8])), dl1, dl2)
        return CellState(self.form.summary(new.values.reshape(-1, 8)).reshape(*v.shape[:-1], 11)), flags


def _cells(n=40, steps=30, seed=0):
    """Closed-form cells loaded along random directions (sticking, sliding, open)."""
    rng = np.random.default_rng(seed)
    th = rng.uniform(-np.pi / 3, 5 * np.pi / 6, n)
    st = CellState.initial(PARAMS, (n,))
    cf = ClosedFormSolver()
    for _ in range(steps):
        st, _ = cf.step(PARAMS, st, -PARAMS.l10 * 1e-3 * np.cos(th), -PARAMS.l20 * 1e-3 * np.sin(th))
    return st


def test_summary_of_h_cells_is_eq_1_12_and_volume_is_the_hexagon():
    form = MesoFormulation(PARAMS)
    st = _cells()
    z = form.summary(st.values)
    assert z.shape == (40, len(STATE_FIELDS))
    np.testing.assert_array_equal(z[:, :8], st.values)
    np.testing.assert_allclose(z[:, 8:10], meso_vsigma(PARAMS, st), rtol=1e-12)
    assert np.all(z[:, 10] == 0.0)
    vs, vol = form.meso(z)
    d1, d2, a = st.d1, st.d2, st.alpha
    np.testing.assert_allclose(vol, 2 * d1 * np.sin(a) * (d2 + d1 * np.cos(a)), rtol=1e-9)  # eq. 1.20


def test_rev_through_the_summary_interface_is_the_closed_form_rev():
    """The REV's meso-stress path (V sigma and V from the solver) with the summary of the
    closed form's cells reproduces the closed-form REV: the summary loses nothing the REV uses."""
    form = MesoFormulation(PARAMS)
    paths = {s.name: s for s in standard_paths(0.02)}
    for spec in (replace(paths["drained"], p0=(1e5,)), paths["undrained"]):
        ref, _ = run_path(PARAMS, spec, "closed-form", 1e-3, 2e-4)
        res, _ = run_path(PARAMS, spec, SummaryOfClosedForm(form), 1e-3, 2e-4)
        for d in deviations(ref, res):
            assert d["rows"] == len(ref.point(0)) and d["q_max_dev_rel"] < 1e-9


def test_head_is_positively_homogeneous_continuous_and_matches_torch():
    """dz(e) = A e + sum_k <n_k . e - c_k^2> B_k: zero for no strain, the NumPy and torch
    evaluations agree, a mechanism acts past its threshold only."""
    import torch

    form = MesoFormulation(PARAMS)
    rng = np.random.default_rng(1)
    out = rng.normal(size=(5, form.n_outputs))
    e = rng.normal(size=(5, 2)) * 1e-3
    y = form.increment(out, e[:, 0], e[:, 1])
    t = form.head(torch.as_tensor(out), torch.as_tensor(e / form.m0)).numpy()
    np.testing.assert_allclose(y, t, rtol=1e-12)
    no_threshold = out.copy()
    no_threshold[:, [10 + 7 * k for k in range(4)]] = 0.0  # c_k = 0: positively homogeneous
    y0 = form.increment(no_threshold, e[:, 0], e[:, 1])
    np.testing.assert_allclose(form.increment(no_threshold, 2.5 * e[:, 0], 2.5 * e[:, 1]), 2.5 * y0, rtol=1e-12)
    assert np.all(form.increment(out, 0 * e[:, 0], 0 * e[:, 1]) == 0.0)
    # one mechanism, by hand: A = 0, n = (1, 0), c^2 = 0.25, B = 1 -> dz = <e1/m0 - 0.25>
    one = MesoFormulation(PARAMS, mechanisms=1)
    o = np.zeros((3, one.n_outputs))
    o[:, 8:11] = [1.0, 0.0, 0.5]
    o[:, 11:] = 1.0
    dz = one.increment(o, np.array([1e-3, -1e-3, 2e-4]), np.array([5e-4, 5e-4, 0.0]))
    np.testing.assert_allclose(dz, [[0.75] * 4, [0.0] * 4, [0.0] * 4], atol=1e-15)


def test_refusals():
    form = MesoFormulation(PARAMS, "dem:hexagon-center")
    cols = {k: np.zeros(3) for k in ("deps1", "deps2", "d1", "d2", "alpha", "N1", "N2", "T1", "l1", "l2")}
    with pytest.raises(InputError, match="state_extra"):
        form.augment(cols)
    with pytest.raises(InputError, match="--formulation meso"):
        make_formulation("compliance", PARAMS, "dem:hexagon-center")
    for cell in ("surrogate", "dem:bihexagon"):  # learned cells; the 3D model's (three lengths)
        with pytest.raises(InputError, match="H-cell or DEM data"):
            MesoFormulation(PARAMS, cell)


def test_the_summary_takes_the_cells_from_their_solver():
    """The data's cells as the registry resolves their spec: their geometry and unloaded state
    (the closed form's exactly: the standard DEM cell's differs from it at round-off)."""
    h, std, rich = (MesoFormulation(PARAMS, c) for c in ("closed-form", "dem:standard", "dem:hexagon-center"))
    assert h.geometry.standard and std.geometry.standard and rich.geometry.mesostructure == "hexagon-center"
    np.testing.assert_array_equal(h.initial(PARAMS, (1,)).values[0, :8], CellState.initial(PARAMS, (1,)).values[0])


def test_richer_cells_learn_the_meso_stress_h_cells_take_eq_1_12():
    h = MesoFormulation(PARAMS)
    rich = MesoFormulation(PARAMS, "dem:hexagon-center")
    assert not h.richer and h.n_outputs == 8 + 4 * 7 and h.learned == ("alpha", "N1", "N2", "T1")
    assert rich.richer and rich.n_outputs == 12 + 4 * 9 and rich.learned[-2:] == ("Vs_nn", "Vs_tt")
    # the way back: a separated hexagon contact carries no force, whatever the network says
    st = _cells(1, steps=5)
    z = h.summary(st.values)
    Y = np.zeros((1, 4))
    Y[0, 1] = 1e3  # a large learned N1 increment
    new, _ = h.advance(z, Y, np.array([[0.0, 0.5]]))  # l2 grows by r/2: grains 1, 2 apart
    assert new[0, 0] > 2 * PARAMS.radius and new[0, 3] == 0.0 and new[0, 5] == 0.0


def test_tiny_meso_model_round_trip_metrics_and_rev(tiny_model):
    model, tmp = tiny_model
    assert model.formulation.name == "meso" and model.formulation.cell == "closed-form"
    names = {r["output"] for r in model.meta["metrics"]}
    assert {"Vs_nn_next", "Vs_tt_next", "dVs_nn"} <= names
    s = SurrogateSolver(model, on_outside="fallback")
    z0 = s.initial(PARAMS, (3,))
    assert z0.values.shape == (3, 11) and np.all(z0.values[:, [3, 4, 5, 8, 9, 10]] == 0)
    same, _ = s.step(PARAMS, z0, np.zeros(3), np.zeros(3))
    # no strain, no change (forces from the geometry: round-off of eq. 1.2, 1e-15 of kn 2r)
    np.testing.assert_allclose(same.values, z0.values, rtol=1e-14, atol=1e-15 * PARAMS.kn * 4 * PARAMS.radius ** 2)
    paths = {p.name: p for p in standard_paths(0.005)}
    res, _ = run_path(PARAMS, replace(paths["drained"], p0=(1e5,)), s, 1e-3, 2e-4)
    q = np.asarray(res.point(0)["q"])
    assert np.all(np.isfinite(q)) and q[-1] > 0
    assert s.counts["network_cells"] > 0


def test_sample_of_a_richer_dataset_keeps_the_extra_state(tmp_path):
    """A sample of a richer-cell dataset carries state_extra (rows, n_extra), checked on a
    dataset whose shards we write with a DEM layout from closed-form cells (no YADE here)."""
    import json

    import pyarrow.parquet as pq

    from hmodel.data import Dataset

    spec = DatasetSpec(kind=2, n_directions=2, theta_min=0.0, theta_max=90.0, alpha0_min=45.0,
                       alpha0_max=45.0, max_strain=0.002, step=0.001, start_every=0.002,
                       magnitude=0.002, n_increments=4, substeps=1)
    ds = generate(spec, PARAMS, tmp_path / "data")
    # add two extra columns to the shards and name them in the manifest: the layout of a richer cell
    from hmodel.data.generator import _table
    from hmodel.data.schema import column_array
    from hmodel.data.store import sha256
    m = json.loads((tmp_path / "data" / "manifest.json").read_text())
    for e in m["shards"]:
        path = tmp_path / "data" / e["file"]
        t = pq.read_table(path)
        c = {k: column_array(t, k) for k in t.column_names}
        before = np.column_stack([c[k] for k in ("d1", "d2", "alpha", "N1", "N2", "T1", "l1", "l2")]
                                 + [c["N1"], c["T1"]])
        after = np.column_stack([c[f"{k}_next"] for k in ("d1", "d2", "alpha", "N1", "N2", "T1", "l1", "l2")]
                                + [c["N1_next"], c["T1_next"]])
        flags = np.column_stack([c[k] for k in ("sliding", "open1", "open2", "contact14", "contact26")])
        labels = (c["alpha0"], c["path_id"], c["theta"], c["start_strain"])
        pq.write_table(_table(np.column_stack([c["deps1"], c["deps2"]]), before, after, flags, labels), path)
        e["sha256"] = sha256(path)
    m["columns"] += ["state_extra", "state_extra_next"]
    m["extra_fields"] = ["a", "b"]
    (tmp_path / "data" / "manifest.json").write_text(json.dumps(m))
    ds = Dataset.open(tmp_path / "data")
    assert ds.n_extra == 2 and ds.read(["state_extra"])["state_extra"].shape == (ds.n_rows, 2)
    write_split(ds, tmp_path / "sample", 4, 2)
    cols, info = read_sample(tmp_path / "sample", "train")
    assert cols["state_extra"].shape == (4, 2) and info["provenance"]["extra_fields"] == ["a", "b"]
    np.testing.assert_array_equal(cols["state_extra"][:, 0], cols["N1"])
    np.testing.assert_array_equal(cols["state_extra_next"][:, 1], cols["T1_next"])


def test_training_on_several_samples_takes_their_union(tiny_model, tmp_path):
    """A second sample (cells consolidated first: ``prestrain``) trains together with the first;
    the provenance lists both; samples of another material are refused."""
    _, tmp = tiny_model
    spec = DatasetSpec(kind=2, n_directions=4, theta_min=-60.0, theta_max=150.0, alpha0_min=45.0,
                       alpha0_max=45.0, max_strain=0.01, step=0.001, start_every=0.002,
                       magnitude=0.002, magnitude_min=0.0, n_increments=12, substeps=1,
                       prestrain=0.001, from_unloaded=True)
    ds = generate(spec, Params(sliding_rhs="equilibrium"), tmp_path / "data")
    write_split(ds, tmp_path / "sample", 200, 50)
    cfg = TrainConfig(formulation="meso", width=16, depth=1, epochs=2, patience=2, device="cpu")
    model, _ = train_on_sample([tmp / "sample", tmp_path / "sample"], cfg)
    assert [p["source_checksum"] for p in model.meta["training_data"]] == [
        read_sample(tmp / "sample", "train")[1]["provenance"]["source_checksum"], ds.checksum]
    assert model.meta["train_rows"] + model.meta["val_rows"] == 700 + 200
    # both samples count their paths from 0: in the union they stay apart, so the rollout windows
    # of the union are those of each sample (none chains one sample's states to another's)
    from hmodel.surrogate.training import union
    parts = [read_sample(f, "train")[0] for f in (tmp / "sample", tmp_path / "sample")]
    form = MesoFormulation(Params(sliding_rhs="equilibrium"), "closed-form")
    n = [form.windows(c, 3)["mask"].sum() for c in parts]
    assert form.windows(union(parts), 3)["mask"].sum() == sum(n) and min(n) > 0
    other = generate(spec, Params(sliding_rhs="equilibrium", kn=1e8), tmp_path / "other")
    write_split(other, tmp_path / "other-sample", 200, 50)
    with pytest.raises(InputError, match="share the material"):
        train_on_sample([tmp / "sample", tmp_path / "other-sample"], cfg)



def test_windows_follow_the_paths_start_states(tiny_model):
    """Rollout windows chain a path's consecutive start states: the strain step along theta,
    the length change, the learned fields after each step; they stop at the path's end and
    where a start state is missing."""
    from hmodel.data import Dataset

    _, tmp = tiny_model
    form = MesoFormulation(PARAMS, "closed-form")
    c = form.augment(Dataset.open(tmp / "data").read())
    w = form.windows(c, 3)
    n_paths, n_starts = 8, 10  # 0.002 ... 0.02: starts along each path (no unloaded one)
    assert len(w["z0"]) == n_paths * (n_starts - 1)
    assert w["mask"].sum(0).tolist() == [n_paths * (n_starts - k) for k in (1, 2, 3)]
    first = (c["path_id"] == 0) & np.isclose(c["start_strain"], 0.002)
    second = (c["path_id"] == 0) & np.isclose(c["start_strain"], 0.004)
    i = np.flatnonzero(np.isclose(w["z0"][:, 6], c["l1"][first][0]) & np.isclose(w["z0"][:, 7], c["l2"][first][0]))
    assert len(i) == 1
    th = c["theta"][first][0]
    np.testing.assert_allclose(w["e"][i[0], 0], 0.002 * np.array([np.cos(th), np.sin(th)]) / form.m0)
    np.testing.assert_allclose(w["dl"][i[0], 0], [c["l1"][second][0] - c["l1"][first][0],
                                                  c["l2"][second][0] - c["l2"][first][0]])
    np.testing.assert_allclose(w["target"][i[0], 0], [c[k][second][0] for k in form.learned])
    # a start state the data lacks ends the windows through it
    gone = (c["path_id"] == 0) & np.isclose(c["start_strain"], 0.008)
    w2 = form.windows({k: v[~gone] for k, v in c.items()}, 3)
    assert w2["mask"].sum() < w["mask"].sum() - 3


def test_a_jump_of_the_cell_is_left_out_of_the_loss(tiny_model):
    """With ``max_secant``, the rows whose secant |dz|/|de| jumps past it weigh nothing and the
    rollout windows end before the step that jumps; without it, every row counts (as before)."""
    from hmodel.data import Dataset
    from hmodel.surrogate.formulations.meso_rollout import jumps

    _, tmp = tiny_model
    form = MesoFormulation(PARAMS, "closed-form")
    c = form.augment(Dataset.open(tmp / "data").read())
    w = form.windows(c, 3, max_secant=10.0, floor=0.25)
    # the closed form never jumps: the cut leaves every window as it was
    assert w["mask"].sum() == form.windows(c, 3)["mask"].sum()
    # alpha snapped by 0.1 rad at one start state of path 0 (a secant of 50 over its 0.002 steps)
    snapped = dict(c)
    at = (c["path_id"] == 0) & np.isclose(c["start_strain"], 0.010)
    snapped["alpha"] = np.where(at, c["alpha"] + 0.1, c["alpha"])
    w3 = form.windows(snapped, 3, max_secant=10.0, floor=0.25)
    # cut: the windows from 0.004 (its 3rd step), 0.006 (2nd, 3rd), 0.008 and 0.010 (all of each)
    assert w3["mask"].sum() == w["mask"].sum() - 9 and len(w3["z0"]) == len(w["z0"]) - 2
    # rows: the secant of each field, the increment taken as at least the floor
    Y = np.array([[0.5, 1.0], [30.0, 0.0], [0.0, -3.0], [0.0, 2.0]])  # secants 1, 6, 12, 4
    e = np.array([[1.0, 0.0], [3.0, 4.0], [0.0, 0.1], [0.0, 0.5]])
    np.testing.assert_array_equal(jumps(Y, e, 5.0, 0.25), [False, True, True, False])
    cfg = TrainConfig(formulation="meso", max_secant=5.0, secant_floor=2.5e-4)
    W = form.row_weights(Y, np.ones_like(Y), e, cfg)
    assert (W[[1, 2]] == 0).all() and (W[[0, 3]] > 0).all()
    np.testing.assert_array_equal(form.row_weights(Y, np.ones_like(Y), e, replace(cfg, max_secant=0.0)) > 0, True)
    with pytest.raises(InputError, match="max_secant"):
        TrainConfig(formulation="meso", max_secant=-1.0)
    with pytest.raises(InputError, match="meso"):
        TrainConfig(formulation="increment", max_secant=10.0)


@pytest.mark.parametrize("substeps", [1, 3])
def test_rollout_error_rolls_out_what_the_rev_does(substeps):
    """The rollout error that training charges (torch) equals the one of the NumPy way back the
    REV uses, stepped from the same states with the same network; with sub-steps, the REV at a
    finer increment than the data's."""
    import torch

    from hmodel.surrogate.model import Architecture
    from hmodel.surrogate.training import build_network

    form = MesoFormulation(PARAMS, "dem:hexagon-center", mechanisms=3)
    rng = np.random.default_rng(3)
    n, T = 16, 4
    F, d = form.force_scale, 2 * PARAMS.radius
    z0 = np.zeros((n, 11))
    z0[:, 2] = np.radians(45) + rng.normal(0, 0.01, n)
    z0[:, 6], z0[:, 7] = PARAMS.l10 * (1 - 1e-3), PARAMS.l20 * (1 - 1e-3)
    z0[:, 3:6] = F * rng.uniform(0, 2e-4, (n, 3)) * [1, 1, 0.3]
    z0[:, 8:10] = F * d * rng.uniform(0, 1e-3, (n, 2))
    e = rng.normal(0, 1, (n, T, 2))
    dl = -np.stack([PARAMS.l10 * e[..., 0], PARAMS.l20 * e[..., 1]], axis=-1) * form.m0
    target = np.cumsum(rng.normal(0, 1, (n, T, 6)), axis=1) * form._scales() * form.m0 * 0.1 \
        + form._learned_values(z0)[:, None, :]
    mask = np.ones((n, T))
    mask[:3, 2:] = 0.0
    torch.manual_seed(0)
    net = build_network(Architecture(16, 2, "silu"), 8, form.n_outputs).double()
    off, scale = form.features(z0).mean(0), form.features(z0).std(0) + 1e-9
    as_t = lambda a: torch.as_tensor(a, dtype=torch.float64)  # noqa: E731
    with torch.no_grad():
        got = float(form.rollout_error(net.float(), *(as_t(a) for a in (z0, e, dl, target, mask)),
                                       lambda X: (X - as_t(off)) / as_t(scale), substeps))
    z, want = z0, 0.0
    for k in range(T):
        for _ in range(substeps):
            with torch.no_grad():
                out = net(torch.as_tensor((form.features(z) - off) / scale, dtype=torch.float32)).double().numpy()
            z, _ = form.advance(z, form.head(out, e[:, k] / substeps), dl[:, k] / substeps)
        err = (form._learned_values(z) - target[:, k]) / (form._scales() * form.m0)
        want += ((err ** 2).mean(1) * mask[:, k]).sum()
    assert got == pytest.approx(want / mask.sum(), rel=1e-6)


def test_rollout_training_is_refused_where_it_does_not_apply(tiny_model):
    _, tmp = tiny_model
    with pytest.raises(InputError, match="formulation meso"):
        TrainConfig(formulation="compliance", rollout=4)
    with pytest.raises(InputError, match="rollout_substeps"):
        TrainConfig(formulation="meso", rollout=4, rollout_substeps=0)
    with pytest.raises(InputError, match="richer cell"):
        train_on_sample(tmp / "sample", TrainConfig(formulation="meso", rollout=4, epochs=1, device="cpu"))


def test_a_richer_cells_geometry_needs_no_yade():
    """The summary of an unloaded hexagon-center cell, its Love-Weber stress and its layout come
    from :mod:`hmodel.cell.geometry`, which the cells' solver (resolved by the registry) declares:
    no YADE is looked for nor started, here where none can be found."""
    import os
    import subprocess
    import sys
    code = ("from hmodel import Params; from hmodel.surrogate.formulations.meso import MesoFormulation; "
            "f = MesoFormulation(Params(), 'dem:hexagon-center'); "
            "z = f.summary(f.geometry.initial(Params(), (2,)).values); "
            "assert f.richer and z.shape == (2, 11) and f.geometry.n_fields == 8 + 14 + 21; "
            "assert type(f.geometry).__module__ == 'hmodel.cell.geometry'; "
            "assert f.cell_solver._server is None, 'YADE started'")
    env = {**os.environ, "HMODEL_YADE": os.path.join(os.sep, "nonexistent", "yade")}
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert run.returncode == 0, run.stderr


def test_a_loose_cage_holds_its_free_grain_without_force():
    """Hexagon-center: where the hexagon's clearance at its centre exceeds the centre grain's
    radius, V sigma is the hexagon's own (eq. 1.12 of the advanced fields), whatever the network
    says; where the cage squeezes the grain, the learned V sigma stands. Cells without free
    grains (H-cells) have no such gate."""
    form = MesoFormulation(PARAMS, "dem:hexagon-center")
    r = PARAMS.radius
    assert form._cage[0] == pytest.approx((np.sqrt(3) - 1) * r) and MesoFormulation(PARAMS)._cage[0] == 0
    F, d = form.force_scale, 2 * r
    v = np.zeros((2, 11))
    v[:, 2] = np.radians(45)
    v[:, 3], v[:, 4], v[:, 5] = 1e-4 * F, 0.5e-4 * F, 0.2e-4 * F
    v[:, 8:10] = 5e-3 * F * d
    v[:, 6], v[:, 7] = PARAMS.l10, PARAMS.l20
    dl = np.array([[0.0, 0.01 * PARAMS.l20],     # t stretched: the cage opens (clearance > rc)
                   [0.0, -0.001 * PARAMS.l20]])  # t squeezed: the centre grain is caught
    Y = np.zeros((2, len(form.learned)))
    new, _ = form.advance(v, Y, dl)
    hexagon = meso_vsigma(PARAMS, CellState(np.ascontiguousarray(new[:, :8])))
    np.testing.assert_allclose(new[0, 8:10], hexagon[0], rtol=1e-12)
    np.testing.assert_allclose(new[1, 8:10], v[1, 8:10], rtol=1e-12)
    assert not np.allclose(hexagon[1], v[1, 8:10])


def test_an_ensemble_averages_its_members_increments(tiny_model):
    """Two networks trained alike (other seed): the ensemble's learned alpha (never clipped on
    the way back) is the mean of the members' after one step; one member is the model itself;
    a compliance model, or members of other formulations, are refused."""
    model, tmp = tiny_model
    cfg = TrainConfig(formulation="meso", width=32, depth=2, activation="silu", epochs=40,
                      patience=40, device="cpu", seed=1)
    other = load(save(train_on_sample(tmp / "sample", cfg)[0], tmp / "other.safetensors"))
    form = model.formulation
    z = CellState(form.summary(_cells(n=30, steps=8).values))
    rng = np.random.default_rng(2)
    dl1, dl2 = PARAMS.l10 * rng.uniform(-1e-3, 1e-3, 30), PARAMS.l20 * rng.uniform(-1e-3, 1e-3, 30)
    a, b = (SurrogateSolver(m).step(PARAMS, z, dl1, dl2)[0].values for m in (model, other))
    ens = SurrogateSolver([model, other])
    e = ens.step(PARAMS, z, dl1, dl2)[0].values
    assert not np.allclose(a[:, 2], b[:, 2], rtol=0, atol=1e-9)  # the members differ
    np.testing.assert_allclose(e[:, 2], 0.5 * (a[:, 2] + b[:, 2]), rtol=1e-13)
    np.testing.assert_array_equal(SurrogateSolver([model]).step(PARAMS, z, dl1, dl2)[0].values, a)
    assert ens.counts["network_cells"] == 30
    # through the solver spec, as the CLI gives it
    from hmodel.solvers import get_solver
    spec = get_solver(f"surrogate:{tmp / 'meso.safetensors'}+{tmp / 'other.safetensors'}")
    np.testing.assert_array_equal(spec.step(PARAMS, z, dl1, dl2)[0].values, e)
    from hmodel.surrogate.shipped import load_shipped
    with pytest.raises(InputError, match="meso or compliance"):  # strain-input networks do not average
        SurrogateSolver([load_shipped("increment"), load_shipped("increment")])
    with pytest.raises(InputError, match="at least one"):
        SurrogateSolver([])
    with pytest.raises(InputError, match="different formulations"):
        SurrogateSolver([model, replace(other, formulation=replace(form, mechanisms=2))])


def test_a_cell_step_cuts_every_increment_into_network_steps_of_at_most_that_size(tmp_path):
    """With ``cell_step`` h, a cell increment of 3h is three network steps of h, each from the
    state the one before reached (not one step, as without it), whatever the REV increment;
    the step travels with the model file."""
    from hmodel.surrogate.shipped import load_shipped

    shipped = load_shipped("hexagon-center-0")
    model = replace(shipped, formulation=replace(shipped.formulation, cell_step=None))
    h = 2.5e-4
    stepped = replace(model, formulation=replace(model.formulation, cell_step=h))
    save(stepped, tmp_path / "m.safetensors")
    again = load(tmp_path / "m.safetensors")
    assert again.formulation.cell_step == h and again.formulation.max_increment(None) == h
    params = Params(sliding_rhs="equilibrium")
    whole, one = SurrogateSolver(again), SurrogateSolver(model)
    assert whole.kernel(params) is None and one.kernel(params) is not None
    cells = whole.initial(params, (4,))
    dl = -3 * h * params.l10 * np.array([1.0, 0.5, -0.5, 0.2])
    dl2 = 3 * h * params.l20 * np.array([0.5, -0.5, 1.0, 0.1])
    got, _ = whole.step(params, cells, dl, dl2)
    by_hand = cells
    for _ in range(3):
        by_hand, _ = one.step(params, by_hand, dl / 3, dl2 / 3)
    np.testing.assert_allclose(got.values, by_hand.values, rtol=1e-12, atol=1e-12 * np.abs(by_hand.values).max())
    in_one, _ = one.step(params, cells, dl, dl2)
    assert np.abs(in_one.values - got.values).max() > 1e-6 * np.abs(got.values).max()
    with pytest.raises(InputError, match="cell_step"):
        replace(model.formulation, cell_step=0.0)
