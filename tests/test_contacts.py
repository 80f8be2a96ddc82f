"""A REV's contacts one by one and their fabric (hmodel.rev.contacts), as a DEM sample's
(docs/model3d.md, "Contact fabric"; docs/notes/2026-12-07-contact-fabric.md)."""

import csv
import math

import numpy as np
import pytest

from hmodel import Params
from hmodel.errors import InputError
from hmodel.loading import Recorder, consolidate, run_segment, run_biaxial, run_triaxial
from hmodel.loading.stages import Stage
from hmodel.rev import Rev, Rev3D, Sphere
from hmodel.rev.contacts import (
    TILT_BANDS,
    cell_contacts,
    check_contacts,
    fabric,
    fabric_rows,
    grain_contacts,
    isotropic_shares,
)
from hmodel.rev.rev3d import voigt_to_tensor
from hmodel.variants import get_variant

SAND = dict(get_variant("sand").options)


def sheared_3d(params: Params, strain: float):
    rev = Rev3D([params], Sphere(order=17, n_azimuth=2))
    p = np.array([1e5])
    start = consolidate(rev, p)
    rows = {"eps11": strain, "sig_r": 1e5, "eps22-eps33": 0.0, "eps23": 0.0, "eps13": 0.0, "eps12": 0.0}
    end = run_segment(rev, start, Stage("shear", rows, steps=round(strain / 1e-3)).segment(start), Recorder()).state
    return rev, end


@pytest.mark.parametrize("options", [
    {**SAND, "alpha0": math.radians(60.0)},  # Hertz-Mindlin, renewal=mix, lateral=axisymmetric
    {"cross_contacts": "frictionless", "alpha0": math.radians(46.0)},  # linear, cross contacts carry
])
def test_the_contacts_sum_to_the_3d_rev_s_stress(options):
    # eq. 1.11 contact by contact from the branch vectors against eq. 1.12 per cell: two routes
    # to σ, off-diagonal terms included
    params = Params(**options)
    rev, end = sheared_3d(params, 0.03)
    c = cell_contacts(rev, end)
    ref = voigt_to_tensor(end.sig)[0]
    np.testing.assert_allclose(c.stress(float(rev.macro_volume(end.eps)[0])), ref, atol=1e-9 * abs(ref).max())
    if params.cross_contacts == "frictionless":  # the case exercises what it claims
        assert (c.fn[-8 * rev.n_cells:] > 0.0).any()


def test_the_contacts_sum_to_the_2d_rev_s_stress_for_every_set():
    sets = [Params(), Params(contact="hertz-mindlin", shear_modulus=29e9, poisson=0.2, alpha0=math.radians(40.0))]
    rev = Rev(sets)
    state = rev.initial(2)
    for _ in range(60):  # sheared, with a shear strain: σ12 nonzero
        state = rev.step(state, np.array([[1e-4, -0.5e-4, 0.0], [1e-4, -1e-4, 2e-5]]))
    volumes = rev.macro_volume(state.eps, state.set_index)
    for b in range(2):
        s = cell_contacts(rev, state, b).stress(float(volumes[b]))
        ref = state.sig[b]
        np.testing.assert_allclose([s[0, 0], s[1, 1], s[0, 1], s[1, 0]], [ref[0], ref[1], ref[2], ref[2]],
                                   atol=1e-9 * abs(ref).max())
    assert abs(state.sig[1, 2]) > 1e-3 * state.sig[1, 0]


def test_one_axial_bihexagon_by_hand():
    # n = e1, α 60°: eight inclined contacts 60° from the axis, four column contacts along it;
    # d1 = d2 = 2r = 1e-3, N1 = 1, N2 = 0.5, T1 = 0.2 in both hexagons, lengths apart (no extra)
    from hmodel.rev.contacts import _cell_contacts

    params = Params(radius=5e-4)
    a = math.radians(60.0)
    hexagon = [1e-3, 1e-3, a, 1.0, 0.5, 0.2, 5e-3, 5e-3]
    f = fabric(_cell_contacts(params, np.array([hexagon + hexagon]), np.eye(3)[None], np.ones(1)))
    inclined11 = 8 * 1e-3 * (math.cos(a) ** 2 + 0.2 * math.sin(a) * math.cos(a))
    column11 = 4 * 0.5 * 1e-3
    # each hexagon's four inclined contacts give 4 d1 (N1 sin² - T1 sin cos) along its own t
    inclined_r = 0.5 * 2 * 4 * 1e-3 * (math.sin(a) ** 2 - 0.2 * math.sin(a) * math.cos(a))
    assert f.count == 12.0
    assert f.tensor[0, 0] == pytest.approx((8 * 0.25 + 4) / 12)
    assert np.trace(f.tensor) == pytest.approx(1.0)
    assert f.force_tensor[0, 0] == pytest.approx((8 * 0.25 + 4 * 0.5) / (8 + 4 * 0.5))
    assert f.stress_ratio == pytest.approx((inclined11 + column11) / inclined_r)
    assert [b["contacts"] for b in f.bands] == pytest.approx([4 / 12, 0.0, 8 / 12, 0.0])
    assert [b["sig_axial"] for b in f.bands] == pytest.approx(
        [column11 / (inclined11 + column11), 0.0, inclined11 / (inclined11 + column11), 0.0])
    assert [b["sig_lateral"] for b in f.bands] == pytest.approx([0.0, 0.0, 1.0, 0.0])


