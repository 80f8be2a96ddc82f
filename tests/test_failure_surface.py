"""The failure surface in the π-plane: the Mohr–Coulomb, Matsuoka–Nakai and
Lade–Duncan envelopes against independent checks, and the constant-p driver along rays of
fixed Lode angle."""

import math

import numpy as np
import pytest

from hmodel import Params
from hmodel.errors import InputError
from hmodel.failure_surface import (
    FailureSurface,
    check_lode,
    failure_surface,
    friction_angle,
    full_envelope,
    lade_duncan,
    lade_duncan_k,
    matsuoka_nakai,
    matsuoka_nakai_k,
    mohr_coulomb,
    phi_compression,
    phi_extension,
    principal_stresses,
    ray_direction,
    ray_segment,
)
from hmodel.loading.result import lode_b
from hmodel.rev import Sphere

LODE = np.linspace(0.0, 60.0, 13)


def invariants(s):
    s1, s2, s3 = np.moveaxis(np.asarray(s), -1, 0)
    return s1 + s2 + s3, s1 * s2 + s2 * s3 + s3 * s1, s1 * s2 * s3


# -- the π-plane and the three criteria -----------------------------------------------------------

def test_rays_have_their_lode_angle_mean_stress_and_q_eq():
    sig = principal_stresses(200e3, 0.9, LODE)
    full = np.column_stack([sig, np.zeros((len(LODE), 3))])
    theta, b = lode_b(full)
    np.testing.assert_allclose(theta, LODE, atol=1e-9)
    np.testing.assert_allclose(sig.mean(axis=1), 200e3, rtol=1e-14)
    q = np.sqrt(0.5 * ((sig[:, 0] - sig[:, 1]) ** 2 + (sig[:, 1] - sig[:, 2]) ** 2 + (sig[:, 2] - sig[:, 0]) ** 2))
    np.testing.assert_allclose(q, 0.9 * 200e3, rtol=1e-13)
    assert np.all(sig[:, 0] >= sig[:, 1] - 1e-9) and np.all(sig[:, 1] >= sig[:, 2] - 1e-9)
    d = ray_direction(LODE)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, rtol=1e-14)
    np.testing.assert_allclose(d.sum(axis=1), 0.0, atol=1e-15)


@pytest.mark.parametrize("phi", [20.0, 30.0, 40.0])
def test_mohr_coulomb_by_its_definition_and_its_strength_ratio(phi):
    r = mohr_coulomb(phi, LODE)
    # on the envelope, (σ1 - σ3)/(σ1 + σ3) = sin φ at every Lode angle
    np.testing.assert_allclose(friction_angle(principal_stresses(1.0, r, LODE)), phi, rtol=1e-12)
    s = math.sin(math.radians(phi))
    assert r[0] == pytest.approx(6 * s / (3 - s), rel=1e-14)  # compression
    assert r[-1] == pytest.approx(6 * s / (3 + s), rel=1e-14)  # extension
    assert r[-1] / r[0] == pytest.approx((3 - s) / (3 + s), rel=1e-13)
    assert phi_compression(r[0]) == pytest.approx(phi, rel=1e-13)
    assert phi_extension(r[-1]) == pytest.approx(phi, rel=1e-13)


@pytest.mark.parametrize("mc", [0.8, 1.2, 1.6])
def test_matsuoka_nakai_and_lade_duncan_through_the_compression_point(mc):
    kmn, kld = matsuoka_nakai_k(mc), lade_duncan_k(mc)
    s = 3 * mc / (6 + mc)  # the same friction angle in compression
    assert kmn == pytest.approx((9 - s * s) / (1 - s * s), rel=1e-12)
    assert kld == pytest.approx((3 - s) ** 3 / ((1 + s) * (1 - s) ** 2), rel=1e-12)
    rmn, rld = matsuoka_nakai(kmn, LODE), lade_duncan(kld, LODE)
    assert rmn[0] == pytest.approx(mc, rel=1e-12) and rld[0] == pytest.approx(mc, rel=1e-12)
    # the invariants of the stresses on each envelope give back the constants
    i1, i2, i3 = invariants(principal_stresses(150e3, rmn, LODE))
    np.testing.assert_allclose(i1 * i2 / i3, kmn, rtol=1e-10)
    i1, i2, i3 = invariants(principal_stresses(150e3, rld, LODE))
    np.testing.assert_allclose(i1 ** 3 / i3, kld, rtol=1e-10)
    # Matsuoka–Nakai passes through the Mohr–Coulomb corners (equal φ in compression and
    # extension); Lade–Duncan lies outside it in extension; both lie outside Mohr–Coulomb
    mc_r = mohr_coulomb(math.degrees(math.asin(s)), LODE)
    assert rmn[-1] == pytest.approx(mc_r[-1], rel=1e-10)
    assert np.all(rmn >= mc_r * (1 - 1e-12)) and np.all(rld >= rmn * (1 - 1e-12))


