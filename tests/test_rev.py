"""The REV (eqs. 1.1, 1.13-1.21): symmetry, objectivity, tangent, volumes, Coulomb bound; the
isotropic response to isotropic strain for the 2D and the 3D REV alike (the 3D REV's own tests
are in test_rev3d.py)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hmodel import Params
from hmodel.cell import meso_volume
from hmodel.rev import Directions, Rev, Rev3D, Sphere


def _rot(beta):
    c, s = math.cos(beta), math.sin(beta)
    return np.array([[c, -s], [s, c]])


def _tensor(v):
    return np.array([[v[0], v[2]], [v[2], v[1]]])


@pytest.mark.parametrize("alpha_omega", [0.0, 0.6])
def test_weights_sum_to_one(alpha_omega):
    d = Directions.from_params(Params(n_theta=37, alpha_omega=alpha_omega, beta_omega=0.3))
    assert d.weights.sum() == pytest.approx(1.0, abs=1e-14)


@pytest.mark.parametrize("dim, rule, steps", [
    pytest.param(2, {"volume": v}, 50, id=f"2d-{v}") for v in ("hexagon", "rectangle", "box", "hexagon-consistent")
] + [
    pytest.param(3, {"order": o, "n_azimuth": m}, 100, id=f"3d-order{o}-m{m}")
    for o, m in ((3, 1), (7, 2), (17, 2), (35, 3))
])
def test_isotropic_fabric_and_equal_strains_give_isotropic_stress(dim, rule, steps):
    # Every cell sees the same normal strains, so every cell has the same state, and the stress
    # is (s_n - s_t) Σ w n⊗n + s_t I = isotropic because Σ w n⊗n = I/dim (in 3D: the rule is
    # exact to degree 2).
    rev = Rev(Params(n_theta=90, **rule)) if dim == 2 else Rev3D(Params(), Sphere(**rule))
    iso = np.zeros(rev.n_components)
    iso[:dim] = 2e-5
    s = rev.initial(1)
    for _ in range(steps):
        s = rev.step(s, iso[None])
    sig = s.sig[0]
    assert sig[0] > 0
    np.testing.assert_allclose(sig[:dim], sig[0], rtol=1e-12)
    np.testing.assert_allclose(sig[dim:], 0.0, atol=1e-12 * sig[0])


@pytest.mark.parametrize("volume", ["hexagon", "box"])
def test_objectivity_rotating_fabric_and_loading_rotates_stress(volume):
    n = 36
    beta = 6 * math.pi / n  # a multiple of the direction spacing: the directions map onto themselves
    base = Params(n_theta=n, alpha_omega=0.5, beta_omega=0.0, volume=volume)
    turned = base.with_(beta_omega=beta)
    R = _rot(beta)
    rev0, rev1 = Rev(base), Rev(turned)
    s0, s1 = rev0.initial(1), rev1.initial(1)
    rng = np.random.default_rng(1)
    for _ in range(60):
        d = rng.normal(scale=1e-4, size=3) + np.array([1e-4, 0.5e-4, 0.0])
        t = R @ _tensor(d) @ R.T
        s0 = rev0.step(s0, d[None])
        s1 = rev1.step(s1, np.array([[t[0, 0], t[1, 1], t[0, 1]]]))
    expect = R @ _tensor(s0.sig[0]) @ R.T
    got = _tensor(s1.sig[0])
    np.testing.assert_allclose(got, expect, atol=1e-9 * np.abs(expect).max())


def _elastic_tangent_by_hand(p: Params) -> np.ndarray:
    """dsig/deps at the unloaded state from eq. 1.7 linearised, written independently here."""
    d = 2 * p.radius
    a = p.alpha0
    c, s = math.cos(a), math.sin(a)
    A = np.array([[2 * c, 1, -2 * d * s], [2 * s, 0, 2 * d * c], [c, -1, -p.kt * d * (p.g2 + s) / p.kn]])
    th = np.arange(p.n_theta) * math.pi / p.n_theta
    w = (1 + p.alpha_omega * np.cos(2 * (th - p.beta_omega))) / p.n_theta
    V0 = 2 * d * s * (d + d * c)  # hexagon, eq. 1.20
    D = np.zeros((3, 3))
    for j, e in enumerate(np.eye(3)):
        for ti, wi in zip(th, w):
            n_, t_ = np.array([math.cos(ti), math.sin(ti)]), np.array([-math.sin(ti), math.cos(ti)])
            E = _tensor(e)
            dl = np.array([-p.l10 * n_ @ E @ n_, -p.l20 * t_ @ E @ t_])
            dd1, dd2, da = np.linalg.solve(A, [dl[0], dl[1], 0.0])
            dN1, dN2, dT1 = -p.kn * dd1, -p.kn * dd2, p.kt * d * da
            vnn = 4 * dN1 * d * c * c + 4 * dT1 * d * c * s + 2 * dN2 * d
            vtt = 4 * dN1 * d * s * s - 4 * dT1 * d * c * s
            sig = vnn * np.outer(n_, n_) + vtt * np.outer(t_, t_)
            D[:, j] += wi * np.array([sig[0, 0], sig[1, 1], sig[0, 1]]) / V0
    return D


@pytest.mark.parametrize("alpha_omega", [0.0, 0.4])
def test_small_strain_tangent_matches_finite_differences(alpha_omega):
    # From the unloaded state every contact opens under extension, so probe directions that
    # compress every cell (deps_nn > 0 and deps_tt > 0 in all directions).
    p = Params(n_theta=24, alpha_omega=alpha_omega, beta_omega=0.2)
    rev = Rev(p)
    D = _elastic_tangent_by_hand(p)
    h = 1e-9
    for e in ([1.0, 0.5, 0.0], [0.5, 1.0, 0.0], [1.0, 1.0, 0.4], [1.0, 0.7, -0.3]):
        e = np.array(e)
        fd = rev.step(rev.initial(1), (h * e)[None]).sig[0] / h
        assert not rev.step(rev.initial(1), (h * e)[None]).flags.broken.any()
        np.testing.assert_allclose(fd, D @ e, rtol=1e-6, atol=1e-7 * np.abs(fd).max())


def test_isotropic_elastic_tangent_is_isotropic():
    D = _elastic_tangent_by_hand(Params(n_theta=36))
    assert D[0, 0] == pytest.approx(D[1, 1], rel=1e-12) and D[0, 1] == pytest.approx(D[1, 0], rel=1e-12)
    assert abs(D[0, 2]) < 1e-9 * D[0, 0] and abs(D[2, 0]) < 1e-9 * D[0, 0]


@pytest.mark.parametrize("volume", ["hexagon-consistent", "rectangle"])
def test_consistent_volumes_follow_the_localization(volume):
    # With the virtual rectangle (eq. 1.21) the hexagon's area follows (1 - deps_nn)(1 - deps_tt);
    # with the rectangle (eq. 1.18) so does l1*l2 by construction.
    p = Params(n_theta=12, volume=volume)
    rev = Rev(p)
    s = rev.initial(1)
    for _ in range(20):
        s = rev.step(s, np.array([[1e-4, 2e-5, 3e-5]]))
    v0 = meso_volume(p, s.cells)[0]
    de = np.array([1e-6, -2e-6, 0.5e-6])
    s2 = rev.step(s, de[None])
    v1 = meso_volume(p, s2.cells)[0]
    th = rev.directions.theta
    enn = de[0] * np.cos(th) ** 2 + de[1] * np.sin(th) ** 2 + 2 * de[2] * np.sin(th) * np.cos(th)
    ett = de[0] * np.sin(th) ** 2 + de[1] * np.cos(th) ** 2 - 2 * de[2] * np.sin(th) * np.cos(th)
    np.testing.assert_allclose(v1 / v0, (1 - enn) * (1 - ett), rtol=1e-10)


def test_macro_volume_follows_macro_strain():
    rev = Rev(Params(n_theta=6))
    eps = np.array([[0.01, -0.02, 0.005]])
    assert rev.macro_volume(eps)[0] == pytest.approx(rev.volume0 * (0.99 * 1.02 - 0.005 ** 2))


@pytest.mark.parametrize("beta_deg, major", [(0.0, 0), (90.0, 1)])
def test_anisotropic_fabric_stiffer_along_its_major_direction(beta_deg, major):
    """Under isotropic strain every cell sees the same local strains, so the REV stress is the
    fabric average of one cell's (sigma_nn, sigma_tt), and eq. 1.17 gives
    sigma11 - sigma22 = (alpha_omega / 2) cos(2 beta_omega) (sigma_nn - sigma_tt) and
    sigma11 + sigma22 = sigma_nn + sigma_tt. At alpha0 = 45 deg a cell is stiffer along its axis
    (eq. 1.7 linearised by hand, ``_elastic_tangent_by_hand``), so the fabric's major direction
    (x1 for beta_omega = 0, x2 for 90 deg) carries the larger stress."""
    de = np.array([1e-5, 1e-5, 0.0])
    by_hand = _elastic_tangent_by_hand(Params(n_theta=1)) @ de  # a single cell along x1
    assert by_hand[0] > 1.2 * by_hand[1] > 0
    cell = Rev(Params(n_theta=1))
    one = cell.step(cell.initial(1), de[None]).sig[0]  # the same cell, one step of the REV
    np.testing.assert_allclose(one[:2], by_hand[:2], rtol=1e-4)
    a, beta = 0.5, math.radians(beta_deg)
    rev = Rev(Params(n_theta=72, alpha_omega=a, beta_omega=beta))
    s = rev.step(rev.initial(1), de[None]).sig[0]
    assert s[major] > 1.1 * s[1 - major] > 0
    assert s[0] - s[1] == pytest.approx(0.5 * a * math.cos(2 * beta) * (one[0] - one[1]), rel=1e-9)
    assert s[0] + s[1] == pytest.approx(one[0] + one[1], rel=1e-12)
    assert abs(s[2]) < 1e-9 * s[major]


increments = st.lists(st.tuples(*(st.floats(-2e-3, 2e-3, allow_nan=False) for _ in range(3))),
                      min_size=1, max_size=40)


@settings(max_examples=40, deadline=None)
@given(path=increments, rule=st.sampled_from(["report", "equilibrium"]),
       volume=st.sampled_from(["hexagon", "rectangle", "box", "hexagon-consistent"]))
def test_coulomb_bound_and_finiteness_on_random_paths(path, rule, volume):
    p = Params(n_theta=18, sliding_rhs=rule, volume=volume)
    rev = Rev(p)
    s = rev.step(rev.initial(1), np.array([[5e-4, 5e-4, 0.0]]))  # some confinement first
    for d in path:
        s = rev.step(s, np.array([d]))
        c = s.cells
        assert np.all(np.isfinite(c.values)) and np.all(np.isfinite(s.sig))
        assert np.all(np.abs(c.T1) <= p.tan_phi * c.N1 * (1 + 1e-12) + 1e-9)
        assert np.all(c.N1 >= 0) and np.all(c.N2 >= 0)
