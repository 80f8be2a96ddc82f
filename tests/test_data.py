"""H-cell databases (report §2.3): rows, storage, resumption, cleaning rules, sampling."""

import math
import signal
import subprocess
import sys
import time

import numpy as np
import pyarrow.parquet as pq
import pytest

from hmodel import InputError, Params
from hmodel.cell import CellState
from hmodel.cell.closed_form import ClosedFormSolver
from hmodel.data import Dataset, DatasetError, DatasetSpec, generate
from hmodel.data import store
from hmodel.data.filters import RULES, kept_rows, keep_mask, parse_rules, rule_counts, rule_masks
from hmodel.data.sampling import sample_split, select, write_split
from hmodel.data.schema import COLUMNS

SMALL1 = DatasetSpec(kind=1, n_directions=7, alpha0_min=40, alpha0_max=60, alpha0_step=10,
                     max_strain=0.1, step=0.001, shard_rows=500)
SMALL2 = DatasetSpec(kind=2, n_directions=5, alpha0_min=35, alpha0_max=45, alpha0_step=10,
                     max_strain=0.2, step=0.001, start_every=0.04, n_increments=24, shard_rows=400)


@pytest.fixture(scope="module")
def d2(tmp_path_factory):
    return generate(SMALL2, Params(), tmp_path_factory.mktemp("d") / "d2")


@pytest.fixture(scope="module")
def d1(tmp_path_factory):
    return generate(SMALL1, Params(), tmp_path_factory.mktemp("d") / "d1")


def checksums(ds):
    return [e["sha256"] for e in ds.manifest["shards"]]


def _hand_state(row, prefix=""):
    return CellState.from_fields(**{f: row[f + prefix] for f in ("d1", "d2", "alpha", "N1", "N2",
                                                                  "T1", "l1", "l2")})


def test_default_specs_reproduce_the_report_scale():
    one, two = DatasetSpec(kind=1), DatasetSpec(kind=2)
    assert one.n_steps == 300 and two.start_steps.tolist() == list(range(10, 301, 10))
    assert 7e5 <= one.n_rows <= 8.5e5  # ≈ 7e5 rows after the report's cleaning (measured 717,072)
    assert 1.2e7 <= two.n_rows <= 1.4e7  # ≈ 1.2e7 after cleaning (measured 12.0 M)
    assert one.alpha0_deg[0] == 32 and one.alpha0_deg[-1] == 88


def test_dataset2_row_equals_the_cell_solver_with_ten_substeps(d2):
    params = Params()
    cols = d2.read()
    rng = np.random.default_rng(0)
    for i in rng.choice(d2.n_rows, 25, replace=False):
        row = {c: cols[c][i] for c in COLUMNS}
        a0 = row["alpha0"]
        # initial lengths by hand from eq. 1.2 with d1 = d2 = 2r = 2
        l10, l20 = 2 + 4 * math.cos(a0), 4 * math.sin(a0)
        state = _hand_state(row)
        for _ in range(10):
            state, flags = ClosedFormSolver().step(params, state, -l10 * row["deps1"] / 10,
                                                   -l20 * row["deps2"] / 10)
        for f in ("d1", "d2", "alpha", "N1", "N2", "T1", "l1", "l2"):
            assert getattr(state, f) == pytest.approx(row[f + "_next"], rel=1e-12, abs=1e-9)
        assert bool(flags.sliding) == row["sliding"] and bool(flags.open1) == row["open1"]
        assert math.hypot(row["deps1"], row["deps2"]) == pytest.approx(0.01)


def test_dataset2_start_states_are_dataset1_states(d1, d2):
    # The start state at 4 % of a path is the state after 40 monotonic steps of 0.1 %.
    params = Params()
    cols = d2.read()
    row = np.flatnonzero((np.abs(cols["start_strain"] - 0.04) < 1e-12) & (cols["path_id"] == 3))[0]
    a0, th = cols["alpha0"][row], cols["theta"][row]
    l10, l20 = 2 + 4 * math.cos(a0), 4 * math.sin(a0)
    state = CellState.from_fields(d1=2.0, d2=2.0, alpha=a0, N1=0.0, N2=0.0, T1=0.0, l1=l10, l2=l20)
    for _ in range(40):
        state, _ = ClosedFormSolver().step(params, state, -l10 * 0.001 * math.cos(th), -l20 * 0.001 * math.sin(th))
    assert state.N1 == pytest.approx(cols["N1"][row], rel=1e-12)
    assert state.alpha == pytest.approx(cols["alpha"][row], rel=1e-12)


