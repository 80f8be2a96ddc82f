"""``hmodel dem sample --dim 3`` (hmodel.dem.sample with dim = 3): a periodic assembly of
polydisperse spheres in YADE, consolidated isotropically and sheared in drained and undrained
triaxial compression and drained triaxial extension; resumable. Bad options, missing YADE, the
initial gas and the size guard are tested for disks and spheres alike in test_dem_sample.py."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from hmodel.cli.app import main
from hmodel.dem.sample import CSV_COLUMNS_3D, SampleSettings, initial_packing, run_test
from hmodel.errors import InputError

P0 = 1e5
#: A small sample, a short shear: 120 spheres (the guard asks 82 for r_max / r_min = 2), 0.5 %.
SMALL = ["--dim", "3", "--spheres", "120", "--axial-strain", "0.005", "--rows", "5",
         "--inertial-number", "5e-4", "--p0", "100kPa"]
KIND_FLAGS = {"triaxial-drained": [], "triaxial-undrained": ["--undrained"],
              "triaxial-extension": ["--extension"]}


def _read_csv(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], {c: np.array([float(r[k]) for r in rows[1:]]) for k, c in enumerate(rows[0])}


def _states(path):
    """(rows, [(cell, radii, positions, contacts)] consolidated and final) of a test's npz."""
    with np.load(path) as z:
        return z["rows"], [(z[f"{s}_cell"], z["radii"], z[f"{s}_positions"], z[f"{s}_contacts"])
                           for s in ("consolidated", "final")]


def _love_weber(cell, contacts):
    """(1/V) sum f (x) l written out from the contact columns [i, j, fn, ftx, fty, ftz, lx, ly, lz]:
    f = fn e + ft, e = l / |l|, V = Lx Ly Lz (compression positive)."""
    sigma = np.zeros((3, 3))
    for c in contacts:
        l = c[6:9]
        f = c[2] * l / math.sqrt(l @ l) + c[3:6]
        sigma += np.outer(f, l)
    return sigma / (cell[0] * cell[1] * cell[2])


@pytest.fixture(scope="module")
def sample_dir(tmp_path_factory):
    """One folder: drained, undrained and extension tests of the same 120-sphere sample at 100 kPa."""
    out = tmp_path_factory.mktemp("sample3d") / "s"
    for flags in KIND_FLAGS.values():
        assert main(["dem", "sample", *SMALL, *flags, "--out", str(out)]) == 0
    return out


@pytest.mark.slow
@pytest.mark.yade
def test_stress_is_the_love_weber_sum_over_the_contacts(sample_dir):
    """YADE's stress in every row equals the sum over the exported contacts, computed here from
    the contact list; the strains are the logarithms of the cell's edges."""
    for kind in KIND_FLAGS:
        rows, states = _states(sample_dir / f"{kind}_100kPa.npz")
        for (cell, radii, pos, contacts), row in zip(states, (rows[0], rows[-1])):
            sigma = _love_weber(cell, contacts)
            voigt = [sigma[0, 0], sigma[1, 1], sigma[2, 2], 0.5 * (sigma[0, 1] + sigma[1, 0]),
                     0.5 * (sigma[0, 2] + sigma[2, 0]), 0.5 * (sigma[1, 2] + sigma[2, 1])]
            assert np.allclose(row[3:9], voigt, rtol=0, atol=1e-9 * P0)
            # symmetric for grains in equilibrium; a quasi-static sample is near it
            assert np.max(np.abs(sigma - sigma.T)) < 2e-3 * P0
            assert len(pos) == len(radii) == 120 and np.all(pos >= 0) and np.all(pos <= cell)
        c0, c1 = states[0][0], states[1][0]
        assert np.allclose(rows[-1, :3], np.log(c0 / c1), rtol=1e-9, atol=1e-12)


@pytest.mark.yade
def test_consolidated_state_is_isotropic_and_the_csv_complete(sample_dir):
    meta = json.loads((sample_dir / "sample.json").read_text())
    assert meta["settings"]["dim"] == 3 and sorted(meta["tests"]) == sorted(f"{k}_100kPa" for k in KIND_FLAGS)
    for kind in KIND_FLAGS:
        header, t = _read_csv(sample_dir / f"{kind}_100kPa.csv")
        assert tuple(header) == CSV_COLUMNS_3D and len(t["eps_a"]) == 6
        s = [t[f"sig{i}{i}"][0] for i in (1, 2, 3)]
        assert np.allclose(s, P0, rtol=1.5e-3)  # the consolidation's tolerance, 1e-3 p0 per axis
        # shear stresses are not servoed: a few % of p0 in so small a sample
        assert max(abs(t[c][0]) for c in ("sig12", "sig13", "sig23")) < 0.1 * P0
        assert t["eps_a"][0] == t["eps_v"][0] == 0.0 and abs(t["q"][0]) < 3e-3 * P0
        # the CSV's invariants from its own stress components
        assert np.allclose(t["p"], (t["sig11"] + t["sig22"] + t["sig33"]) / 3, rtol=1e-12)
        assert np.allclose(t["q"], t["sig11"] - (t["sig22"] + t["sig33"]) / 2, rtol=1e-12, atol=1e-9)
        rec = meta["tests"][f"{kind}_100kPa"]
        assert rec["inertial_number"] == pytest.approx(5e-4) and rec["inertial_number_max"] <= 1e-3
        z0 = rec["consolidated"]["coordination"]
        assert t["coordination"][0] == pytest.approx(z0) and 4.0 < z0 < 8.0  # frictionless: ~6
        assert 0.3 < rec["consolidated"]["porosity"] < 0.42  # random close packing ~ 0.36
        # sliding: none after the frictionless consolidation, some as the sample is sheared
        assert t["sliding"][0] == 0.0 and 0.0 < t["sliding"][-1] < 0.6
        # the contact fabric (hmodel.rev.contacts): its stress ratio is the sample's σ11/σr
        for state, row in (("consolidated", 0), ("final", -1)):
            f = rec[state]["fabric"]
            assert f["stress_ratio"] == pytest.approx(t["sig11"][row] / (0.5 * (t["sig22"][row] + t["sig33"][row])),
                                                      rel=1e-9)
            assert sum(b["contacts"] for b in f["bands"]) == pytest.approx(1.0)
        with open(sample_dir / f"{kind}_100kPa_contact_fabric.csv", newline="") as fh:
            fab = list(csv.DictReader(fh))
        assert [r["state"] for r in fab] == ["consolidated"] * 4 + ["final"] * 4
        assert float(fab[-1]["stress_ratio"]) == pytest.approx(rec["final"]["fabric"]["stress_ratio"])


