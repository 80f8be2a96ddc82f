"""The bi-hexagonal 3D cell (docs/model3d.md) against hand algebra, the 2D H-cell, finite
differences of its own equations and the Coulomb bound."""

import math

import numpy as np
import pytest

from hmodel import Params
from hmodel.cell import (
    BIHEX_FIELDS,
    BIHEX_FLAGS,
    BiHexSolver,
    CellState,
    ClosedFormSolver,
    meso_vsigma,
)
from hmodel.cell.bihex import bihex_volume
from hmodel.errors import InputError

SOLVER = BiHexSolver()
SOLVER2D = ClosedFormSolver()
A, B = slice(0, 8), slice(8, 16)


def hand_first_increment(p: Params, dl1: float, dl2: float):
    """(δd1, δd2, δα) of an unloaded hexagon by elimination in eq. 1.7 without sliding.

    Unloaded: d1 = d2 = d, N1 = T1 = 0, so A33 = -(kt/kn) d (g2 + s). Row 2 gives
    δd1 = (δl2 - 2 d c δα)/(2 s); rows 1 + 3 give 3 c δd1 + (A33 - 2 d s) δα = δl1; hence
    δα = (δl1 - 3 c δl2/(2 s)) / (A33 - 2 d s - 3 d c²/s) and δd2 = c δd1 + A33 δα.
    """
    d, c, s = 2 * p.radius, math.cos(p.alpha0), math.sin(p.alpha0)
    a33 = -p.kt_kn * d * (p.g2 + s)
    da = (dl1 - 3 * c * dl2 / (2 * s)) / (a33 - 2 * d * s - 3 * d * c * c / s)
    dd1 = (dl2 - 2 * d * c * da) / (2 * s)
    dd2 = c * dd1 + a33 * da
    return dd1, dd2, da


@pytest.mark.parametrize("g2", [0, 1])
@pytest.mark.parametrize("alpha0", [45.0, 50.0, 60.0])
def test_first_isotropic_increment_by_hand(g2, alpha0):
    p = Params(alpha0=math.radians(alpha0), g2=g2, radius=0.5e-3)
    eps = 1e-6
    s0 = SOLVER.initial(p)
    l1, l2 = s0.values[6], s0.values[7]
    s, f = SOLVER.step(p, s0, -eps * l1, -eps * l2, -eps * l2)
    dd1, dd2, da = hand_first_increment(p, -eps * l1, -eps * l2)
    d = 2 * p.radius
    for h in (A, B):  # both hexagons see the same lengths: the same increment
        v = s.values[h]
        assert v[0] - d == pytest.approx(dd1, rel=1e-9)
        assert v[1] - d == pytest.approx(dd2, rel=1e-9)
        assert v[2] - p.alpha0 == pytest.approx(da, rel=1e-9, abs=1e-18)
        assert v[3] == pytest.approx(-p.kn * dd1, rel=1e-9)
        assert v[4] == pytest.approx(-p.kn * dd2, rel=1e-9)
        assert v[5] == pytest.approx(p.kt * d * da, rel=1e-9, abs=1e-12)
        # eq. 1.5 (the closure) holds exactly for an increment from rest, at alpha0
        c, sn = math.cos(p.alpha0), math.sin(p.alpha0)
        assert v[4] == pytest.approx(v[3] * c + (g2 + sn) * v[5], rel=1e-12)
    assert not f.flags[[0, 5]].any() and not f.flags[[1, 2, 6, 7]].any()
    # Love-Weber over the twelve contacts: V sigma_nn gets both hexagons' eq. 1.12 nn terms.
    vs, vol = SOLVER.meso(p, s)
    N1, N2, T1, d1, a = s.values[3], s.values[4], s.values[5], s.values[0], s.values[2]
    nn = 4 * N1 * d1 * math.cos(a) ** 2 + 4 * T1 * d1 * math.cos(a) * math.sin(a) + 2 * N2 * s.values[1]
    tt = 4 * N1 * d1 * math.sin(a) ** 2 - 4 * T1 * d1 * math.cos(a) * math.sin(a)
    assert vs[:3] == pytest.approx([2 * nn, tt, tt], rel=1e-12)
    assert np.all(vs[3:] == 0)
    lstar = s.values[1] + d1 * math.cos(a)
    assert vol == pytest.approx(lstar * (2 * d1 * math.sin(a)) ** 2, rel=1e-14)


def random_lengths(rng, p, n, scale):
    """Length increments (n, 3) mixing shortening and lengthening."""
    return rng.normal(size=(n, 3)) * scale * np.array([p.l10, p.l20, p.l20]) - 0.3 * scale * np.array(
        [p.l10, p.l20, p.l20])