@pytest.mark.parametrize("criterion", ["mc", "mn", "ld"])
def test_envelopes_are_convex_in_the_pi_plane(criterion):
    f = {"mc": lambda t: mohr_coulomb(35.0, t), "mn": lambda t: matsuoka_nakai(matsuoka_nakai_k(1.4), t),
         "ld": lambda t: lade_duncan(lade_duncan_k(1.4), t)}[criterion]
    xy = full_envelope(f, 121)
    e = np.diff(np.vstack([xy, xy[:1]]), axis=0)
    cross = e[:, 0] * np.roll(e[:, 1], -1) - e[:, 1] * np.roll(e[:, 0], -1)
    scale = np.abs(cross).max()
    assert np.all(cross <= 1e-9 * scale) or np.all(cross >= -1e-9 * scale)


def test_bad_lode_angles_are_refused():
    with pytest.raises(InputError, match=r"\[0, 60\].*61"):
        check_lode([0, 61])
    with pytest.raises(InputError, match="Lode"):
        check_lode([math.nan])
    assert check_lode(13).tolist() == [0.0, 13.0]
    with pytest.raises(InputError, match="mean stress"):
        failure_surface(Params(), -1.0, [0])


def test_ray_segment_rows():
    seg = ray_segment(2e5, 20.0, 0.01, 10)
    M = seg.matrix
    d = ray_direction(20.0)
    # strain row ∝ d (conjugate to q_eq), stress rows p and e ⊥ d, shears held
    np.testing.assert_allclose(M[0, :3], math.sqrt(2 / 3) * d, rtol=1e-14)
    assert M[2, :3] @ d == pytest.approx(0.0, abs=1e-15) and M[2, :3].sum() == pytest.approx(0.0, abs=1e-15)
    assert seg.stress_rows == (False, True, True, False, False, False)


# -- the driver ---------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def cheap():
    return failure_surface(Params(sliding_rhs="equilibrium"), 200e3, [0.0, 30.0, 60.0],
                           sphere=Sphere(order=9), max_strain=0.04)


def test_driver_keeps_p_and_b_on_each_ray(cheap: FailureSurface):
    P = cheap.paths
    for i, t in enumerate(cheap.lode):
        ray = (P["point"] == i) & (P["stage"] == "ray")
        assert ray.sum() > 50
        np.testing.assert_allclose(P["p"][ray], 200e3, rtol=1e-8)
        loaded = ray & (P["q_eq"] > 1e-3 * 200e3)
        np.testing.assert_allclose(P["lode"][loaded], t, atol=1e-6)
        tan = math.tan(math.radians(t))
        np.testing.assert_allclose(P["b"][loaded], 2 * tan / (math.sqrt(3) + tan), atol=1e-6)
        np.testing.assert_allclose(np.column_stack([P["sig23"], P["sig13"], P["sig12"]])[ray], 0.0,
                                   atol=1e-6 * 200e3)


def test_driver_peaks_are_finite_and_on_their_rays(cheap: FailureSurface):
    assert cheap.lode.tolist() == [0.0, 30.0, 60.0]
    assert np.all(np.isfinite(cheap.ratio)) and cheap.ratio[0] > 0.5
    np.testing.assert_allclose(cheap.lode_reached, cheap.lode, atol=1e-6)
    np.testing.assert_allclose(cheap.principal.mean(axis=1), 200e3, rtol=1e-8)
    assert cheap.phi_compression == pytest.approx(float(cheap.phi[0]), rel=1e-9)
    fits = cheap.fits()
    for v in fits.values():
        assert v[0] == pytest.approx(cheap.ratio[0], rel=1e-12)
    assert set(cheap.ended) <= {"past peak", "newton", "max strain"}
    assert len(cheap.table()) == 3 and cheap.strength_ratio > 0


