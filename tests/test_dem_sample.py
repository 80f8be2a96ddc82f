"""``hmodel dem sample`` (hmodel.dem.sample): a periodic 2D disk assembly in YADE, consolidated and
sheared in drained and undrained biaxial tests; resumable. What disks and spheres share (bad
options refused, missing YADE, the seeded initial gas, the size guard) is tested here for both
dimensions; the spheres' own tests are in test_dem_sample3d.py."""

from __future__ import annotations

import csv
import json
import math
import time

import numpy as np
import pytest

from hmodel.cli.app import main
from hmodel.dem.sample import (
    SampleSettings,
    SampleState,
    file_stem,
    initial_packing,
    mean_diameter,
)
from hmodel.errors import InputError

SMALL = ["--disks", "200", "--axial-strain", "0.01", "--rows", "10", "--p0", "100kPa"]


def _read_csv(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], np.array(rows[1:], float)


@pytest.fixture(scope="module")
def sample_dir(tmp_path_factory):
    """One folder, a drained then an undrained test of the same 200-disk sample at 100 kPa."""
    out = tmp_path_factory.mktemp("sample") / "s"
    walls = {}
    for kind in ("drained", "undrained"):
        t0 = time.perf_counter()
        code = main(["dem", "sample", *SMALL, "--out", str(out)]
                    + (["--undrained"] if kind == "undrained" else []))
        walls[kind] = time.perf_counter() - t0
        assert code == 0
    return out, walls


@pytest.mark.slow
@pytest.mark.yade
def test_drained_test_holds_the_lateral_stress_and_builds_up_q(sample_dir):
    out, walls = sample_dir
    assert walls["drained"] < 60.0, walls
    header, data = _read_csv(out / "drained_100kPa.csv")
    assert header == ["eps11", "q", "eps_v", "p", "coordination", "sliding"]
    assert len(data) == 11
    eps11, q, eps_v, p, z, sliding = data.T
    assert eps11[0] == 0.0 and eps_v[0] == 0.0 and np.all(np.diff(eps11) > 0)
    assert eps11[-1] == pytest.approx(0.01, rel=1e-3)
    assert abs(q[0]) < 0.01 * 1e5 and abs(p[0] - 1e5) < 0.01 * 1e5  # consolidated to p0
    assert np.all(q[1:] > 0) and q.max() > 0.5e5 and q[1] > q[0]  # q rises from ~0
    s22 = p - 0.5 * q
    assert np.max(np.abs(s22 - 1e5)) < 0.02 * 1e5  # lateral stress held at p0
    assert np.allclose(p, 1e5 + 0.5 * q, rtol=0.02)  # drained: p = p0 + q/2
    meta = json.loads((out / "sample.json").read_text())
    rec = meta["tests"]["drained_100kPa"]
    assert meta["settings"]["disks"] == 200 and meta["yade_version"]
    assert rec["inertial_number"] == pytest.approx(1e-4) and rec["inertial_number_max"] < 2e-4
    assert rec["max_lateral_stress_error"] < 0.02
    assert 0.1 < rec["consolidated"]["porosity"] < 0.25  # frictionless compaction: dense
    assert rec["consolidated"]["void_ratio"] == pytest.approx(
        rec["consolidated"]["porosity"] / (1 - rec["consolidated"]["porosity"]))
    assert 3.0 < rec["consolidated"]["coordination"] <= rec["consolidated"]["mechanical_coordination"]
    assert rec["wall_s"] > 0 and rec["shear_steps"] > 0 and rec["csv"] == "drained_100kPa.csv"
    # the recorded coordination counts the same contacts as the exported states
    assert z[0] == pytest.approx(rec["consolidated"]["coordination"], rel=0.02)
    assert z[-1] == pytest.approx(rec["final"]["coordination"], rel=0.02)
    # frictionless consolidation, then friction: no contact slides at rest, some under shear
    assert sliding[0] < 0.01 and 0 < sliding[-1] < 1 and rec["max_sliding"] == sliding.max()
    # the last row's sliding fraction from the exported contacts: |ft| on tan(phi_g) fn
    f = np.load(out / "drained_100kPa.npz")["final_contacts"]
    on_limit = np.abs(f[:, 3]) >= (1 - 1e-5) * np.tan(np.radians(30.0)) * f[:, 2]
    assert sliding[-1] == pytest.approx(on_limit.mean(), abs=0.01)