def test_open_contacts_and_empty_cells_do_not_count():
    from hmodel.rev.contacts import _cell_contacts

    params = Params(radius=5e-4)
    a = math.radians(60.0)
    carrying = [1e-3, 1e-3, a, 1.0, 0.5, 0.0, 5e-3, 5e-3]
    empty = [1e-3, 1e-3, a, 0.0, 0.0, 0.0, 5e-3, 5e-3]
    one = fabric(_cell_contacts(params, np.array([carrying + carrying]), np.eye(3)[None], np.ones(1)))
    # a second bi-hexagon, lateral and empty, of any weight changes nothing
    frames = np.array([np.eye(3), np.eye(3)[[1, 2, 0]]])
    two = fabric(_cell_contacts(params, np.array([carrying + carrying, empty + empty]), frames, np.array([1.0, 5.0])))
    assert two.as_dict() == one.as_dict()


def test_grain_contacts_along_the_axes():
    # six contacts: two along x (tilt 0) with normal force 3, four across (tilt 90) with 1, one
    # with a tangential force; branch vectors of length 2; an open contact is left out
    branch = np.array([[2.0, 0, 0], [-2.0, 0, 0], [0, 2.0, 0], [0, 0, 2.0], [0, -2.0, 0], [0, 0, -2.0], [2.0, 0, 0]])
    force = np.array([[3.0, 0, 0], [-3.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [0.5, -1.0, 0], [0, 0, -1.0], [0, 0, 0]])
    c = grain_contacts(branch, force)
    np.testing.assert_allclose(c.fn, [3, 3, 1, 1, 1, 1, 0])
    f = fabric(c)
    assert f.count == 6
    assert f.tensor[0, 0] == pytest.approx(2 / 6) and f.force_tensor[0, 0] == pytest.approx(6 / 10)
    assert f.stress_ratio == pytest.approx(12.0 / 4.0)  # the tangential force adds no normal stress
    assert [b["sig_axial"] for b in f.bands] == pytest.approx([1.0, 0.0, 0.0, 0.0])
    assert [b["sig_lateral"] for b in f.bands] == pytest.approx([0.0, 0.0, 0.0, 1.0])
    # the Love-Weber sum keeps the tangential force off the diagonal
    assert c.stress(1.0)[0, 1] == pytest.approx(-1.0)


def test_an_isotropic_assembly_has_the_isotropic_shares():
    rng = np.random.default_rng(3)
    u = rng.normal(size=(200_000, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    f = fabric(grain_contacts(u, u))  # unit forces along unit branches
    assert [b["contacts"] for b in f.bands] == pytest.approx(isotropic_shares(), abs=4e-3)
    np.testing.assert_allclose(f.tensor, np.eye(3) / 3, atol=4e-3)
    assert sum(isotropic_shares()) == pytest.approx(1.0) and sum(isotropic_shares(dim=2)) == pytest.approx(1.0)


def test_distance_of_fabrics():
    u = np.eye(3)
    axial = fabric(grain_contacts(u, u))
    lateral = fabric(grain_contacts(u[1:], u[1:]))
    assert axial.distance(axial, "contacts") == 0.0
    # the axial fabric holds one contact in 0-30 and two in 70-90: a third of it differs
    assert axial.distance(lateral, "contacts") == pytest.approx(1 / 3)
    assert axial.distance(lateral, "sig_lateral") == pytest.approx(0.0)
    assert math.isnan(lateral.bands[0]["sig_axial"]) and lateral.stress_ratio == 0.0
    other = fabric(grain_contacts(u, u), bands=((0.0, 45.0), (45.0, 90.0)))
    with pytest.raises(InputError, match="bands"):
        axial.distance(other, "contacts")


def test_bad_bands_and_force_free_states_are_refused():
    u = np.eye(3)
    with pytest.raises(InputError, match="0-90"):
        fabric(grain_contacts(u, u), bands=((0.0, 30.0), (40.0, 90.0)))
    with pytest.raises(InputError, match="no contact carries"):
        fabric(grain_contacts(u, -u))
    with pytest.raises(InputError, match="zero length"):
        grain_contacts(np.zeros((1, 3)), np.ones((1, 3)))


def test_the_lab_tests_record_the_fabric_and_the_cli_writes_it(tmp_path, cli):
    params = Params(**{**SAND, "alpha0": math.radians(55.0)})
    r = run_triaxial(params, [1e5, 2e5], 0.02, sphere=Sphere(order=17, n_azimuth=2), step=1e-3,
                     contact_fabric=True)
    fabrics = r.meta["contact_fabric"]
    assert len(fabrics["consolidated"]) == len(fabrics["final"]) == 2
    assert fabrics["consolidated"][0]["stress_ratio"] == pytest.approx(1.0, abs=1e-9)
    end = r.point(0).stage("shear")
    assert fabrics["final"][0]["stress_ratio"] == pytest.approx(
        end["sig11"][-1] / (0.5 * (end["sig22"][-1] + end["sig33"][-1])), rel=1e-9)
    assert "contact_fabric" not in run_triaxial(params, 1e5, 0.002, sphere=Sphere(order=7), step=1e-3).meta
    b = run_biaxial(Params(n_theta=36), 1e5, 0.01, step=1e-3, contact_fabric=True)
    assert b.meta["contact_fabric"]["final"][0]["tensor"][0][0] > 0.5  # 2D: 1/2 isotropic
    out = tmp_path / "t"
    code, stdout, _ = cli("run", "biaxial", "--p0", "100kPa", "--param", "n_theta=36", "--axial-strain", "0.01",
                          "--step", "1e-3", "--contact-fabric", "--out", out)
    assert code == 0 and (out / "contact_fabric.png").exists()
    with open(out / "contact_fabric.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["state"] for r in rows] == ["consolidated"] * len(TILT_BANDS) + ["final"] * len(TILT_BANDS)
    assert sum(float(r["contacts"]) for r in rows[:len(TILT_BANDS)]) == pytest.approx(1.0)
    assert rows == [{k: str(v) for k, v in row.items()} for row in fabric_rows(
        [({"point": 0, "state": s}, run_biaxial(Params(n_theta=36), 1e5, 0.01, step=1e-3, contact_fabric=True)
          .meta["contact_fabric"][s][0]) for s in ("consolidated", "final")])]


def test_cells_without_contacts_are_refused():
    class Own:
        state_kind = "own"
        name = "own-cells"

    class FakeRev:
        solver = Own()
        own_meso = True

    with pytest.raises(InputError, match="own-cells"):
        check_contacts(FakeRev())


@pytest.mark.yade
def test_the_cli_refuses_the_fabric_of_richer_dem_cells_in_one_line(tmp_path, cli):
    out = tmp_path / "dem"
    cli.refuses(["run", "biaxial", "--p0", "100kPa", "--solver", "dem:hexagon-center", "--contact-fabric",
                 "--out", out], "contact fabric", out)


def test_a_dem_sample_state_s_fabric_is_its_contacts():
    from hmodel.dem.sample.state import SampleState

    # two spheres side by side along x and one contact across, in a 3D sample's contact rows
    contacts = np.array([[0, 1, 2.0, 0.0, 0.5, 0.0, 1e-3, 0.0, 0.0],
                         [1, 2, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1e-3]])
    state = SampleState(cell=(1e-2, 1e-2, 1e-2), radii=np.full(3, 5e-4), positions=np.zeros((3, 3)),
                        contacts=contacts)
    f = state.fabric()
    assert f["count"] == 2 and f["tensor"][0][0] == pytest.approx(0.5)
    assert f["stress_ratio"] == pytest.approx(2e-3 / (0.5 * 1e-3))
    np.testing.assert_allclose(fabric(grain_contacts(state.branches(), state.forces())).tensor, f["tensor"])
    assert SampleState(cell=(1.0, 1.0, 1.0), radii=np.ones(1), positions=np.zeros((1, 3)),
                       contacts=np.zeros((0, 9))).fabric() is None