def test_dataset2_from_unloaded_adds_the_unloaded_start(tmp_path):
    from dataclasses import replace

    spec = replace(SMALL2, n_directions=2, alpha0_min=45, alpha0_max=45, max_strain=0.08,
                   from_unloaded=True)
    assert spec.start_steps[0] == 0 and len(spec.start_steps) == len(replace(spec, from_unloaded=False).start_steps) + 1
    ds = generate(spec, Params(), tmp_path / "d")
    c = ds.read()
    assert ds.n_rows == spec.n_rows == 2 * 3 * 24
    rest = c["start_strain"] == 0
    assert rest.sum() == 2 * 24
    np.testing.assert_array_equal(c["N1"][rest], 0.0)
    np.testing.assert_allclose(c["alpha"][rest], math.radians(45), rtol=1e-15)
    # the loaded starts are the same as without the option
    plain = generate(replace(spec, from_unloaded=False), Params(), tmp_path / "p").read()
    np.testing.assert_array_equal(plain["N1_next"], c["N1_next"][~rest])


def test_prestrain_starts_every_path_from_the_consolidated_cell(tmp_path):
    from dataclasses import replace

    spec = replace(SMALL2, n_directions=2, alpha0_min=45, alpha0_max=45, max_strain=0.04,
                   from_unloaded=True, prestrain=0.002)
    c = generate(spec, Params(), tmp_path / "d").read()
    cf, params = ClosedFormSolver(), Params()
    a0 = math.radians(45)
    l10, l20 = 2 + 4 * math.cos(a0), 4 * math.sin(a0)
    state = CellState.from_fields(d1=2.0, d2=2.0, alpha=a0, N1=0.0, N2=0.0, T1=0.0, l1=l10, l2=l20)
    for _ in range(2):  # two isotropic steps of 0.1 %
        state, _ = cf.step(params, state, -l10 * 0.001, -l20 * 0.001)
    rest = np.flatnonzero(c["start_strain"] == 0)
    assert state.N1 == pytest.approx(c["N1"][rest[0]], rel=1e-12) and state.N1 > 0
    # increments are strains on the initial lengths: the row's l1 change is -l10 deps1
    np.testing.assert_allclose(c["l1_next"] - c["l1"], -l10 * c["deps1"], rtol=1e-9, atol=1e-15)
    with pytest.raises(InputError, match="prestrain"):
        replace(spec, prestrain=0.0015)