@pytest.mark.parametrize("rule", ["report", "equilibrium"])
def test_loading_in_one_plane_is_the_2d_cell(rule):
    # dl3 = 0: hexagon A is the 2D H-cell driven by (dl1, dl2), hexagon B the 2D H-cell driven
    # by (dl1, 0), with sliding and opening on the way (the construction decouples them).
    p = Params(sliding_rhs=rule)
    rng = np.random.default_rng(1)
    n_cells, n_steps = 40, 150
    s3 = SOLVER.initial(p, (n_cells,))
    sa = SOLVER2D.initial(p, (n_cells,))
    sb = SOLVER2D.initial(p, (n_cells,))
    seen = np.zeros(len(BIHEX_FLAGS), bool)
    for _ in range(n_steps):
        dl = random_lengths(rng, p, n_cells, 2e-4)
        s3, f3 = SOLVER.step(p, s3, dl[:, 0], dl[:, 1], 0.0)
        sa, fa = SOLVER2D.step(p, sa, dl[:, 0], dl[:, 1])
        sb, fb = SOLVER2D.step(p, sb, dl[:, 0], 0.0)
        np.testing.assert_array_equal(s3.values[:, A], sa.values)
        np.testing.assert_array_equal(s3.values[:, B], sb.values)
        np.testing.assert_array_equal(f3.flags[:, :5], fa.flags)
        np.testing.assert_array_equal(f3.flags[:, 5:10], fb.flags)
        seen |= f3.flags.any(axis=0)
        vs, _ = SOLVER.meso(p, s3)
        va, vb = meso_vsigma(p, sa), meso_vsigma(p, sb)
        extra14 = np.where(sa.l1 <= 2 * p.radius, p.kn * (2 * p.radius - sa.l1) * sa.l1, 0.0)
        np.testing.assert_allclose(vs[:, 0], va[:, 0] + vb[:, 0] - extra14, rtol=1e-13, atol=1e-6)
        np.testing.assert_allclose(vs[:, 1], va[:, 1], rtol=1e-13, atol=1e-6)
        np.testing.assert_allclose(vs[:, 2], vb[:, 1], rtol=1e-13, atol=1e-6)
    assert seen[BIHEX_FLAGS.index("sliding")] and seen[BIHEX_FLAGS.index("open1")]


def test_swapping_t1_and_t2_swaps_the_hexagons():
    p = Params()
    rng = np.random.default_rng(2)
    s, t = SOLVER.initial(p, (20,)), SOLVER.initial(p, (20,))
    for _ in range(60):
        dl = random_lengths(rng, p, 20, 1e-4)
        s, _ = SOLVER.step(p, s, dl[:, 0], dl[:, 1], dl[:, 2])
        t, _ = SOLVER.step(p, t, dl[:, 0], dl[:, 2], dl[:, 1])
    np.testing.assert_array_equal(s.values[:, A], t.values[:, B])
    vs, vol_s = SOLVER.meso(p, s)
    vt, vol_t = SOLVER.meso(p, t)
    np.testing.assert_allclose(vs[:, [0, 2, 1]], vt[:, :3], rtol=1e-13)
    np.testing.assert_allclose(vol_s, vol_t, rtol=1e-13)


def residuals(p: Params, v: np.ndarray) -> np.ndarray:
    """The cell's own equations as residuals (n, 6), zero on an exact solution: per hexagon,
    eq. 1.2 (l1 - d2 - 2 d1 cos a, l - 2 d1 sin a) and eq. 1.5 (N2 - N1 cos a - (g2 + sin a) T1)."""
    out = []
    for h in (A, B):
        d1, d2, a, n1, n2, t1, l1, l2 = (v[:, h][:, k] for k in range(8))
        out += [l1 - d2 - 2 * d1 * np.cos(a), l2 - 2 * d1 * np.sin(a),
                n2 - n1 * np.cos(a) - (p.g2 + np.sin(a)) * t1]
    return np.stack(out, axis=1)


