"""The closed-form H-cell (eqs. 1.3-1.12) against hand derivations and invariants."""

import math

import numpy as np
import pytest

from hmodel import Params
from hmodel.cell import CellState, ClosedFormSolver, meso_vsigma

SOLVER = ClosedFormSolver()


def test_first_increment_by_hand_from_eq_1_7():
    # alpha0 = 45 deg, r = 1, kt/kn = 1/2, g2 = 0: c = s = k = 1/sqrt(2), d1 = d2 = 2, no force,
    # so A = [[2k, 1, -4k], [2k, 0, 4k], [k, -1, -k]] (A33 = -kt d1 s/kn = -k). Eliminating
    # dd2 = k dd1 - k da from row 3 gives 3 dd1 - 5 da = dl1/k and dd1 + 2 da = dl2/(2k), so
    # da = (1.5 dl2 - dl1)/(11 k), dd1 = dl2/(2k) - 2 da.
    p = Params()
    k = 1 / math.sqrt(2)
    dl1, dl2 = -p.l10 * 1e-5, -p.l20 * 0.4e-5
    da = (1.5 * dl2 - dl1) / (11 * k)
    dd1 = dl2 / (2 * k) - 2 * da
    dd2 = k * dd1 - k * da
    s, f = SOLVER.step(p, CellState.initial(p), dl1, dl2)
    assert s.d1 == pytest.approx(2 + dd1, rel=1e-14, abs=1e-16)
    assert s.d2 - 2 == pytest.approx(dd2, rel=1e-10)
    assert s.alpha - math.pi / 4 == pytest.approx(da, rel=1e-10)
    assert s.N1 == pytest.approx(-p.kn * dd1, rel=1e-10)
    assert s.N2 == pytest.approx(-p.kn * dd2, rel=1e-10)
    assert s.T1 == pytest.approx(p.kt * 2 * da, rel=1e-10)  # dT1 = kt d1 dalpha
    assert not f.sliding and abs(s.T1) < p.tan_phi * s.N1


def test_equilibrium_of_grain_2_holds_without_sliding():
    # Row 3 of eq. 1.7 is eq. 1.5 differentiated: N2 = N1 cos a + (g2 + sin a) T1 to O(step^2).
    for g2 in (0, 1):
        p = Params(g2=g2)
        s = CellState.initial(p)
        for _ in range(200):
            s, f = SOLVER.step(p, s, -p.l10 * 2e-6, -p.l20 * 1e-6)
        assert not f.sliding
        eq = s.N1 * np.cos(s.alpha) + (g2 + np.sin(s.alpha)) * s.T1
        assert s.N2 == pytest.approx(eq, rel=1e-4)


def test_sliding_stays_on_coulomb_cone():
    p = Params()
    s = CellState.initial(p)
    seen = False
    for _ in range(300):  # compress along n, stretch along t: alpha opens, T1 grows
        s, f = SOLVER.step(p, s, -p.l10 * 1e-4, p.l20 * 0.5e-4)
        if f.sliding:
            seen = True
            assert abs(s.T1) == pytest.approx(p.tan_phi * s.N1, rel=1e-12)
    assert seen


@pytest.mark.parametrize("rule", ["report", "equilibrium"])
def test_rules_agree_for_positive_sliding(rule):
    # eq. 1.10's two readings differ only when the contact slides with T1 < 0.
    p = Params(sliding_rhs=rule)
    q = Params(sliding_rhs="equilibrium")
    s = t = CellState.initial(p)
    for _ in range(100):
        s, _ = SOLVER.step(p, s, -p.l10 * 1e-4, p.l20 * 0.5e-4)
        t, _ = SOLVER.step(q, t, -p.l10 * 1e-4, p.l20 * 0.5e-4)
    assert np.all(s.T1 >= 0)
    np.testing.assert_allclose(s.values, t.values, rtol=1e-12)


def test_zero_increment_changes_nothing_with_equilibrium_rule():
    p = Params(sliding_rhs="equilibrium")
    s = CellState.initial(p)
    for _ in range(300):  # alpha closes: T1 < 0 until it slides
        s, f = SOLVER.step(p, s, p.l10 * 0.3e-4, -p.l20 * 1e-4)
    assert f.sliding and s.T1 < 0
    s2, f2 = SOLVER.step(p, s, 0.0, 0.0)
    np.testing.assert_array_equal(s2.values, s.values)


def test_report_rule_breaks_a_cell_sliding_with_negative_t1():
    # Documented behaviour of DESIGN.md's lambda (as in the report's code): with xi = -1 it
    # is off by 2 (g2 + sin a) T1/kn, which opens the sliding contact at the first step.
    p = Params(sliding_rhs="report")
    q = Params(sliding_rhs="equilibrium")
    s = CellState.initial(q)
    for _ in range(300):
        s, f = SOLVER.step(q, s, p.l10 * 0.3e-4, -p.l20 * 1e-4)
    assert f.sliding and s.T1 < 0
    s2, f2 = SOLVER.step(p, s, 0.0, 0.0)
    assert f2.broken and s2.N1 == 0 and s2.N2 == 0 and s2.T1 == 0


