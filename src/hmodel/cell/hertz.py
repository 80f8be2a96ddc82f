"""Hertz-Mindlin contacts of the H-cell: eq. 1.7 with a stiffness per contact
(``contact="hertz-mindlin"``, docs/mechanisms.md, "Hertz–Mindlin contacts").

The normal law of two equal spheres is N = c δ^(3/2) (Hertz), of tangent stiffness
kn(N) = 3/2 c δ^(1/2); the tangential stiffness is Mindlin's no-slip one, kt = m kn(N) with
m = 2(1 - ν)/(2 - ν), taken at the force at the start of an increment as in the linear law
(δT1 = kt d1 δα). The normal force follows the law exactly: a contact at the overlap its force
implies, δ = (N/c)^(2/3), ends the increment at N' = c (δ - δd)^(3/2), so that eq. 1.7's third
row depends on the solution through the secant stiffnesses (N' - N)/(-δd). Rows 1-2 give δd2
and δα as affine functions of δd1; the third row is solved for δd1 by Newton's method (with
higher-order corrections near the solution), from the solution with the tangent stiffnesses at
the start of the increment corrected by the law's Taylor series there.

The law is extended to negative overlaps as N = c δ |δ|^(1/2), a virtual tension, as the
linear law's N - kn δd may fall below zero: a contact whose force would be negative opens, as
in the published model (docs/model.md step 3), and the third row stays smooth where a contact
starts from zero force.

Plain scalar functions, inlined into the closed form's kernel
(:mod:`hmodel.cell.closed_form`), which keeps the linear law's expressions where c = 0.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: Newton passes on δd1 at most, and the residual of the third row, relative to its terms, at
#: which a point is the solution.
NEWTON_PASSES = 60
NEWTON_RTOL = 1e-12
#: The residual's round-off: of the forces, relative to those at the start.
FORCE_EPS = 1e-14
#: Halley's steps at most of a cube root from y^(1/4) (:func:`overlap_root`): each at least
#: halves the ratio to the root, which is below 2^60 for y from 1e-200 to 1e200.
ROOT_PASSES = 100


@njit(cache=True, inline="always", error_model="numpy")
def gap_root(y, gap):
    """``(u, near)``: the cube root u of y = n/c > 0 from the square root of a loaded contact's
    gap 2r - d (its overlap to round-off) by one or two of Halley's steps, and whether the gap
    was near enough (within 10^-4 relative) for these steps to reach it (cubic convergence:
    one from a relative error of 1e-10, two from 1e-5). Without branches, so that a loop over
    cells (:mod:`hmodel.cell.hertz_batch`) runs it as vector operations."""
    u = math.sqrt(abs(gap))
    u3 = u * u * u
    miss = abs(u3 - y)
    polished = u * (u3 + 2.0 * y) / (2.0 * u3 + y)
    u = polished if miss > 3e-10 * y else u
    u3 = u * u * u
    return u * (u3 + 2.0 * y) / (2.0 * u3 + y), miss <= 1e-4 * y


@njit(cache=True, inline="always", error_model="numpy")
def overlap_root(n, c, gap):
    """δ^(1/2) of a contact whose normal force n ≥ 0 implies the overlap δ = (n/c)^(2/3), the
    cube root of n/c. A contact loaded since it touched has the overlap gap = 2r - d to
    round-off: from its square root, Halley's steps reach the cube root at a fraction of the
    library's cost (:func:`gap_root`). A contact whose gap says nothing of its force starts
    from y^(1/4) instead, and Halley's steps, which at least halve the ratio to the root while
    far from it, reach it within 2 ulp for y from 1e-200 to 1e200 (not the library's cbrt: a
    call on this branch, never taken by a loaded contact, slowed every contact's update in the
    engine benchmark, the compiler being free to evaluate a pure call ahead of its branch)."""
    y = n / c
    if y == 0.0:
        return 0.0
    root, near = gap_root(y, gap)
    if near:
        return root
    u = math.sqrt(math.sqrt(y))
    u3 = u * u * u
    for _ in range(ROOT_PASSES):
        if abs(u3 - y) <= 3e-10 * y:
            break
        u = u * (u3 + 2.0 * y) / (2.0 * u3 + y)
        u3 = u * u * u
    return u * (u3 + 2.0 * y) / (2.0 * u3 + y)


@njit(cache=True, inline="always", error_model="numpy")
def law(c, e):
    """``(N, b)``: the normal force c e |e|^(1/2) at the overlap e (negative: a virtual tension)
    and b = |e|^(1/2), whose 3/2 c b is the tangent stiffness there."""
    b = math.sqrt(abs(e))
    return c * e * b, b


@njit(cache=True, inline="always", error_model="numpy")
def extra_force(kn, c, gap):
    """Normal force of an extra contact of docs/model.md step 3 (grains 1-4, 2-6, ... that
    touch) at the overlap gap = 2r - l ≥ 0: kn gap (linear, c = 0), or Hertz's c gap^(3/2)."""
    if c != 0.0:
        return c * gap * math.sqrt(gap)
    return kn * gap