def test_default_rule_is_among_the_offered_ones():
    # docs/model3d.md, "Convergence in directions": the default and the offered orders
    from hmodel.rev.sphere import DEFAULT_AZIMUTHS, DEFAULT_ORDER, OFFERED, ORDERS
    assert DEFAULT_ORDER in OFFERED and set(OFFERED) <= set(ORDERS)
    assert list(OFFERED) == sorted(OFFERED)
    s = Sphere()
    assert (s.order, s.n_azimuth) == (DEFAULT_ORDER, DEFAULT_AZIMUTHS)


def test_compression_peak_against_an_independent_constant_p_triaxial_test():
    # The ray at θ = 0 driven by ε_s is the constant-p triaxial compression driven by ε11 with
    # σ22 = σ33 (other rows, other strain variable, the same stress path): the same peak
    # q_eq/p up to the increments (measured 3e-6 at order 9).
    from hmodel.loading import Recorder, Segment, consolidate, run_segment
    from hmodel.rev import Rev3D

    params, sphere = Params(sliding_rhs="equilibrium"), Sphere(order=9)
    fs = failure_surface(params, 200e3, [0.0], sphere=sphere, max_strain=0.1)
    assert fs.ended == ("past peak",)
    rev = Rev3D(params, sphere)
    M = np.eye(6)
    M[1, :3] = 1 / 3
    M[2, :3] = (0.0, 1.0, -1.0)
    rec = Recorder()
    run_segment(rev, consolidate(rev, 200e3), Segment((False, True, True, False, False, False), M,
                np.array([0.08, 200e3, 0.0, 0.0, 0.0, 0.0]), 800, "shear"), rec)
    res = rec.result()
    assert res["q_eq"].max() / 200e3 == pytest.approx(fs.ratio[0], rel=1e-4)
    assert res["eps11"][np.argmax(res["q_eq"])] == pytest.approx(fs.strain[0, 0], abs=2e-4)


# -- sizes and the tension cut-off ---------------------------------------------------------------

def _no_rev(*args, **kwargs):
    raise AssertionError("the REV was built before the request was checked")


def test_increments_and_rays_are_counted_before_anything_is_built(monkeypatch):
    import hmodel.failure_surface as fsm
    from hmodel.limits import WorkTooLarge

    monkeypatch.setattr(fsm, "Rev3D", _no_rev)
    with pytest.raises(WorkTooLarge, match=r"increments of each ray .*: 9e\+08 exceeds the limit"):
        failure_surface(Params(), 2e5, [0], step=1e-9, max_strain=0.9)
    # each ray within the limit, the rays together not: 4 rays × 300 increments
    monkeypatch.setenv("HMODEL_MAX_INCREMENTS", "1000")
    with pytest.raises(WorkTooLarge, match=r"failure surface \(4 rays × 300\): 1\.2e\+03 exceeds the limit of 1e\+03"):
        failure_surface(Params(), 2e5, [0, 13, 30, 60], max_strain=0.03)
    with pytest.raises(AssertionError, match="the REV was built"):  # 3 rays × 300 pass
        failure_surface(Params(), 2e5, [0, 30, 60], max_strain=0.03)
    monkeypatch.delenv("HMODEL_MAX_INCREMENTS")
    # the paths' table: 4 rays × (3000 + 2) rows, against the rows limit and, of 26 columns
    # (limits.table_bytes: 12.5 MB), against the memory limit
    monkeypatch.setenv("HMODEL_MAX_ROWS", "12000")
    with pytest.raises(WorkTooLarge, match=r"paths \(4 rays × 3002 rows\): a result table of 1\.2e\+04 rows"):
        failure_surface(Params(), 2e5, [0, 13, 30, 60])
    monkeypatch.delenv("HMODEL_MAX_ROWS")
    monkeypatch.setenv("HMODEL_MEMORY_LIMIT", "10MB")
    with pytest.raises(WorkTooLarge, match=r"paths \(12008 rows\) needs about 11\.9 MiB of memory"):
        failure_surface(Params(), 2e5, [0, 13, 30, 60])
    monkeypatch.setenv("HMODEL_MEMORY_LIMIT", "20MB")
    with pytest.raises(AssertionError, match="the REV was built"):
        failure_surface(Params(), 2e5, [0, 13, 30, 60])


