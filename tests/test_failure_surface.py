"""The failure surface in the π-plane (issue 34): the Mohr–Coulomb, Matsuoka–Nakai and
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