@njit(cache=True, inline="always", error_model="numpy")
def extra_slope(kn, c, two_r, l):
    """d/dl of :func:`extra_force` (kn, c, 2r - l) · l, the extra contact's V σ term: kn (2r - 2l),
    or c (2r - l)^(1/2) (2r - l - 3/2 l)."""
    if c != 0.0:
        g = two_r - l
        return c * math.sqrt(g) * (g - 1.5 * l)
    return kn * (two_r - 2.0 * l)


@njit(cache=True, inline="always", error_model="numpy")
def affine(a11, a13, a21, a23, dl1, dl2):
    """Rows 1-2 of eq. 1.7 (compatibility, [[a11, 1, a13], [a21, 0, a23]]) solved for δα and
    δd2 as affine functions of δd1: ``(q, δα0, w, δd20)`` of δα = δα0 + q δd1 and
    δd2 = δd20 + w δd1."""
    q = -a21 / a23
    da0 = dl2 / a23
    return q, da0, -a11 - a13 * q, dl1 - a13 * da0


@njit(cache=True, inline="always", error_model="numpy")
def state_at(x, c, u1, u2, da0, q, e0, w):
    """The cell at δd1 = x: ``(δd2, δα, N1', N2', b1, b2)``, rows 1-2 (:func:`affine`) and the
    contacts' law (:func:`law`) at the overlaps u1² - x, u2² - δd2."""
    da = da0 + q * x
    dd2 = e0 + w * x
    f1, b1 = law(c, u1 * u1 - x)
    f2, b2 = law(c, u2 * u2 - dd2)
    return dd2, da, f1, f2, b1, b2


@njit(cache=True, inline="always", error_model="numpy")
def _row3(x, c, u1, u2, n1, n2, da0, q, e0, w, coef, gt, flam):
    """Eq. 1.7's third row at δd1 = x in forces (the linear row times -kn), its slope and the
    sum of its terms' magnitudes: ``(r, dr/dx, size, δd2, δα, N1', N2', b1, b2)``
    (:func:`solve`)."""
    dd2, da, f1, f2, b1, b2 = state_at(x, c, u1, u2, da0, q, e0, w)
    t1 = coef * (f1 - n1)
    t2 = f2 - n2
    t3 = gt * da
    r = t1 - t2 + t3 + flam
    dr = -1.5 * c * (coef * b1 - b2 * w) + gt * q
    return r, dr, abs(t1) + abs(t2) + abs(t3) + abs(flam), dd2, da, f1, f2, b1, b2


@njit(cache=True, inline="always", error_model="numpy")
def free_solution(e0, w, coef):
    """δd1 of a force-free cell (an open or reborn one: no force, hence no overlap, and no
    tangential stiffness, so gt = 0, and no sliding force), in closed form (docs/mechanisms.md,
    "Force-free cells"): the third row is coef f(-δd1) = f(-δd2) with the odd, homogeneous law
    f(e) = c e |e|^(1/2), f(λe) = λ^(3/2) f(e), hence for coef > 0 f(-coef^(2/3) δd1) = f(-δd2),
    and f is one-to-one: δd2 = coef^(2/3) δd1, with δd2 = e0 + w δd1 from rows 1-2
    (:func:`affine`)."""
    return e0 / (np.cbrt(coef * coef) - w)