@pytest.mark.yade
def test_undrained_test_keeps_the_area(sample_dir):
    out, walls = sample_dir
    header, data = _read_csv(out / "undrained_100kPa.csv")
    assert header == ["eps11", "q", "eps_v", "p", "coordination", "sliding"]
    eps11, q, eps_v, p = data.T[:4]
    assert np.all(np.diff(eps11) > 0) and np.max(np.abs(eps_v)) < 1e-9
    assert q[-1] > 0.5e5 and abs(q[0]) < 1e3
    meta = json.loads((out / "sample.json").read_text())
    assert sorted(meta["tests"]) == ["drained_100kPa", "undrained_100kPa"]
    # both tests start from the same consolidated sample (same seed, deterministic YADE)
    a, b = (meta["tests"][n]["consolidated"] for n in ("drained_100kPa", "undrained_100kPa"))
    assert a["porosity"] == pytest.approx(b["porosity"], rel=1e-9)


@pytest.mark.yade
def test_stresses_are_love_weber_per_unit_area_and_the_figure_is_drawn(sample_dir):
    """The CSV's stresses are (1/A) Σ f⊗l over the exported contacts (compression positive),
    A the periodic cell's area: hmodel's 2D convention (hmodel.dem.stress)."""
    from matplotlib.image import imread

    out, _ = sample_dir
    with np.load(out / "drained_100kPa.npz") as z:
        rows = z["rows"]
        st = SampleState(cell=tuple(z["final_cell"]), radii=z["radii"],
                         positions=z["final_positions"], contacts=z["final_contacts"])
        st0 = SampleState(cell=tuple(z["consolidated_cell"]), radii=z["radii"],
                          positions=z["consolidated_positions"], contacts=z["consolidated_contacts"])
    meta = json.loads((out / "sample.json").read_text())["tests"]["drained_100kPa"]
    for state, row, name in ((st0, rows[0], "consolidated"), (st, rows[-1], "final")):
        sigma = state.stress()
        assert sigma[0, 0] == pytest.approx(row[2], rel=1e-9)
        assert sigma[1, 1] == pytest.approx(row[3], rel=1e-9)
        # the contact fabric of the same contacts (hmodel.rev.contacts), in sample.json
        f = meta[name]["fabric"]
        assert f["stress_ratio"] == pytest.approx(row[2] / row[3], rel=1e-9)
        assert np.trace(np.array(f["tensor"])) == pytest.approx(1.0)
    assert (out / "drained_100kPa_contact_fabric.csv").exists()
    lx0, ly0 = st0.cell
    assert rows[-1, 0] == pytest.approx(math.log(lx0 / st.cell[0]), rel=1e-9)  # log strains
    assert np.all(st.positions >= 0) and np.all(st.positions <= np.array(st.cell))
    image = imread(out / "sample.png")
    assert min(image.shape[:2]) >= 300 and np.ptp(image[..., :3]) > 0.5


@pytest.mark.yade
def test_an_existing_csv_is_not_run_again(sample_dir, monkeypatch, cli):
    out, _ = sample_dir
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    monkeypatch.setenv("HMODEL_YADE", "/no/such/yade")  # YADE is never started
    code, stdout, err = cli("dem", "sample", *SMALL, "--out", out)
    assert code == 0, err
    assert "drained_100kPa.csv exists, skipped" in stdout
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


@pytest.mark.yade
def test_a_folder_of_another_sample_is_refused(sample_dir, cli):
    out, _ = sample_dir
    before = sorted(p.name for p in out.iterdir())
    code, _, err = cli("dem", "sample", "--disks", "300", "--axial-strain", "0.01", "--rows", "10",
                       "--p0", "200kPa", "--out", out)
    assert code == 1 and err.count("\n") == 1 and "other settings (--disks)" in err
    assert sorted(p.name for p in out.iterdir()) == before


@pytest.mark.slow
@pytest.mark.yade
def test_target_porosity_lowers_the_compaction_friction(tmp_path, cli):
    out = tmp_path / "loose"
    code, _, err = cli("dem", "sample", "--disks", "200", "--axial-strain", "0.002", "--rows", "2",
                       "--porosity", "0.18", "--out", out)
    assert code == 0, err
    rec = json.loads((out / "sample.json").read_text())["tests"]["drained_100kPa"]
    assert 0.17 < rec["consolidated"]["porosity"] <= 0.18
    assert 0 < rec["consolidation_friction_deg"] < 30
    # a target looser than compaction with φg = 30° gives: refused, nothing written
    out2 = tmp_path / "too-loose"
    code, _, err = cli("dem", "sample", "--disks", "200", "--axial-strain", "0.002", "--rows", "2",
                       "--porosity", "0.4", "--out", out2)
    assert code == 1 and err.count("\n") == 1 and "target porosity 0.4 is above" in err
    assert not out2.exists()