@pytest.mark.parametrize("g2", [0, 1])
def test_increment_is_the_tangent_of_its_own_equations(g2):
    # From loaded states (some sliding), an increment h of the lengths changes the residuals of
    # eqs. 1.2 and 1.5 by O(h^2) only: halving h divides the change by about 4. The forces
    # follow the contact law exactly (dN = -kn dd, T on the cone when sliding).
    p = Params(g2=g2, sliding_rhs="equilibrium")
    rng = np.random.default_rng(3)
    n = 200
    s = SOLVER.initial(p, (n,))
    iso = -2e-4 * np.array([p.l10, p.l20, p.l20])
    for _ in range(10):
        s, f = SOLVER.step(p, s, *iso)
    direction = rng.normal(size=(n, 3))
    direction = (direction - direction.mean(axis=1, keepdims=True)) * 2e-4 * np.array([p.l10, p.l20, p.l20])
    for _ in range(10):  # deviatoric steps: some contacts reach the cone (about 20 %)
        s, f = SOLVER.step(p, s, *direction.T)
    r0 = residuals(p, s.values)
    changes, regimes = [], []
    for h in (1.0, 0.5, 0.25):
        new, fh = SOLVER.step(p, s, *(h * direction.T))
        changes.append(np.abs(residuals(p, new.values) - r0))
        regimes.append(fh.flags[:, [0, 5, 1, 2, 6, 7]])
        for side, cols in ((A, (0, 1)), (B, (5, 6))):
            dd1 = new.values[:, side][:, 0] - s.values[:, side][:, 0]
            slid = fh.flags[:, cols[0]]
            closed = ~fh.flags[:, cols[1]] & ~fh.flags[:, cols[1] + 1]
            np.testing.assert_allclose((new.values[:, side][:, 3] - s.values[:, side][:, 3])[closed],
                                       -p.kn * dd1[closed], rtol=1e-9, atol=1e-9)
            on_cone = slid & closed
            np.testing.assert_allclose(np.abs(new.values[:, side][:, 5][on_cone]),
                                       p.tan_phi * new.values[:, side][:, 3][on_cone], rtol=1e-12)
    # the cells whose regime (sliding, open) is the same at every h and before
    same = np.all([np.all(r == regimes[0], axis=1) for r in regimes], axis=0)
    same &= np.all(f.flags[:, [0, 5, 1, 2, 6, 7]] == regimes[0], axis=1)
    same &= ~regimes[0][:, 2:].any(axis=1)
    assert same.sum() > n // 2 and regimes[0][same, :2].any()  # some of them slide
    scale = np.array([p.l10, p.l20, p.kn * p.l10] * 2)
    c1, c2, c3 = (c[same] / scale for c in changes)
    big = c1 > 1e-14
    ratio1 = c1[big] / np.maximum(c2[big], 1e-300)
    ratio2 = c2[big] / np.maximum(c3[big], 1e-300)
    assert np.median(ratio1) == pytest.approx(4.0, rel=0.1)
    assert np.median(ratio2) == pytest.approx(4.0, rel=0.1)
    assert c1.max() < 1e-6  # second order in h ~ 1e-4 relative


def test_coulomb_bound_and_no_tension_on_random_paths():
    for rule in ("report", "equilibrium"):
        p = Params(sliding_rhs=rule, phi_g=math.radians(25))
        rng = np.random.default_rng(4)
        s = SOLVER.initial(p, (100,))
        for _ in range(200):
            dl = random_lengths(rng, p, 100, 1e-4)
            s, f = SOLVER.step(p, s, *dl.T)
            for h in (A, B):
                n1, n2, t1 = s.values[:, h][:, 3], s.values[:, h][:, 4], s.values[:, h][:, 5]
                assert np.all(n1 >= 0) and np.all(n2 >= 0)
                assert np.all(np.abs(t1) <= p.tan_phi * n1 * (1 + 1e-12) + 1e-9)
            broken_a = f.flags[:, 1] | f.flags[:, 2]
            assert np.all(s.values[broken_a][:, [3, 4, 5]] == 0)


def test_volume_options_and_refusals():
    p = Params(radius=1.0)
    s = SOLVER.initial(p, (2,))
    l1, l2 = p.l10, p.l20
    assert bihex_volume(p.with_(volume="rectangle"), s.values) == pytest.approx(l1 * l2 * l2)
    assert bihex_volume(p.with_(volume="box"), s.values) == pytest.approx((l1 + 2) * (l2 + 2) ** 2)
    with pytest.raises(InputError, match="hexagon-consistent"):
        SOLVER.step(p.with_(volume="hexagon-consistent"), s, 0.0, 0.0, 0.0)
    with pytest.raises(InputError, match="16 fields"):
        SOLVER.step(p, CellState(np.zeros((2, 8))), 0.0, 0.0, 0.0)
    assert len(BIHEX_FIELDS) == 16 and BIHEX_FIELDS[:8] == ("d1", "d2", "alpha", "N1", "N2", "T1", "l1", "l2")


def test_cross_flag_marks_hexagons_that_interpenetrate():
    # Grains 2 (A) and 7 (B) are sqrt(2) d1 sin(alpha) apart at rest: closer than 2r below 45°.
    for alpha0, expect in ((40.0, True), (60.0, False)):
        p = Params(alpha0=math.radians(alpha0))
        _, f = SOLVER.step(p, SOLVER.initial(p), 0.0, 0.0, 0.0)
        assert bool(f.flags[BIHEX_FLAGS.index("cross")]) is expect