@njit(cache=True, inline="always", error_model="numpy")
def free_state(c, e0, w, da0, q, coef):
    """A force-free cell's solution of the row with ``coef`` (:func:`free_solution`) and rows
    1-2 (:func:`affine`), as :func:`solve` returns it: ``(ok, δd1, δd2, δα, N1', N2', b1, b2)``
    (the overlaps start at zero); ``ok`` False where it is not finite."""
    x = free_solution(e0, w, coef)
    dd2 = e0 + w * x
    f1, b1 = law(c, -x)
    f2, b2 = law(c, -dd2)
    return math.isfinite(x), x, dd2, da0 + q * x, f1, f2, b1, b2


@njit(cache=True, inline="always", error_model="numpy")
def free_regime(c, dl1, dl2, a11, a13, a21, a23, ca, slide):
    """Eq. 1.7 of a force-free cell in the regime its increment takes, as :func:`solve` twice
    (trial without sliding, Coulomb check, sliding) but with one cube root:
    ``(ok, δd1, δd2, δα, N1', N2', b1, b2, sliding, coef)``; ``ok`` False where the closed form
    does not apply (cos α ≤ 0, or the trial's denominator vanishes), for the caller's iteration.

    Without sliding (coef = cos α, :func:`free_solution`) T1' = 0, so the cell is on the Coulomb
    cone iff N1' ≤ 0, iff δd1 = e0/(cos^(2/3) α - w) ≥ 0: the sign of δd1 follows from
    cos² α against w³ without the root. Sliding then goes the way ξ = +1 of T1' = 0, coef =
    cos α + ``slide`` (tan φ (g2 + sin α)), with no sliding force (N1 = T1 = 0 in eq. 1.10)."""
    q, da0, w, e0 = affine(a11, a13, a21, a23, dl1, dl2)
    c2 = ca * ca
    w3 = w * w * w
    if not ca > 0.0 or c2 == w3:
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False, ca
    sliding = e0 >= 0.0 if c2 > w3 else e0 <= 0.0
    coef = ca + slide if sliding else ca
    ok, x, dd2, da, f1, f2, b1, b2 = free_state(c, e0, w, da0, q, coef)
    return ok, x, dd2, da, f1, f2, b1, b2, sliding, coef


@njit(cache=True, inline="always", error_model="numpy")
def solve(c, u1, u2, n1, n2, dl1, dl2, a11, a13, a21, a23, coef, gt, flam):
    """Eq. 1.7 of Hertz-Mindlin contacts: ``(ok, δd1, δd2, δα, N1', N2', b1, b2)``, the
    solution, the new normal forces and the square roots of the new overlaps (tangents
    3/2 c b); ``ok`` is False where Newton found none.

    The third row, grain 2's equilibrium (eq. 1.6) in forces:
    coef (N1' - N1) - (N2' - N2) + gt δα + flam = 0, with the contacts at the overlaps u1², u2²
    their forces N1, N2 imply (Nk' by :func:`law`). Sticking: coef = cos α,
    gt = T1 cos α - N1 sin α + (g2 + sin α) kt d1, flam = 0; sliding: coef = cos α + ξ tan φ
    (g2 + sin α), gt = T1 cos α - N1 sin α, flam = kn λ of eq. 1.10. A force-free cell (no
    overlap, gt = flam = 0, the open cells that are most of a sheared REV's) takes the closed
    form :func:`free_solution` instead of the iteration."""
    q, da0, w, e0 = affine(a11, a13, a21, a23, dl1, dl2)
    if u1 == 0.0 and u2 == 0.0 and gt == 0.0 and flam == 0.0 and coef > 0.0:
        free = free_state(c, e0, w, da0, q, coef)
        if free[0]:
            return free
    x = start(c, u1, u2, da0, q, e0, w, coef, gt, flam)
    floor = FORCE_EPS * (n1 + n2)
    for _ in range(NEWTON_PASSES):
        done, finite, settled, x_next, dd2, da, f1, f2, b1, b2 = newton_pass(
            x, c, u1, u2, n1, n2, da0, q, e0, w, coef, gt, flam, floor)
        if done:
            return True, x, dd2, da, f1, f2, b1, b2
        if not finite:
            break
        x = x_next
        if settled:
            dd2, da, f1, f2, b1, b2 = state_at(x, c, u1, u2, da0, q, e0, w)
            return True, x, dd2, da, f1, f2, b1, b2
    r, dr, size, dd2, da, f1, f2, b1, b2 = _row3(x, c, u1, u2, n1, n2, da0, q, e0, w, coef, gt,
                                                  flam)
    return False, x, dd2, da, f1, f2, b1, b2