@pytest.mark.yade
def test_drained_undrained_and_extension_paths(sample_dir):
    _, d = _read_csv(sample_dir / "triaxial-drained_100kPa.csv")
    assert np.all(np.diff(d["eps_a"]) > 0) and d["eps_a"][-1] == pytest.approx(0.005, rel=1e-3)
    for c in ("sig22", "sig33"):  # lateral stresses held at p0 by the servo
        assert np.max(np.abs(d[c] - P0)) < 0.02 * P0
    assert d["q"][1] > 0.2 * P0 and np.all(d["q"][1:] > 0)
    assert np.allclose(d["p"], P0 + d["q"] / 3, atol=0.02 * P0)  # drained: dp = dq / 3
    _, u = _read_csv(sample_dir / "triaxial-undrained_100kPa.csv")
    assert np.max(np.abs(u["eps_v"])) < 1e-11 and u["q"][-1] > 0.2 * P0  # tr eps = 0
    assert u["eps_a"][-1] == pytest.approx(0.005, rel=1e-3)
    _, e = _read_csv(sample_dir / "triaxial-extension_100kPa.csv")
    assert np.all(np.diff(e["eps_a"]) < 0) and e["eps_a"][-1] == pytest.approx(-0.005, rel=1e-3)
    assert np.all(e["sig11"][1:] < e["sig22"][1:]) and np.all(e["sig11"][1:] < e["sig33"][1:])
    assert np.max(np.abs(e["sig22"] - P0)) < 0.02 * P0 and np.max(np.abs(e["sig33"] - P0)) < 0.02 * P0
    assert np.all(e["q"][1:] < 0)  # q = s11 - (s22 + s33) / 2


@pytest.mark.yade
def test_sliding_fraction_is_that_of_the_contact_list(sample_dir):
    """The last row's sliding fraction: contacts with |ft| at tan(phi_g) fn, from the exported
    list. The list splits f along the branch vector at the end of the step, the contact law
    capped ft on the contact normal of the step: a sliding contact's |ft| / (tan phi fn) is 1 to
    about 1e-5 there, hence the tolerance."""
    rows, states = _states(sample_dir / "triaxial-drained_100kPa.npz")
    contacts = states[1][3]
    ft = np.linalg.norm(contacts[:, 3:6], axis=1)
    at_limit = ft >= (1 - 1e-4) * math.tan(math.radians(30.0)) * contacts[:, 2]
    assert rows[-1, 10] == len(contacts)
    assert rows[-1, 11] == pytest.approx(np.mean(at_limit & (contacts[:, 2] > 0)), abs=1e-12)


@pytest.mark.yade
def test_figure_resume_and_refused_folder(sample_dir, monkeypatch, capsys):
    from matplotlib.image import imread

    image = imread(sample_dir / "sample.png")
    assert min(image.shape[:2]) >= 300 and np.ptp(image[..., :3]) > 0.5
    before = {p.name: p.read_bytes() for p in sample_dir.iterdir()}
    monkeypatch.setenv("HMODEL_YADE", "/no/such/yade")  # YADE is never started
    assert main(["dem", "sample", *SMALL, "--extension", "--out", str(sample_dir)]) == 0
    assert "triaxial-extension_100kPa.csv exists, skipped" in capsys.readouterr().out
    assert main(["dem", "sample", *SMALL, "--out", str(sample_dir), "--dim", "2"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "other settings (--dim)" in err
    assert {p.name: p.read_bytes() for p in sample_dir.iterdir()} == before


def test_extension_of_disks_and_a_2d_kind_of_spheres_are_refused(tmp_path, cli):
    out = tmp_path / "out"
    cli.refuses(["dem", "sample", "--extension", "--out", out], "add --dim 3", out)
    with pytest.raises(InputError, match="sphere sample .* not 'drained'"):
        run_test(SampleSettings(dim=3, disks=200), "drained", P0)


def test_spheres_are_spread_by_their_distribution():
    # (the seeded gas without overlap, both distributions: test_dem_sample.py)
    vol = initial_packing(SampleSettings(dim=3, disks=8000, radius_ratio=3.0, distribution="equal-volume"))[0]
    # r in [0.5, 1.5] with pdf ~ r^-3: every radius interval holds the same solid volume, so
    # the spheres below r = 1 hold half of it
    assert np.sum(vol[vol < 1.0] ** 3) / np.sum(vol ** 3) == pytest.approx(0.5, abs=0.03)
