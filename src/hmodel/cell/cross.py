"""Contacts between the two hexagons of a bi-hexagon (``cross_contacts="frictionless"``,
docs/mechanisms.md, "Contacts between the two hexagons"; docs/model3d.md).

Grain 2 of hexagon A, at (-d2/2, l2/2, 0) in the cell frame (n, t1, t2), and grain 7 of
hexagon B, at (-d2_b/2, 0, l3/2), are dc = sqrt(D²/4 + l2²/4 + l3²/4) apart, D = d2 - d2_b; so
are the seven other pairs (2-10, 3-8, 3-9, 6-7, 6-10, 5-8, 5-9) by the cell's mirror
symmetries. Where they overlap (dc < 2r) each pair pushes with F(2r - dc) along the line of
centres (the cell's normal law: kn δ, or c δ^(3/2) of Hertz; no tangential force: the stated
assumption). On grain 2 the pair 7 and 10 gives (-F D/dc, F l2/dc, 0): the t2 parts cancel,
the t1 part goes to the external force that prescribes l2, and **-Y, Y = F D/dc, enters grain
2's balance along n** (eq. 1.5), +Y grain 7's: the only coupling of the two hexagons.

**Closure (derived, docs/mechanisms.md).** Eq. 1.7's third row of each hexagon, in forces (the
row times -kn; :mod:`hmodel.cell.hertz`), gains the change of the cross term over the increment,
with the cross force at the end of the increment: coef δN1 - δN2 + gt δα + kn λ - (Y' - Y) = 0
for A, + (Y' - Y) for B. Rows 1-2 of each hexagon give δd2 and δα affine in δd1 as in 2D
(:func:`hmodel.cell.hertz.affine`), and Y' depends on the solution through D' only, so the
coupled problem is one scalar equation in ΔY = Y' - Y: each hexagon solves its own third row
with ΔY as a force on its right-hand side (in closed form for linear contacts, by
:func:`hmodel.cell.hertz.solve` for Hertz's), which gives D'(ΔY); Newton's method on
Y(D'(ΔY)) - Y - ΔY = 0, with dD'/dΔY from each hexagon's row slope. Each hexagon sticks or
slides (eq. 1.3): an active set from the regimes of the trial at ΔY = 0; a hexagon whose trial
tangential force leaves the Coulomb cone at the coupled solution slides from the next pass on
(a sliding hexagon is not returned to sticking: the 2D rule, at most three passes).

Plain compiled functions called by :func:`hmodel.cell.bihex.bihex_increment` when the packed
parameter ``P_CROSS`` is set; a cell whose hexagons do not touch, before or after, takes the
two 2D increments unchanged.
"""

from __future__ import annotations

import math

from numba import njit

from . import hertz
from .closed_form import (
    P_HERTZ,
    P_KN,
    P_KT,
    P_R,
    P_TAN,
    angle_rows,
    cell_update,
    finish_update,
    hertz_overlaps,
    sliding_force,
    write_update,
)

#: Newton passes on ΔY at most; the residual, relative to the forces in the balance, at which
#: ΔY is the solution.
CROSS_PASSES = 50
CROSS_RTOL = 1e-13


@njit(cache=True, inline="always", error_model="numpy")
def cross_distance(dd2, l2, l3):
    """Distance of grains 2 (A) and 7 (B), and of the seven other cross pairs, with
    dd2 = d2 - d2_b."""
    return math.sqrt(0.25 * (dd2 * dd2 + l2 * l2 + l3 * l3))


@njit(cache=True, inline="always", error_model="numpy")
def cross_force(kn, c, two_r, dc):
    """``(F, dF/d dc)``: the normal force of one cross pair at distance dc (zero apart), linear
    kn (2r - dc) or Hertz c (2r - dc)^(3/2) (``c`` nonzero): the law of the extra contacts
    (:func:`hmodel.cell.hertz.extra_force`)."""
    gap = two_r - dc
    if gap <= 0.0:
        return 0.0, 0.0
    return hertz.extra_force(kn, c, gap), (-1.5 * c * math.sqrt(gap) if c != 0.0 else -kn)