@njit(cache=True, inline="always", error_model="numpy")
def start(c, u1, u2, da0, q, e0, w, coef, gt, flam):
    """δd1 where :func:`solve` starts: the row with the tangent stiffnesses at the start of
    the increment (an unloaded contact has none, and the row of two is homogeneous in them where
    both are), corrected where both contacts are loaded and each moves by less than half its
    overlap by one Newton step on the row with the law's Taylor series there,
    c u³ (1 - s)^(3/2) = c u³ (1 - 3/2 s + 3/8 s² + 1/16 s³ + O(s⁴)) at s = δd / u²: a start off
    by O(s⁴), from which one pass of :func:`newton_pass` mostly settles (from the tangent start,
    off by O(s²), it took two). Without branches (the correction is computed and not taken
    where it does not apply), so that a loop over cells runs it as vector operations."""
    k1 = 1.5 * c * u1
    k2 = 1.5 * c * u2
    k1 = k1 if k1 != 0.0 else (k2 if k2 != 0.0 else 1.0)
    k2 = k2 if k2 != 0.0 else k1
    slope = -coef * k1 + k2 * w + gt * q
    x = -(k2 * e0 + gt * da0 + flam) / slope
    dd2 = e0 + w * x
    iu = 1.0 / (u1 * u2)
    t1 = x * u2 * iu  # δd1 / u1, δd2 / u2
    t2 = dd2 * u1 * iu
    s1 = t1 * u2 * iu
    s2 = t2 * u1 * iu
    curv = c * (coef * x * t1 * (0.375 + 0.0625 * s1) - dd2 * t2 * (0.375 + 0.0625 * s2))
    dcurv = c * (coef * t1 * (0.75 + 0.1875 * s1) - w * t2 * (0.75 + 0.1875 * s2))
    near = (abs(x) < 0.5 * u1 * u1) & (abs(dd2) < 0.5 * u2 * u2)
    return x - curv / (slope + dcurv) if near else x