def test_lost_contact_1_makes_the_cell_force_free():
    p = Params()
    # A loaded cell whose contact 1 opens: d1 just below 2r, pulled apart along n and t.
    s = CellState.from_fields(d1=2 - 1e-6, d2=2 - 1e-3, alpha=p.alpha0, N1=p.kn * 1e-6,
                              N2=p.kn * 1e-3, T1=0.0, l1=p.l10, l2=p.l20)
    s2, f = SOLVER.step(p, s, 0.0, 1e-3)  # widen the cell: d1 grows past 2r
    assert f.open1 and not f.open2 and s2.d1 > 2
    assert s2.N1 == s2.N2 == s2.T1 == 0 and not f.sliding
    np.testing.assert_array_equal(meso_vsigma(p, s2), 0.0)


def test_lost_contact_2_makes_the_cell_force_free():
    p = Params()
    s = CellState.from_fields(d1=2 - 1e-3, d2=2 - 1e-6, alpha=p.alpha0, N1=p.kn * 1e-3,
                              N2=p.kn * 1e-6, T1=0.0, l1=p.l10, l2=p.l20)
    s2, f = SOLVER.step(p, s, 1e-3, 0.0)  # lengthen the cell along n: d2 grows past 2r
    assert f.open2 and not f.open1 and s2.d2 > 2
    assert s2.N1 == s2.N2 == s2.T1 == 0
    np.testing.assert_array_equal(meso_vsigma(p, s2), 0.0)


def test_extension_from_rest_opens_contacts_by_loading():
    p = Params()
    s, f = SOLVER.step(p, CellState.initial(p), p.l10 * 1e-3, p.l20 * 1e-3)
    assert f.broken and s.N1 == s.N2 == s.T1 == 0


def _hand_vsigma(d1, d2, a, n1, n2, t1):
    c, s = math.cos(a), math.sin(a)
    return (4 * n1 * d1 * c * c + 4 * t1 * d1 * c * s + 2 * n2 * d2,
            4 * n1 * d1 * s * s - 4 * t1 * d1 * c * s)


def test_extra_contact_1_4_adds_to_sigma_nn():
    p = Params()
    v = dict(d1=1.99, d2=1.98, alpha=math.radians(89), N1=2e6, N2=4e6, T1=1e5)
    l1 = 1.9  # grains 1 and 4 overlap (Fig. 1.6)
    s = CellState.from_fields(**v, l1=l1, l2=3.9)
    vnn, vtt = meso_vsigma(p, s)
    hnn, htt = _hand_vsigma(*v.values())
    assert vnn == pytest.approx(hnn + p.kn * (2 - l1) * l1, rel=1e-12)
    assert vtt == pytest.approx(htt, rel=1e-12)


def test_extra_contacts_2_6_add_to_sigma_tt():
    p = Params()
    v = dict(d1=1.99, d2=1.98, alpha=math.radians(31), N1=2e6, N2=4e6, T1=-1e5)
    l2 = 1.95
    s = CellState.from_fields(**v, l1=5.3, l2=l2)
    vnn, vtt = meso_vsigma(p, s)
    hnn, htt = _hand_vsigma(*v.values())
    assert vnn == pytest.approx(hnn, rel=1e-12)
    assert vtt == pytest.approx(htt + 2 * p.kn * (2 - l2) * l2, rel=1e-12)


def test_overcompression_flags_raised_by_loading():
    p = Params(alpha0=math.radians(31))  # l20 = 4 sin 31 deg = 2.06 r: close to 2r
    s = CellState.initial(p)
    for _ in range(40):
        s, f = SOLVER.step(p, s, 0.0, -p.l20 * 1e-3)
    assert f.contact26 and s.l2 <= 2
    assert meso_vsigma(p, s)[1] > _hand_vsigma(s.d1, s.d2, s.alpha, s.N1, s.N2, s.T1)[1]
    p = Params(alpha0=math.radians(89))  # l10 = 2r (1 + 2 cos 89 deg) = 2.07 r
    s = CellState.initial(p)
    for _ in range(40):
        s, f = SOLVER.step(p, s, -p.l10 * 1e-3, 0.0)
    assert f.contact14 and s.l1 <= 2


def test_singular_system_raises_with_location():
    from hmodel import SolverError
    p = Params()
    # d1 = 0 makes the third column of A vanish: eq. 1.7 is singular.
    s = CellState.from_fields(d1=0.0, d2=2.0, alpha=p.alpha0, N1=0.0, N2=0.0, T1=0.0, l1=2.0, l2=0.0)
    with pytest.raises(SolverError, match="could not be solved"):
        SOLVER.step(p, s, -1e-4, -1e-4)


def test_batch_equals_one_by_one():
    p = Params()
    rng = np.random.default_rng(0)
    s = CellState.initial(p, (4, 5))
    dl = rng.normal(scale=1e-4, size=(4, 5, 2)) - 1e-4
    for _ in range(20):
        s, _ = SOLVER.step(p, s, dl[..., 0], dl[..., 1])
    one = CellState.initial(p)
    for _ in range(20):
        one, _ = SOLVER.step(p, one, dl[2, 3, 0], dl[2, 3, 1])
    np.testing.assert_array_equal(s.values[2, 3], one.values)