@njit(cache=True, inline="always", error_model="numpy")
def cross_balance(kn, c, two_r, dd2, l2, l3):
    """``(Y, dY/d dd2)``: Y = F dd2 / dc, the cross forces' part of grain 7's balance along n
    (-Y of grain 2's), with dd2 = d2 - d2_b."""
    dc = cross_distance(dd2, l2, l3)
    f, df = cross_force(kn, c, two_r, dc)
    if f == 0.0:
        return 0.0, 0.0
    ddc = 0.25 * dd2 / dc
    return f * dd2 / dc, (df * ddc * dd2 + f) / dc - f * dd2 * ddc / (dc * dc)


@njit(cache=True, inline="always", error_model="numpy")
def cross_vsigma(kn, c, two_r, dd2, l2, l3):
    """The eight cross pairs' V σ (nn, t1t1, t2t2) in the cell frame (Love-Weber, eq. 1.11):
    8 F b ⊗ b / dc, b = (dd2/2, l2/2, l3/2); the shear terms cancel by the mirror symmetries."""
    dc = cross_distance(dd2, l2, l3)
    f, _ = cross_force(kn, c, two_r, dc)
    if f == 0.0:
        return 0.0, 0.0, 0.0
    w = 2.0 * f / dc
    return w * dd2 * dd2, w * l2 * l2, w * l3 * l3


@njit(cache=True, inline="always", error_model="numpy")
def _force_free(n1, n2, t1):
    """Whether a hexagon's contacts carry nothing (open, or reborn at contact)."""
    return n1 == 0.0 and n2 == 0.0 and t1 == 0.0


@njit(cache=True, error_model="numpy")  # a call, not inlined: ten call sites would compile ten copies
def _hexagon_solve(d1, d2, a, n1, n2, t1, dl1, dl2, sliding, xi, shift, p):
    """Eq. 1.7 of one hexagon in a given regime with the force ``shift`` added to its third row
    in forces (coef δN1 - δN2 + gt δα + kn λ + shift = 0; the rows of
    :func:`hmodel.cell.closed_form._hertz_regime`, linear contacts' with kn):
    ``(ok, δd1, δd2, δα, N1', N2', T1' without sliding, dδd2/dshift)``, the last from the
    row's slope at the solution (δd2 = δd20 + w δd1 by rows 1-2)."""
    kn = p[P_KN]
    c = p[P_HERTZ]
    tanphi = p[P_TAN]
    ca, sa, gs, a11, a13, a21, a23 = angle_rows(d1, a, p)
    g = t1 * ca - n1 * sa
    if c != 0.0:
        u1, u2, kt = hertz_overlaps(d1, d2, n1, n2, p)
    else:
        kt = p[P_KT]
    if sliding:
        coef = ca + xi * tanphi * gs
        gt = g
        flam = sliding_force(a, n1, t1, xi, p) + shift
    else:
        coef = ca
        gt = g + gs * kt * d1
        flam = shift
    q, da0, w, e0 = hertz.affine(a11, a13, a21, a23, dl1, dl2)
    if c != 0.0:
        ok, x, dd2, da, f1, f2, b1, b2 = hertz.solve(c, u1, u2, n1, n2, dl1, dl2, a11, a13, a21,
                                                    a23, coef, gt, flam)
        slope = -1.5 * c * (coef * b1 - b2 * w) + gt * q
    else:
        slope = -kn * coef + kn * w + gt * q
        x = -(kn * e0 + gt * da0 + flam) / slope
        dd2 = e0 + w * x
        da = da0 + q * x
        f1 = n1 - kn * x
        f2 = n2 - kn * dd2
        ok = slope != 0.0
    return ok, x, dd2, da, f1, f2, t1 + kt * d1 * da, -w / slope