@njit(cache=True, inline="always", error_model="numpy")
def newton_pass(x, c, u1, u2, n1, n2, da0, q, e0, w, coef, gt, flam, floor):
    """One pass of :func:`solve` from δd1 = x: ``(done, finite, settled, x', δd2, δα, N1', N2',
    b1, b2)``; ``done`` where x solves the third row (its residual within the tolerance
    relative to its terms, the state at x returned), else the next point x' (``finite`` False
    where the Newton step is not), ``settled`` where x' is the solution.

    The step is of fourth order near the solution: the series reversion of the row's Taylor
    series at x, r + r1 t + r2 t²/2 + r3 t³/6 + r4 t⁴/24 = 0 (rk: its k-th derivative, from the
    normal laws' at each overlap e = b²: ±3/4 c / b, -3/8 c / b³, ±9/16 c / b⁵), is
    t = -h (1 + A h + (2 A² - B) h²), h = r / r1, A = r2 / (2 r1), B = r3 / (6 r1); its error
    (5 A³ - 5 A B + C) h⁴, C = r4 / (24 r1), bounded by the terms' magnitudes, leaves a residual
    below the tolerance: x' is then the solution. Where a contact is at zero overlap or the
    correction is large (|A h| > 1/2) the pass takes Newton's plain step. Without branches, so
    that a loop over cells runs it as vector operations."""
    r, dr, size, dd2, da, f1, f2, b1, b2 = _row3(x, c, u1, u2, n1, n2, da0, q, e0, w, coef, gt,
                                                  flam)
    tol = NEWTON_RTOL * size + floor
    inv_dr = 1.0 / dr
    step = r * inv_dr
    inv_b = 1.0 / (b1 * b2)
    i1 = b2 * inv_b
    i2 = b1 * inv_b
    ww = w * w
    hs = 0.375 * c * (coef * math.copysign(i1, u1 * u1 - x)
                      - ww * math.copysign(i2, u2 * u2 - dd2)) * inv_dr * step
    j1 = i1 * i1 * i1
    j2 = i2 * i2 * i2
    hb = 0.0625 * c * (coef * j1 - ww * w * j2) * inv_dr * step * step
    a_abs = 0.375 * c * (abs(coef) * i1 + ww * i2) * abs(inv_dr)
    b_abs = 0.0625 * c * (abs(coef) * j1 + abs(ww * w) * j2) * abs(inv_dr)
    c_abs = 0.0234375 * c * (abs(coef) * j1 * i1 * i1 + ww * ww * j2 * i2 * i2) * abs(inv_dr)
    h2 = step * step
    plain = (b1 == 0.0) | (b2 == 0.0) | (abs(hs) > 0.5)
    x_next = x - step if plain else x - step * (1.0 + hs + 2.0 * hs * hs - hb)
    bound = (5.0 * a_abs * (a_abs * a_abs + b_abs) + c_abs) * h2 * h2 * abs(dr)
    settled = (not plain) & (bound <= tol)
    return abs(r) <= tol, math.isfinite(step), settled, x_next, dd2, da, f1, f2, b1, b2


@njit(cache=True, inline="always", error_model="numpy")
def first_pass(c, u1, u2, n1, n2, da0, q, e0, w, coef, gt, flam):
    """:func:`solve`'s first pass for a cell with both contacts loaded (u1, u2 > 0), without
    branches: ``(ok, δd1, δd2, δα, N1', N2')``, the values :func:`solve` returns to the last bit
    where ``ok`` (the start solves the row, or one :func:`newton_pass` from it settles);
    :mod:`hmodel.cell.hertz_batch` runs it for many cells as vector operations and hands those
    without ``ok`` to :func:`solve`."""
    x = start(c, u1, u2, da0, q, e0, w, coef, gt, flam)
    done, finite, settled, x_next, dd2, da, f1, f2, b1, b2 = newton_pass(
        x, c, u1, u2, n1, n2, da0, q, e0, w, coef, gt, flam, FORCE_EPS * (n1 + n2))
    x = x if done else x_next
    dd2, da, f1, f2, b1, b2 = state_at(x, c, u1, u2, da0, q, e0, w)
    return done | (finite & settled), x, dd2, da, f1, f2


@njit(cache=True, inline="always", error_model="numpy")
def column(c, b1, b2, q, w, coef, gt, sliding, ktd1, xitan, pdd2, pda):
    """Derivatives of the solution of :func:`solve` along a length increment that moves
    (δd2, δα) at fixed δd1 by (pdd2, pda) (rows 1-2: (1, 0) along δl1, (-a13/a23, 1/a23) along
    δl2): ``(dδd1, dδd2, dδα, dN1, dN2, dT1)``, by the implicit function theorem on the third
    row at the solution, whose tangents are 3/2 c b1, 3/2 c b2. ``ktd1``: kt d1 (sticking,
    δT1 = kt d1 δα); ``xitan``: ξ tan φ (``sliding``, T1' = ξ tan φ N1')."""
    dr = -1.5 * c * (coef * b1 - b2 * w) + gt * q
    dx = -(1.5 * c * b2 * pdd2 + gt * pda) / dr
    ddd2 = pdd2 + w * dx
    dda = pda + q * dx
    dn1 = -1.5 * c * b1 * dx
    dn2 = -1.5 * c * b2 * ddd2
    dt1 = xitan * dn1 if sliding else ktd1 * dda
    return dx, ddd2, dda, dn1, dn2, dt1