def test_the_number_of_lode_angles_is_bounded():
    from hmodel.failure_surface import MAX_LODE_ANGLES
    from hmodel.limits import WorkTooLarge

    assert len(check_lode(np.linspace(0.0, 60.0, MAX_LODE_ANGLES))) == MAX_LODE_ANGLES
    assert len(check_lode([30.0] * 5000)) == 2  # repeated angles are one ray
    with pytest.raises(WorkTooLarge, match=f"5001 Lode angles \\(with 0\\): at most {MAX_LODE_ANGLES}"):
        check_lode(np.linspace(0.0, 60.0, 5001)[1:])


def test_a_ray_on_the_tension_cut_off_has_no_peak(tmp_path, capsys):
    """A strong fabric along axis 1 with one azimuth: on the rays at 30° and 60° σ3 falls to 0
    and stays there (q_eq/p = -3 / (2 cos θ3), φ = 90°). Those rays end there, soon, with no
    friction angle or strength ratio, and say so in the CSV, the JSON and a warning."""
    import json

    from hmodel.cli.app import main
    from hmodel.failure_surface import CHUNK, TENSION

    sphere = Sphere(order=9, n_azimuth=1, alpha_omega=1.0, axis=(1.0, 0.0, 0.0))
    fs = failure_surface(Params(sliding_rhs="equilibrium"), 200e3, [30.0, 60.0], sphere=sphere)
    assert fs.ended == ("past peak", "tension cut-off", "tension cut-off")
    assert fs.peak.tolist() == [True, False, False]
    assert np.isfinite(fs.phi[0]) and np.all(np.isnan(fs.phi[1:])) and np.all(np.isnan(fs.ratio[1:]))
    assert math.isnan(fs.strength_ratio) and math.isnan(fs.phi_extension)
    P = fs.paths
    for i, t in ((1, 30.0), (2, 60.0)):
        ray = (P["point"] == i) & (P["stage"] == "ray")
        minor = np.column_stack([P["sig11"], P["sig22"], P["sig33"]])[ray].min(axis=1)
        # the path stops at its first state on the cut-off, within a chunk of reaching it
        assert minor[-1] <= TENSION * 200e3 and np.all(minor[:-1] > TENSION * 200e3)
        assert ray.sum() < 3000 - CHUNK
        q = P["q_eq"][ray][-1] / 200e3
        assert q == pytest.approx(-1.5 / math.cos(math.radians(t) + 2 * math.pi / 3), rel=2e-3)
    out = tmp_path / "fs"
    assert main(["failure-surface", "--fabric", "1", "--lode", "30,60", "--order", "9", "--azimuths", "1",
                 "--out", str(out)]) == 0
    printed = capsys.readouterr()
    assert "Lode  30.0°: no peak, σ3 fell to 0 (tension cut-off)" in printed.out
    assert "strength ratio: none" in printed.out
    assert printed.err.startswith("hmodel: warning: Lode 30°, 60°: the path reached the tension cut-off")
    assert printed.err.count("\n") == 1
    rows = (out / "failure_surface.csv").read_text().splitlines()
    header = rows[0].split(",")
    cut = dict(zip(header, rows[2].split(",")))
    assert cut["phi"] == cut["q_p"] == "" and cut["peak"] == "false" and cut["ended"] == "tension cut-off"
    assert dict(zip(header, rows[1].split(",")))["peak"] == "true"
    info = json.loads((out / "failure_surface.json").read_text())
    assert info["phi"][1:] == [None, None] and info["strength_ratio"] is None
    assert info["peak"] == [True, False, False] and len(info["warnings"]) == 1