@njit(cache=True, error_model="numpy")  # a call, not inlined: the published path stays lean
def cross_increment(values, i, dl1, dl2, dl3, p, out, flags):
    """Advance bi-hexagon ``values[i]`` (16 fields) with the contacts between its hexagons by
    (δl1, δl2, δl3) into ``out[i]`` and ``flags[i, :10]`` (the module's closure). Returns False
    when an increment failed (singular rows, Newton without a solution, non-finite result)."""
    kn = p[P_KN]
    c = p[P_HERTZ]
    two_r = 2.0 * p[P_R]
    tanphi = p[P_TAN]
    a_d1, a_d2, a_a, a_n1, a_n2, a_t1, a_l1, a_l2 = (values[i, 0], values[i, 1], values[i, 2],
                                                     values[i, 3], values[i, 4], values[i, 5],
                                                     values[i, 6], values[i, 7])
    b_d1, b_d2, b_a, b_n1, b_n2, b_t1, b_l1, b_l3 = (values[i, 8], values[i, 9], values[i, 10],
                                                     values[i, 11], values[i, 12], values[i, 13],
                                                     values[i, 14], values[i, 15])
    l2n = a_l2 + dl2
    l3n = b_l3 + dl3
    y0, _ = cross_balance(kn, c, two_r, a_d2 - b_d2, a_l2, b_l3)
    if y0 == 0.0:  # apart (or D = 0) before: the published increments, unless they meet after
        ra = cell_update(a_d1, a_d2, a_a, a_n1, a_n2, a_t1, a_l1, a_l2, dl1, dl2, p)
        rb = cell_update(b_d1, b_d2, b_a, b_n1, b_n2, b_t1, b_l1, b_l3, dl1, dl3, p)
        yfree, _ = cross_balance(kn, c, two_r, ra[2] - rb[2], l2n, l3n)
        if yfree == 0.0:  # ΔY = 0 solves the coupled rows: two 2D H-cells
            ok_a = write_update(ra, out, flags, i, 0, 0)
            return write_update(rb, out, flags, i, 8, 5) and ok_a
    scale = abs(a_n1) + abs(a_n2) + abs(b_n1) + abs(b_n2) + abs(y0)
    slide_a = False
    slide_b = False
    xi_a = 1.0
    xi_b = 1.0
    sa_ = _hexagon_solve(a_d1, a_d2, a_a, a_n1, a_n2, a_t1, dl1, dl2, False, 1.0, 0.0, p)
    sb_ = _hexagon_solve(b_d1, b_d2, b_a, b_n1, b_n2, b_t1, dl1, dl3, False, 1.0, 0.0, p)
    # the regimes of the trial without the change of the cross forces (the coupling is weak:
    # they seldom differ), checked again at the coupled solution
    if abs(sa_[6]) >= tanphi * sa_[4]:
        slide_a = True
        xi_a = 1.0 if sa_[6] >= 0.0 else -1.0
        sa_ = _hexagon_solve(a_d1, a_d2, a_a, a_n1, a_n2, a_t1, dl1, dl2, True, xi_a, 0.0, p)
    if abs(sb_[6]) >= tanphi * sb_[4]:
        slide_b = True
        xi_b = 1.0 if sb_[6] >= 0.0 else -1.0
        sb_ = _hexagon_solve(b_d1, b_d2, b_a, b_n1, b_n2, b_t1, dl1, dl3, True, xi_b, 0.0, p)
    ok = False
    for _ in range(3):  # active set: a hexagon that leaves the Coulomb cone slides from then on
        dy = 0.0
        ok = False
        if not (sa_[0] and sb_[0]):
            break
        # D' = d2 + δd2 - d2_b - δd2_b, hexagon A's row takes -ΔY, B's +ΔY: dD'/dΔY = k,
        # exact for linear contacts (D' affine in ΔY), the slope at the last point for Hertz's
        d_free = a_d2 + sa_[2] - b_d2 - sb_[2]
        k = -(sa_[7] + sb_[7])
        size = scale + abs(sa_[4]) + abs(sa_[5]) + abs(sb_[4]) + abs(sb_[5])
        for n_pass in range(CROSS_PASSES):
            if c != 0.0:
                if n_pass > 0:  # the first pass is at ΔY = 0, where sa_ and sb_ were solved
                    sa_ = _hexagon_solve(a_d1, a_d2, a_a, a_n1, a_n2, a_t1, dl1, dl2, slide_a, xi_a,
                                         -dy, p)
                    sb_ = _hexagon_solve(b_d1, b_d2, b_a, b_n1, b_n2, b_t1, dl1, dl3, slide_b, xi_b,
                                         dy, p)
                    if not (sa_[0] and sb_[0]):
                        break
                dn = a_d2 + sa_[2] - b_d2 - sb_[2]
                k = -(sa_[7] + sb_[7])
            else:
                dn = d_free + k * dy
            y, dy_dd = cross_balance(kn, c, two_r, dn, l2n, l3n)
            r = y - y0 - dy
            if abs(r) <= CROSS_RTOL * (size + abs(y)):
                ok = True
                break
            dy -= r / (dy_dd * k - 1.0)
        if not ok:
            break
        if c == 0.0:
            sa_ = _hexagon_solve(a_d1, a_d2, a_a, a_n1, a_n2, a_t1, dl1, dl2, slide_a, xi_a, -dy, p)
            sb_ = _hexagon_solve(b_d1, b_d2, b_a, b_n1, b_n2, b_t1, dl1, dl3, slide_b, xi_b, dy, p)
        trial_a = not slide_a and abs(sa_[6]) >= tanphi * sa_[4]
        trial_b = not slide_b and abs(sb_[6]) >= tanphi * sb_[4]
        if not (trial_a or trial_b):
            break
        if trial_a:
            slide_a = True
            xi_a = 1.0 if sa_[6] >= 0.0 else -1.0
        if trial_b:
            slide_b = True
            xi_b = 1.0 if sb_[6] >= 0.0 else -1.0
        sa_ = _hexagon_solve(a_d1, a_d2, a_a, a_n1, a_n2, a_t1, dl1, dl2, slide_a, xi_a, 0.0, p)
        sb_ = _hexagon_solve(b_d1, b_d2, b_a, b_n1, b_n2, b_t1, dl1, dl3, slide_b, xi_b, 0.0, p)
    if not ok and (_force_free(a_n1, a_n2, a_t1) or _force_free(b_n1, b_n2, b_t1)):
        # A hexagon with every contact open holds its grains along n by nothing: the cross pairs'
        # n-component cannot be balanced there, and its row has no stiffness to solve with (zero
        # Hertz overlaps). Its grains give way, so the pairs transmit nothing along n over the
        # increment: the two 2D increments, as where the hexagons do not touch.
        ra = cell_update(a_d1, a_d2, a_a, a_n1, a_n2, a_t1, a_l1, a_l2, dl1, dl2, p)
        rb = cell_update(b_d1, b_d2, b_a, b_n1, b_n2, b_t1, b_l1, b_l3, dl1, dl3, p)
        ok_a = write_update(ra, out, flags, i, 0, 0)
        return write_update(rb, out, flags, i, 8, 5) and ok_a
    fa = finish_update(a_d1, a_d2, a_a, a_l1, a_l2, dl1, dl2, sa_[1], sa_[2], sa_[3], sa_[4],
                       sa_[5], sa_[6], slide_a, xi_a, p)
    fb = finish_update(b_d1, b_d2, b_a, b_l1, b_l3, dl1, dl3, sb_[1], sb_[2], sb_[3], sb_[4],
                       sb_[5], sb_[6], slide_b, xi_b, p)
    ok_a = write_update(fa, out, flags, i, 0, 0)
    ok_b = write_update(fb, out, flags, i, 8, 5)
    return ok and ok_a and ok_b