# -- what disks and spheres share (the spheres' own: test_dem_sample3d.py) ---------------------

def _bad(dim, cases):
    return [pytest.param(dim, args, message, id=f"{dim}d-{message}") for args, message in cases]


@pytest.mark.parametrize("dim, args, message", _bad(2, [
    (["--p0", "0"], "pressure must be positive"),
    (["--p0", "-100kPa"], "pressure must be positive"),
    (["--p0", "100kPa,abc"], "cannot read pressure"),
    (["--p0", "100kPa,100kPa"], "pressures must differ"),
    (["--distribution", "gaussian"], "--distribution must be one of uniform, equal-area"),
    (["--radius-ratio", "0.5"], "--radius-ratio must be >= 1"),
    (["--kn", "-1"], "--kn must be a positive number"),
    (["--phi-g", "95"], "--phi-g must lie in (0, 90)"),
    (["--porosity", "1.2"], "--porosity must lie in (0, 1)"),
    (["--porosity", "0.2", "--compaction-friction", "0"], "must then be above 0"),
    (["--axial-strain", "1.5"], "--axial-strain must be below 1"),
    (["--rows", "0"], "--rows must be a positive integer"),
    (["--seed", "-1"], "--seed must be >= 0"),
    (["--disks", "5"], "--disks must be at least 20"),
    # (6 r_max)^2 (pi / (2 sqrt 3)) / (pi E[r^2]), r in [2/11, 20/11] at ratio 10: uniform,
    # E[r^2] = 148/121 and 14400 / (296 sqrt 3) = 28.1; equal-area, E[r^2] = r_min r_max =
    # 40/121 and 14400 / (80 sqrt 3) = 103.9
    (["--disks", "28", "--radius-ratio", "10"], "use at least 29 disks"),
    (["--disks", "103", "--radius-ratio", "10", "--distribution", "equal-area"], "use at least 104 disks"),
    (["--inertial-number", "1e-4", "--strain-rate", "1e-3"], "not both"),
    (["--strain-rate", "0"], "--strain-rate must be a positive number"),
]) + _bad(3, [
    (["--spheres", "60"], "too small a sample to be periodic"),
    (["--radius-ratio", "4", "--spheres", "100"], "too small a sample to be periodic"),  # 100 pass at 2
    (["--phi-g", "0"], "--phi-g must lie in (0, 90)"),
    (["--phi-g", "95"], "--phi-g must lie in (0, 90)"),
    (["--kn", "-1"], "--kn must be a positive number"),
    (["--kt-kn", "0"], "--kt-kn must be a positive number"),
    (["--compaction-friction", "90"], "--compaction-friction must lie in [0, 90)"),
    (["--distribution", "equal-area"], "one of uniform, equal-volume with spheres"),
    (["--undrained", "--extension"], "drained and undrained compression and drained extension"),
    (["--dim", "4"], "--dim must be 2 (disks) or 3 (spheres)"),
]))
def test_bad_options_are_one_line_errors_and_write_nothing(tmp_path, monkeypatch, cli, dim, args, message):
    monkeypatch.setenv("HMODEL_YADE", str(tmp_path / "no-such-yade"))  # refused before YADE
    out = tmp_path / "out"
    sample = ["dem", "sample"] if dim == 2 else ["dem", "sample", "--dim", "3"]  # disks by default
    cli.refuses([*sample, *args, "--out", out], message, out)
    assert list(tmp_path.iterdir()) == []


def test_missing_yade_is_one_line(tmp_path, monkeypatch, cli, dim):
    monkeypatch.setenv("HMODEL_YADE", str(tmp_path / "no-such-yade"))
    out = tmp_path / "out"
    grains = {2: ["--disks", "200"], 3: ["--dim", "3", "--spheres", "120"]}[dim]
    cli.refuses(["dem", "sample", *grains, "--out", out], "YADE is not installed", out)


def test_unknown_option(tmp_path, cli):
    out = tmp_path / "out"
    cli.refuses(["dem", "sample", "--grains", "200", "--out", out], "No such option: --grains", out, code=2)