def test_dataset3_starts_from_the_cells_of_a_rev_along_its_loading(tmp_path):
    """Dataset 3: the increments of Dataset 2 from the states of a REV's cells, consolidated to p0
    then sheared drained or undrained: the start states are those of the same REV run by hand,
    every cell of the consolidated isotropic REV is alike, and each row is one solver step."""
    from dataclasses import replace

    from hmodel.loading.named_paths import biaxial, consolidate
    from hmodel.rev import Rev

    spec = DatasetSpec(kind=3, n_directions=8, max_strain=0.004, step=0.001, start_every=0.002,
                       magnitude=0.001, n_increments=4, substeps=2, from_unloaded=True,
                       rev_paths="drained:1e5,undrained:2e5")
    ds = generate(spec, Params(), tmp_path / "d3")
    c = ds.read()
    assert ds.n_rows == spec.n_rows == 2 * 8 * 3 * 4 and len(ds.shards()) == 2
    assert sorted(set(c["path_id"])) == list(range(16))
    np.testing.assert_allclose(np.unique(c["theta"]), np.arange(8) * np.pi / 8)
    np.testing.assert_allclose(np.unique(c["start_strain"]), [0.0, 0.002, 0.004])
    params = Params(n_theta=8)
    for loading, (name, p0) in enumerate(spec.rev_loadings):
        rev = Rev(params)
        s = consolidate(rev, [p0], step=0.0002)
        rows = (c["path_id"] // 8 == loading)
        rest = rows & (c["start_strain"] == 0)
        assert np.ptp(c["N1"][rest]) <= 1e-12 * c["N1"][rest].max() and c["N1"][rest].min() > 0
        for strain in (0.002, 0.004):
            for _ in range(2):
                s = biaxial(rev, s, 0.001, undrained=name == "undrained",
                            lateral_stress=None if name == "undrained" else [p0], step=0.001)
            at = rows & np.isclose(c["start_strain"], strain)
            cell = c["path_id"][at] % 8
            np.testing.assert_array_equal(c["N2"][at], s.cells.values[0, cell, 4])
            np.testing.assert_array_equal(c["l1"][at], s.cells.values[0, cell, 6])
        assert name == "undrained" or s.sig[0, 1] == pytest.approx(p0, rel=1e-6)
    i = 37  # any row: the state after is the solver's, in two sub-steps on the initial lengths
    cf = ClosedFormSolver()
    state = _hand_state({k: c[k][i] for k in c})
    a0 = math.radians(45)
    for _ in range(2):
        state, _ = cf.step(Params(), state, -(2 + 4 * math.cos(a0)) * c["deps1"][i] / 2,
                           -4 * math.sin(a0) * c["deps2"][i] / 2)
    assert state.N1 == pytest.approx(c["N1_next"][i], rel=1e-12, abs=1e-9)
    assert state.alpha == pytest.approx(c["alpha_next"][i], rel=1e-14)
    with pytest.raises(InputError, match="prestrain"):
        replace(spec, prestrain=0.001)


def test_dataset1_rows_hold_initial_state_and_total_strain(d1):
    c = d1.read()
    assert len(c["deps1"]) == d1.n_rows == SMALL1.n_rows
    np.testing.assert_array_equal(c["N1"], 0.0)
    np.testing.assert_allclose(c["d1"], 2.0)
    np.testing.assert_allclose(c["l1"], 2 + 4 * np.cos(c["alpha0"]), rtol=1e-14)
    total = np.hypot(c["deps1"], c["deps2"])
    np.testing.assert_allclose(total.reshape(-1, 100)[0], 0.001 * np.arange(1, 101), rtol=1e-12)
    np.testing.assert_allclose(np.arctan2(c["deps2"], c["deps1"]), c["theta"], atol=1e-12)
    # Compression along theta shortens the cell; l_next follows eq. 1.1 on the initial lengths.
    np.testing.assert_allclose(c["l1_next"], c["l1"] * (1 - c["deps1"]), rtol=1e-10)


def test_parquet_schema_metadata_holds_parameters_and_units(d2):
    import json
    meta = json.loads(pq.read_schema(d2.shards()[0]).metadata[b"hmodel"])
    assert meta["params"]["kn"] == 2e8 and meta["units"]["N1"] == "N" and meta["units"]["alpha"] == "rad"
    assert pq.read_schema(d2.shards()[0]).names == list(COLUMNS)


def test_rows_identical_whatever_the_number_of_workers(d2, tmp_path):
    two = generate(SMALL2, Params(), tmp_path / "w2", workers=2)
    assert len(checksums(two)) > 1
    assert checksums(two) == checksums(d2)


def test_dask_local_cluster_gives_the_same_rows(d2, tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster:
        ds = generate(SMALL2, Params(), tmp_path / "dask", scheduler=cluster.scheduler_address)
    assert checksums(ds) == checksums(d2)


def test_interrupted_run_resumes_and_computes_only_missing_shards(d2, tmp_path, monkeypatch):
    out = tmp_path / "r"
    calls = []
    original = store.encode_shard

    def counting(spec, params, i):
        calls.append(i)
        if len(calls) == 3:
            raise KeyboardInterrupt  # killed while computing the third shard
        return original(spec, params, i)

    monkeypatch.setattr(store, "encode_shard", counting)
    with pytest.raises(KeyboardInterrupt):
        generate(SMALL2, Params(), out)
    with pytest.raises(DatasetError, match="incomplete"):
        Dataset.open(out)
    (out / "part-00007.parquet.part").write_bytes(b"half a shard")  # debris of a killed write
    calls.clear()
    monkeypatch.setattr(store, "encode_shard", original)
    ds = generate(SMALL2, Params(), out)
    assert checksums(ds) == checksums(d2)
    assert not list(out.glob("*.part"))


def test_a_dataset_written_before_a_parameter_existed_resumes(d2, tmp_path):
    """A manifest without a parameter added to Params since (its default is the model the rows
    were computed with) resumes; the same manifest with another value of it is refused."""
    import json
    import shutil
    out = tmp_path / "old"
    shutil.copytree(d2.folder, out)
    path = out / store.MANIFEST
    manifest = json.loads(path.read_text())
    del manifest["params"]["alpha0_spread"]
    manifest["shards"] = manifest["shards"][:1]
    manifest["complete"] = False
    path.write_text(json.dumps(manifest))
    ds = generate(SMALL2, Params(), out)
    assert ds.manifest["complete"] and checksums(ds) == checksums(d2)
    manifest["params"]["alpha0_spread"] = 5.0
    path.write_text(json.dumps(manifest))
    with pytest.raises(InputError, match="other params"):
        generate(SMALL2, Params(), out)


def test_killed_process_resumes(d2, tmp_path):
    out = tmp_path / "k"
    args = [sys.executable, "-c", "from hmodel.cli.app import main; import sys; sys.exit(main())",
            "data", "generate", "2", "--out", str(out), "--workers", "1", "--directions", "5",
            "--alpha0", "35:45:10", "--max-strain", "0.2", "--start-every", "0.04",
            "--increments", "24", "--shard-rows", "400"]
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 60
    while time.time() < deadline and proc.poll() is None:
        if list(out.glob("part-*.parquet")):  # killed after its first shard
            break
        time.sleep(0.01)
    proc.send_signal(signal.SIGKILL)
    assert proc.wait() == -signal.SIGKILL  # it was still running: the kill cut it short
    import json
    left = json.loads((out / store.MANIFEST).read_text())
    assert not left["complete"] and len(left["shards"]) < SMALL2.n_shards, left
    assert len(list(out.glob("part-*.parquet"))) < SMALL2.n_shards
    with pytest.raises(DatasetError, match="incomplete"):
        Dataset.open(out)
    ds = generate(SMALL2, Params(), out)
    assert checksums(ds) == checksums(d2) and ds.manifest["complete"]


@pytest.mark.parametrize("damage", ["flip", "truncate", "delete"])
def test_altered_shard_is_refused_and_regenerated(d2, tmp_path, damage):
    import shutil
    out = tmp_path / "t"
    shutil.copytree(d2.folder, out)
    shard = out / "part-00001.parquet"
    data = bytearray(shard.read_bytes())
    if damage == "flip":
        data[len(data) // 2] ^= 0xFF
        shard.write_bytes(bytes(data))
    elif damage == "truncate":
        shard.write_bytes(bytes(data[: len(data) // 2]))
    else:
        shard.unlink()
    with pytest.raises(DatasetError, match="part-00001"):
        Dataset.open(out)
    assert checksums(generate(SMALL2, Params(), out)) == checksums(d2)
    Dataset.open(out)


def test_manifest_mismatches_are_refused(d2, tmp_path):
    import json
    import shutil
    with pytest.raises(InputError, match="other options"):
        generate(DatasetSpec(**{**SMALL2.to_dict(), "n_increments": 12}), Params(), d2.folder)
    with pytest.raises(InputError, match="other params"):
        generate(SMALL2, Params(kn=1e8), d2.folder)
    out = tmp_path / "v"
    shutil.copytree(d2.folder, out)
    m = json.loads((out / "manifest.json").read_text())
    m["schema_version"] = 99
    (out / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(DatasetError, match="schema version"):
        Dataset.open(out)
    (out / "manifest.json").write_text("{not json")
    with pytest.raises(DatasetError, match="not a valid manifest"):
        Dataset.open(out)


@pytest.mark.parametrize("bad", [
    dict(kind=3), dict(n_directions=0), dict(alpha0_min=30), dict(alpha0_max=90), dict(step=0),
    dict(max_strain=0.1005), dict(kind=2, start_every=0.0015), dict(magnitude=float("nan")),
    dict(substeps=0), dict(max_strain=1.5), dict(kind=3, rev_paths="sheared:1e5"),
    dict(kind=3, rev_paths="drained:-1e5"), dict(kind=3, rev_paths="drained"), dict(rev_paths="drained:1e5"),
])
def test_bad_generator_options(bad):
    with pytest.raises(InputError):
        DatasetSpec(**bad)


def test_each_rule_removes_exactly_what_it_should():
    r = 1.0
    c = {k: np.zeros(6) for k in COLUMNS}
    c.update(l1=np.array([3, 1.9, 3, 3, 3, 3.0]), l2=np.array([3, 3, 2.5, 3, 3, 3.0]),
             l1_next=np.array([3, 3, 1.99, 3, 3, 3.0]), l2_next=np.array([3, 3, 3, 1.5, 3, 3.0]),
             open1=np.array([0, 0, 0, 0, 1, 0], bool), open2=np.array([0, 0, 0, 0, 0, 1], bool),
             N1=np.array([1, 1, 1, 1, 0, 0.0]), N2=np.array([1, 1, 1, 1, 0, 0.0]),
             start_strain=np.array([0.01, 0.01, 0.01, 0.01, 0.02, 0.0]))
    c["T1"] = np.array([0, 0, 0, 0, 0, np.nan])
    m = rule_masks(c, tuple(RULES), r)
    assert m["short"].tolist() == [False, False, True, True, False, False]
    assert m["short-input"].tolist() == [False, True, False, False, False, False]
    assert m["broken"].tolist() == [False, False, False, False, True, True]
    assert m["unloaded-input"].tolist() == [False, False, False, False, True, False]
    assert m["non-finite"].tolist() == [False] * 5 + [True]
    assert keep_mask(c, ("short", "broken"), r).tolist() == [True, True, False, False, False, False]


def test_rule_counts_and_kept_rows_on_a_dataset(d2):
    c = d2.read(["l1_next", "l2_next", "open1", "open2"])
    short = (c["l1_next"] < 2) | (c["l2_next"] < 2)
    broken = c["open1"] | c["open2"]
    counts = rule_counts(d2, ("short", "broken"))
    assert counts["short"] == short.sum() > 0 and counts["broken"] == broken.sum() > 0
    assert counts["total"] == (short | broken).sum()
    np.testing.assert_array_equal(kept_rows(d2, ("short", "broken")), np.flatnonzero(~(short | broken)))
    assert parse_rules("none") == () and parse_rules(None) == ("short", "non-finite")
    with pytest.raises(InputError, match="bogus"):
        parse_rules("short,bogus")


@pytest.mark.parametrize("method", ["random", "grid", "lhs"])
def test_sampling_sizes_disjoint_reproducible(d2, method):
    tr, te = sample_split(d2, 300, 100, method, seed=7)
    assert len(tr) == 300 and len(te) == 100 and len(np.intersect1d(tr, te)) == 0
    assert len(np.unique(tr)) == 300
    kept = kept_rows(d2, ("short", "non-finite"))
    assert np.isin(tr, kept).all() and np.isin(te, kept).all()
    tr2, te2 = sample_split(d2, 300, 100, method, seed=7)
    np.testing.assert_array_equal(tr, tr2)
    np.testing.assert_array_equal(te, te2)
    assert not np.array_equal(tr, sample_split(d2, 300, 100, method, seed=8)[0])


def _occupied_strata(X, n):
    """Fraction of the n equal-probability strata of each column that hold a sampled row."""
    from scipy.stats import rankdata
    out = []
    for j in range(X.shape[1]):
        u = (rankdata(X[:, j]) - 0.5) / len(X)
        out.append(len(np.unique(np.floor(u * n))) / n)
    return np.array(out)


def test_lhs_stratifies_every_column_better_than_random():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(20000, 4)) * [1, 10, 100, 0.01] + rng.exponential(size=(20000, 4))
    n = 400
    lhs = X[select(X, n, "lhs", np.random.default_rng(1))]
    rand = X[select(X, n, "random", np.random.default_rng(1))]
    # strata from the population's ranks
    def occ(S):
        qs = np.quantile(X, np.linspace(0, 1, n + 1), axis=0)
        return np.array([len(np.unique(np.clip(np.searchsorted(qs[:, j], S[:, j]) - 1, 0, n - 1))) / n
                         for j in range(X.shape[1])])
    assert np.all(occ(lhs) > 0.9)     # LHS: almost one row per stratum
    assert np.all(occ(rand) < 0.75)   # random: about 1 - 1/e of the strata


def test_grid_takes_one_row_per_grid_cell():
    X = np.random.default_rng(0).uniform(size=(5000, 2)) ** 3  # skewed: the grid is in rank space
    picked = X[select(X, 81, "grid", np.random.default_rng(0))]
    q = np.quantile(X, np.linspace(0, 1, 10), axis=0)
    H, _, _ = np.histogram2d(picked[:, 0], picked[:, 1], bins=[q[:, 0], q[:, 1]])
    np.testing.assert_array_equal(H, 1)  # 9 x 9 cells, exactly one row each


def test_sampling_bad_requests(d2):
    with pytest.raises(InputError, match="only"):
        sample_split(d2, d2.n_rows, 1)
    with pytest.raises(InputError, match="method"):
        sample_split(d2, 10, 10, "sobol")
    with pytest.raises(InputError, match="column"):
        sample_split(d2, 10, 10, "lhs", columns=("nope",))


def test_write_split_files_and_manifest(d2, tmp_path):
    meta = write_split(d2, tmp_path / "s", 200, 50, "lhs", 3)
    tr = pq.read_table(tmp_path / "s" / "train.parquet")
    assert tr.num_rows == 200 and tr.column_names == list(COLUMNS) + ["row"]
    assert meta["source_checksum"] == d2.checksum and meta["seed"] == 3
    rows = tr.column("row").to_numpy()
    src = d2.read(["N1_next"], rows=rows)
    np.testing.assert_array_equal(tr.column("N1_next").to_numpy(), src["N1_next"])


def test_data_cli(d2, tmp_path, capsys):
    from hmodel.cli.app import main
    out = tmp_path / "g"
    assert main(["data", "generate", "1", "--out", str(out), "--directions", "3", "--alpha0", "45",
                 "--max-strain", "0.05", "--workers", "1"]) == 0
    assert Dataset.open(out).n_rows == 3 * 50
    assert main(["data", "generate", "3", "--out", str(tmp_path / "r"), "--directions", "4", "--rev-paths",
                 "undrained:1e5", "--max-strain", "0.002", "--start-every", "0.001", "--increments", "2",
                 "--substeps", "1", "--magnitude", "0.001", "--workers", "1"]) == 0
    assert Dataset.open(tmp_path / "r").n_rows == 4 * 2 * 2  # cells x start states x increments
    assert main(["data", "info", str(d2.folder), "--out", str(tmp_path / "info")]) == 0
    text = (tmp_path / "info" / "cleaning.csv").read_text()
    assert "short" in text and "broken" in text
    for f in ("fig-2-1-strains.png", "fig-2-2-removed.png"):
        assert (tmp_path / "info" / f).read_bytes()[:4] == b"\x89PNG"
    assert main(["data", "sample", str(d2.folder), "--train", "100", "--test", "20", "--method", "grid",
                 "--out", str(tmp_path / "s")]) == 0
    assert pq.read_table(tmp_path / "s" / "test.parquet").num_rows == 20
    capsys.readouterr()
    for bad, word in ((["data", "generate", "1", "--out", str(tmp_path / "b"), "--alpha0", "10:20:5"], "alpha0"),
                      (["data", "generate", "3", "--out", str(tmp_path / "b")], "dataset"),
                      (["data", "sample", str(d2.folder), "--rules", "zzz", "--out", str(tmp_path / "b")], "zzz"),
                      (["data", "sample", str(d2.folder), "--method", "sobol", "--out", str(tmp_path / "b")], "sobol"),
                      (["data", "info", str(tmp_path / "nope")], "not a dataset")):
        assert main(bad) != 0
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and word in err[0], err
    assert not (tmp_path / "b").exists()


def _threads_here() -> tuple[int, int]:
    import numba
    from threadpoolctl import threadpool_info
    blas = max((i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"), default=1)
    return blas, numba.get_num_threads()


def test_worker_processes_run_one_thread_each():
    """Worker processes share the cores: BLAS and Numba run one thread in each (threads within
    processes would oversubscribe the machine)."""
    from hmodel.workers import run_tasks
    out = dict(run_tasks(_threads_here, [()] * 2, [0, 1], workers=2))
    assert out == {0: (1, 1), 1: (1, 1)}