@pytest.mark.parametrize("dim, dist", [(2, "uniform"), (2, "equal-area"), (3, "uniform"), (3, "equal-volume")])
def test_initial_packing_is_a_seeded_gas_without_overlap(dim, dist):
    s = SampleSettings(dim=dim, disks=300, radius=2.0, radius_ratio=3.0, distribution=dist, seed=7)
    r, pos, cell = initial_packing(s)
    assert len(r) == 300 and pos.shape == (300, dim) and len(cell) == dim
    assert r.min() >= s.r_min and r.max() <= s.r_max
    assert s.r_min == pytest.approx(1.0) and s.r_max == pytest.approx(3.0)
    assert np.all(pos - r[:, None] >= 0) and np.all(pos + r[:, None] <= cell)
    gap = np.linalg.norm(pos[:, None] - pos[None], axis=-1) - (r[:, None] + r[None])
    np.fill_diagonal(gap, 1.0)
    assert gap.min() > 0
    r2, pos2, _ = initial_packing(s)
    assert np.array_equal(r, r2) and np.array_equal(pos, pos2)


@pytest.mark.parametrize("dim, grains", [(2, 2000), (3, 1500)])
def test_a_test_is_sized_before_any_grain_is_drawn(tmp_path, monkeypatch, dim, grains):
    """A test's estimate is its grains x GRAIN_BYTES and its recorded rows x ROW_BYTES: at the
    budget the grains are drawn and YADE asked (and found missing); one grain or one row more
    is refused, and nothing is written."""
    from dataclasses import replace

    from hmodel.dem.sample import kinds, run_sample, run_test
    from hmodel.dem.sample.settings import GRAIN_BYTES, ROW_BYTES
    from hmodel.dem.yade import YadeNotFound
    from hmodel.limits import WorkTooLarge

    monkeypatch.setenv("HMODEL_YADE", str(tmp_path / "no-such-yade"))
    s = SampleSettings(dim=dim, disks=grains, rows=10)
    monkeypatch.setenv("HMODEL_MEMORY_LIMIT", str(grains * GRAIN_BYTES + 11 * ROW_BYTES))
    kind = kinds(dim)[0]
    with pytest.raises(YadeNotFound):
        run_sample(s, [1e5], kind, tmp_path / "o")
    for more, phrase in ((replace(s, disks=grains + 1), f"{grains + 1:,} "), (replace(s, rows=11), "12 rows")):
        with pytest.raises(WorkTooLarge, match=phrase):
            run_sample(more, [1e5], kind, tmp_path / "o")
        with pytest.raises(WorkTooLarge):
            run_test(more, kind, 1e5)
    assert list(tmp_path.iterdir()) == []


def test_disks_are_spread_by_their_distribution():
    uni = initial_packing(SampleSettings(disks=4000, radius_ratio=3.0))[0]
    area = initial_packing(SampleSettings(disks=4000, radius_ratio=3.0, distribution="equal-area"))[0]
    assert mean_diameter(uni) == pytest.approx(2.0, rel=0.02)
    assert np.mean(area) < np.mean(uni)  # more small disks when every size holds the same area
    # r in [0.5, 1.5], equal area per radius interval: the disks below r = 1 hold half the area
    assert np.sum(area[area < 1.0] ** 2) / np.sum(area ** 2) == pytest.approx(0.5, abs=0.05)


def test_sample_state_measures():
    """Two disks touching across the periodic boundary along x, one free disk."""
    radii = np.array([1.0, 1.0, 0.5])
    st = SampleState(cell=(10.0, 4.0), radii=radii, positions=np.array([[0.5, 2.0], [8.6, 2.0], [5.0, 2.0]]),
                     contacts=np.array([[0, 1, 3.0, 1.0, -1.9, 0.0]]))
    # l from 0 to 1 points along -x; fn = 3 compression, ft along (e_y, -e_x) = (0, 1)
    assert np.allclose(st.forces(), [[-3.0, 1.0]])
    assert np.allclose(st.stress(), np.array([[3.0 * 1.9, 0.0], [-1.9, 0.0]]) / 40.0)
    assert st.porosity == pytest.approx(1 - math.pi * 2.25 / 40)
    assert st.coordination == pytest.approx(2 / 3) and st.rattlers == pytest.approx(1.0)
    assert file_stem("undrained", 150e3) == "undrained_150kPa"
    with pytest.raises(InputError, match="--radius must be a positive"):
        SampleSettings(radius=0.0)
