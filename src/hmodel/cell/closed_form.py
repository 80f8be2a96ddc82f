"""Closed-form incremental response of the H-cell (report eqs. 1.3-1.10, docs/model.md steps 2-3).

One increment of every cell of a batch is a compiled loop (Numba) over cells; each cell solves
the 3x3 system of eq. 1.7 by Cramer's rule, first without sliding, then, if the trial
tangential force leaves the Coulomb cone, again with the sliding closure (eqs. 1.8-1.10).
Contacts that open (d > 2r) make the cell force-free (Fig. 1.5). With Hertz-Mindlin contacts
(``contact="hertz-mindlin"``, :mod:`hmodel.cell.hertz`) each contact has its own stiffness and
the third row, solved by Newton's method, follows the normal law exactly; the linear law's
expressions are kept as they are wherever the Hertz constant is zero.

The kernel takes the packed state (``values[..., 8]``, see :mod:`hmodel.cell.state`) and returns
new arrays; it never writes its inputs.
"""

from __future__ import annotations

import math

import numpy as np
from numba import literally, njit

from ..errors import InputError, SolverError
from ..params import Params
from . import hertz
from .base import STATE_H_CELL, CellKernel, CellSolver
from .renewal import RENEW_CELL, RENEW_CODES, reborn_cell
from .state import FIELDS, FLAGS, CellFlags, CellState, initial_cells

# Positions in the packed parameter vector handed to the kernel. P_HERTZ: 0 for linear
# contacts, else the Hertz constant c of N = c δ^(3/2); P_MINDLIN: kt/kn of Mindlin's no-slip
# tangential stiffness; P_RENEW: 1 when an opened cell is reborn; P_CROSS: 1 when a
# bi-hexagon's two hexagons touch (hmodel.cell.cross; no 2D kernel reads it) (docs/mechanisms.md).
(P_KN, P_KT, P_TAN, P_G2, P_R, P_CONSISTENT, P_EQ_RHS, P_HERTZ, P_MINDLIN,
 P_RENEW, P_CROSS) = range(11)
#: Length of the closed form's packed parameters (a learned law's constants follow).
N_CELL_PARAMS = 11
#: Which cell a compiled loop over cells updates, a constant of the loop (a literal argument:
#: each value compiles a loop of its own, so that the published cell's loop holds none of the
#: mechanisms' code, whose mere presence slows it): the published cell (linear contacts, every
#: mechanism off) or the cell the packed parameters say, cell by cell (:func:`cell_mechanisms`).
#: Two loops, not one per set of mechanisms: every loop is compiled, and a third for
#: Hertz-Mindlin contacts alone ran no faster (benchmarks/engine/engine.json).
MECH_NONE, MECH_ANY = 0, 1


def hertz_constants(params: Params) -> tuple[float, float]:
    """(c, kt/kn) of Hertz-Mindlin contacts between two spheres of radius r (docs/mechanisms.md):
    N = c δ^(3/2) with c = 4/3 E* sqrt(R*), E* = E / (2 (1 - ν²)), E = 2 G (1 + ν), R* = r/2;
    Mindlin's tangential stiffness over Hertz's normal tangent stiffness is 2 (1 - ν)/(2 - ν)."""
    nu = params.poisson
    e_star = 2.0 * params.shear_modulus * (1.0 + nu) / (2.0 * (1.0 - nu * nu))
    return 4.0 / 3.0 * e_star * math.sqrt(params.radius / 2.0), 2.0 * (1.0 - nu) / (2.0 - nu)


def kernel_params(params: Params) -> np.ndarray:
    """Pack the parameters the cell kernel needs into a float vector."""
    c, ratio = hertz_constants(params) if params.contact == "hertz-mindlin" else (0.0, 0.0)
    return np.array([
        params.kn, params.kt, params.tan_phi, float(params.g2), params.radius,
        1.0 if params.volume == "hexagon-consistent" else 0.0,
        1.0 if params.sliding_rhs == "equilibrium" else 0.0,
        c, ratio, RENEW_CODES[params.renewal],
        1.0 if params.cross_contacts == "frictionless" else 0.0,
    ])


@njit(cache=True, inline="always", error_model="numpy")
def cell_mechanisms(p):
    """The :data:`MECH_NONE` or :data:`MECH_ANY` of packed parameters ``p``."""
    if p[P_HERTZ] == 0.0 and p[P_RENEW] == 0.0 and p[P_CROSS] == 0.0:
        return MECH_NONE
    return MECH_ANY


@njit(cache=True, inline="always", error_model="numpy")
def _solve3(a11, a12, a13, a21, a22, a23, a31, a32, a33, b1, b2, b3):
    """Cramer's rule for a 3x3 system; returns (x1, x2, x3, det)."""
    c11, c12, c13, det = _cofactors(a11, a12, a13, a21, a22, a23, a31, a32, a33)
    return _solve3_with(a11, a12, a13, a21, a22, a23, a31, a32, a33, c11, c12, c13, det, b1, b2,
                        b3)


@njit(cache=True, inline="always", error_model="numpy")
def _cofactors(a11, a12, a13, a21, a22, a23, a31, a32, a33):
    """The part of :func:`_solve3` that depends on the matrix only: the cofactors of the first
    row and the determinant, ``(c11, c12, c13, det)``."""
    c11 = a22 * a33 - a23 * a32
    c12 = a23 * a31 - a21 * a33
    c13 = a21 * a32 - a22 * a31
    det = a11 * c11 + a12 * c12 + a13 * c13
    return c11, c12, c13, det


@njit(cache=True, inline="always", error_model="numpy")
def _solve3_with(a11, a12, a13, a21, a22, a23, a31, a32, a33, c11, c12, c13, det, b1, b2, b3):
    """:func:`_solve3` given the matrix's :func:`_cofactors`: (x1, x2, x3, det)."""
    x1 = (b1 * c11 + a12 * (a23 * b3 - b2 * a33) + a13 * (b2 * a32 - a22 * b3)) / det
    x2 = (a11 * (b2 * a33 - a23 * b3) + b1 * c12 + a13 * (a21 * b3 - b2 * a31)) / det
    x3 = (a11 * (a22 * b3 - b2 * a32) + a12 * (b2 * a31 - a21 * b3) + b1 * c13) / det
    return x1, x2, x3, det


@njit(cache=True, inline="always", error_model="numpy")
def _compatibility(d1, ca, sa, p):
    """Rows 1-2 of eq. 1.7, geometric compatibility (eq. 1.2 differentiated; eq. 1.21: the
    virtual rectangle): ``(a11, a13, a21, a23)`` of [[a11, 1, a13], [a21, 0, a23]]."""
    if p[P_CONSISTENT] != 0.0:
        a11 = ca
        a13 = -d1 * sa
    else:
        a11 = 2.0 * ca
        a13 = -2.0 * d1 * sa
    return a11, a13, 2.0 * sa, 2.0 * d1 * ca


@njit(cache=True, inline="always", error_model="numpy")
def angle_rows(d1, a, p):
    """What every form of eq. 1.7 at (d1, α) starts from: ``(cos α, sin α, g2 + sin α, a11,
    a13, a21, a23)``, the last four the compatibility rows (:func:`_compatibility`)."""
    ca = math.cos(a)
    sa = math.sin(a)
    a11, a13, a21, a23 = _compatibility(d1, ca, sa, p)
    return ca, sa, p[P_G2] + sa, a11, a13, a21, a23


@njit(cache=True, inline="always", error_model="numpy")
def hertz_overlaps(d1, d2, n1, n2, p):
    """``(u1, u2, kt)`` of Hertz-Mindlin contacts: the square roots of the two contacts'
    overlaps from their forces (:func:`hmodel.cell.hertz.overlap_root`) and Mindlin's tangential
    stiffness kt = m kn(N1) = m 1.5 c u1."""
    c = p[P_HERTZ]
    two_r = 2.0 * p[P_R]
    u1 = hertz.overlap_root(n1, c, two_r - d1)
    return u1, hertz.overlap_root(n2, c, two_r - d2), p[P_MINDLIN] * 1.5 * c * u1


#: Width of a cell's :func:`regime_state`, the part of eq. 1.7 its committed state fixes.
REGIME_WIDTH = 12
#: A hexagon's fields and flags in a cell's packed state: one H-cell, or each of a
#: bi-hexagon's two hexagons (:mod:`hmodel.cell.bihex`).
N_FIELDS, N_FLAGS = len(FIELDS), len(FLAGS)


@njit(cache=True, inline="always", error_model="numpy")
def regime_state(d1, a, n1, t1, p):
    """The part of :func:`_regime` that depends on the committed state (d1, α, N1, T1) only:
    ``(cos α, g2 + sin α, a11, a13, a21, a23, a33, a33 sliding, c11, c12, c13, det)``, the
    matrix of eq. 1.7 without sliding, its :func:`_cofactors`, and the third row's a33 while
    sliding. A compiled REV trial reads it from an array filled once per committed state
    (:func:`hmodel.rev.kernels.prepare`): Newton makes several trials from one state, and the
    same expressions give the same values to the last bit wherever they are computed."""
    kn = p[P_KN]
    kt = p[P_KT]
    # angle_rows written out: through it the published cell's REV trial ran about 10 % slower
    # (engine benchmark, four alternations against the code before it)
    ca = math.cos(a)
    sa = math.sin(a)
    gs = p[P_G2] + sa
    a11, a13, a21, a23 = _compatibility(d1, ca, sa, p)
    # Row 3, no sliding (eqs. 1.8-1.9): equilibrium of grain 2 with dT1 = kt d1 dalpha.
    g = n1 * sa - t1 * ca
    a33 = (g - kt * d1 * gs) / kn
    c11, c12, c13, det = _cofactors(a11, 1.0, a13, a21, 0.0, a23, ca, -1.0, a33)
    return ca, gs, a11, a13, a21, a23, a33, g / kn, c11, c12, c13, det


@njit(cache=True, inline="always", error_model="numpy")
def regime_increment(d1, n1, t1, dl1, dl2, p, st):
    """The regime the increment (dl1, dl2) takes from a cell whose :func:`regime_state` is
    ``st``: ``(a11, a13, a21, a23, a31, a33, rhs3, sliding, xi, c11, c12, c13, det)``, the
    system of eq. 1.7 (:func:`_regime`) and its matrix's :func:`_cofactors`."""
    ca, gs, a11, a13, a21, a23, a33, a33s, c11, c12, c13, det = st
    kn = p[P_KN]
    kt = p[P_KT]
    tanphi = p[P_TAN]
    dd1, dd2, da, det = _solve3_with(a11, 1.0, a13, a21, 0.0, a23, ca, -1.0, a33, c11, c12, c13,
                                     det, dl1, dl2, 0.0)
    n1_new = n1 - kn * dd1
    t1_new = t1 + kt * d1 * da
    sliding = abs(t1_new) >= tanphi * n1_new
    xi = 1.0 if t1_new >= 0.0 else -1.0
    if sliding:
        a31 = ca + xi * tanphi * gs
        s11, s12, s13, sdet = _cofactors(a11, 1.0, a13, a21, 0.0, a23, a31, -1.0, a33s)
        return (a11, a13, a21, a23, a31, a33s, _sliding_force(gs, n1, t1, xi, p) / kn, sliding,
                xi, s11, s12, s13, sdet)
    return a11, a13, a21, a23, ca, a33, 0.0, sliding, xi, c11, c12, c13, det


@njit(cache=True, inline="always", error_model="numpy")
def _regime(d1, a, n1, t1, dl1, dl2, p):
    """The system of eq. 1.7 in the regime the increment (dl1, dl2) takes: ``(a11, a13, a21,
    a23, a31, a33, rhs3, sliding, xi)``, the matrix [[a11, 1, a13], [a21, 0, a23], [a31, -1,
    a33]] and the third right-hand side (the first two are dl1, dl2).

    Within a regime the solution is affine in (dl1, dl2): its matrix and rhs3 depend on the
    committed state only (:func:`regime_state`), which is what makes :func:`cell_jacobian`
    exact."""
    r = regime_increment(d1, n1, t1, dl1, dl2, p, regime_state(d1, a, n1, t1, p))
    return r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8]


# a call, not inlined: inlined, it is compiled once more into every loop over cells, which
# multiplies the kernels' compile time for a Hertz cell barely cheaper
# (docs/notes/2026-12-07-hertz-solve-speed.md)
@njit(cache=True, error_model="numpy")
def _hertz_regime(d1, d2, a, n1, n2, t1, dl1, dl2, p):
    """Eq. 1.7 of Hertz-Mindlin contacts (docs/mechanisms.md) in the regime the increment
    (dl1, dl2) takes, as :func:`_regime` (trial without sliding, Coulomb check, sliding):
    ``(ok, δd1, δd2, δα, N1', N2', T1' without sliding, sliding, ξ, b1, b2, coef, gt, kt)``,
    the solution, its forces and what :func:`hmodel.cell.hertz.column` differentiates it
    with.

    The third row with a stiffness per contact, in forces: cos α δN1 - δN2 + (T1 cos α -
    N1 sin α) δα + (g2 + sin α) δT1 = 0 (eq. 1.6; the linear row times -kn), δNk of the exact
    law (:func:`hmodel.cell.hertz.solve`) and Mindlin's δT1 = kt d1 δα, kt = m kn(N1) at the
    start; sliding, T1 follows the Coulomb cone and λ of eq. 1.10 enters as the force kn λ
    (:func:`sliding_force`)."""
    c = p[P_HERTZ]
    tanphi = p[P_TAN]
    ca, sa, gs, a11, a13, a21, a23 = angle_rows(d1, a, p)
    u1, u2, kt = hertz_overlaps(d1, d2, n1, n2, p)
    if u1 == 0.0 and u2 == 0.0 and t1 == 0.0:  # force-free (open or reborn): no Newton needed
        ok, dd1, dd2, da, f1, f2, b1, b2, sliding, coef = hertz.free_regime(
            c, dl1, dl2, a11, a13, a21, a23, ca, tanphi * gs)
        if ok:
            return ok, dd1, dd2, da, f1, f2, 0.0, sliding, 1.0, b1, b2, coef, 0.0, kt
    g = t1 * ca - n1 * sa
    coef = ca
    gt = g + gs * kt * d1
    ok, dd1, dd2, da, f1, f2, b1, b2 = hertz.solve(c, u1, u2, n1, n2, dl1, dl2, a11, a13, a21,
                                                  a23, coef, gt, 0.0)
    t1_new = t1 + kt * d1 * da
    sliding = abs(t1_new) >= tanphi * f1
    xi = 1.0 if t1_new >= 0.0 else -1.0
    if sliding:
        coef = ca + xi * tanphi * gs
        gt = g
        ok, dd1, dd2, da, f1, f2, b1, b2 = hertz.solve(c, u1, u2, n1, n2, dl1, dl2, a11, a13, a21,
                                                      a23, coef, gt, sliding_force(a, n1, t1, xi, p))
    return ok, dd1, dd2, da, f1, f2, t1 + kt * d1 * da, sliding, xi, b1, b2, coef, gt, kt


@njit(cache=True, inline="always", error_model="numpy")
def cell_update(d1, d2, a, n1, n2, t1, l1, l2, dl1, dl2, p):
    """:func:`cell_update_mech` of the cell the packed parameters ``p`` say (:data:`MECH_ANY`)."""
    return cell_update_mech(d1, d2, a, n1, n2, t1, l1, l2, dl1, dl2, p, MECH_ANY)


@njit(cache=True, inline="always", error_model="numpy")
def cell_update_mech(d1, d2, a, n1, n2, t1, l1, l2, dl1, dl2, p, mech):
    """One cell's increment by (dl1, dl2) on scalars: the state's eight fields (d1, d2, α, N1,
    N2, T1, l1, l2) in, ``(ok, *eight new fields, *five flags)`` out (:func:`finish_update`).

    The kernel of every closed-form caller (:func:`cell_increment` writes it into arrays):
    scalars in and out, so that a loop over cells makes no array views, each of which costs an
    atomic reference count (the bi-hexagon's REV trial makes two such updates per cell).
    ``ok`` is False when the system of eq. 1.7 is singular or the result is not finite (or,
    with Hertz-Mindlin contacts, :func:`hmodel.cell.hertz.solve` found no solution). ``mech``
    (:data:`MECH_NONE`, ...): the cell the caller's loop updates, a constant there.
    """
    if mech == MECH_ANY and p[P_HERTZ] != 0.0:
        return _hertz_update(d1, d2, a, n1, n2, t1, l1, l2, dl1, dl2, p, mech)
    return cell_update_linear(d1, d2, a, n1, n2, t1, l1, l2, dl1, dl2, p, mech,
                              regime_state(d1, a, n1, t1, p))


@njit(cache=True, inline="always", error_model="numpy")
def _hertz_update(d1, d2, a, n1, n2, t1, l1, l2, dl1, dl2, p, mech):
    """:func:`cell_update_mech` of Hertz-Mindlin contacts."""
    h = _hertz_regime(d1, d2, a, n1, n2, t1, dl1, dl2, p)
    r = finish_update_mech(d1, d2, a, l1, l2, dl1, dl2, h[1], h[2], h[3], h[4], h[5], h[6], h[7],
                           h[8], p, mech)
    return ((h[0] and r[0]), r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8], r[9], r[10], r[11],
            r[12], r[13])


@njit(cache=True, inline="always", error_model="numpy")
def prepared(p):
    """Whether a cell of packed parameters ``p`` has a state-only part to prepare
    (:func:`prepare_cell`): linear contacts. With Hertz-Mindlin contacts the same (their
    overlaps' roots and rows, read from an array) left the drained biaxial test as slow as it
    was; their trials compute it as before."""
    return p[P_HERTZ] == 0.0


@njit(cache=True, inline="always", error_model="numpy")
def prepare_cell(values, i, p, pre):
    """``pre[i]``: the :func:`regime_state` of each hexagon of cell ``values[i]``'s committed
    state, for every increment from it (:func:`cell_increment_prepared`; linear contacts,
    :func:`prepared`). ``pre``'s width says how many hexagons, :data:`REGIME_WIDTH` each: an
    H-cell is one (its fields 0-7), a bi-hexagon two (fields 0-7 and 8-15,
    :mod:`hmodel.cell.bihex`), so that one preparation serves both REVs."""
    for h in range(pre.shape[1] // REGIME_WIDTH):
        k = N_FIELDS * h
        st = regime_state(values[i, k], values[i, k + 2], values[i, k + 3], values[i, k + 5], p)
        for j in range(REGIME_WIDTH):
            pre[i, REGIME_WIDTH * h + j] = st[j]


@njit(cache=True, inline="always", error_model="numpy")
def cell_increment_prepared(values, i, dl1, dl2, p, out, flags, mech, pre, h):
    """:func:`cell_increment_mech` of hexagon h of cell i of ``values`` (h = 0: an H-cell, or a
    bi-hexagon's hexagon A; 1: its hexagon B; fields from ``8 h``, flags from ``5 h``), the same
    result to the last bit: linear contacts from the hexagon's :func:`prepare_cell` part of
    ``pre[i]``, Hertz-Mindlin contacts as :func:`cell_update_mech` does. One closed form for
    every loop over cells: Numba compiles both branches of a test on a literal ``mech``, and a
    loop holding this and :func:`cell_increment_mech` took longer to compile."""
    if mech == MECH_ANY and p[P_HERTZ] != 0.0:
        return cell_increment_hertz(values, i, dl1, dl2, p, out, flags, mech, h)
    k = N_FIELDS * h
    c = REGIME_WIDTH * h
    r = cell_update_linear(values[i, k], values[i, k + 1], values[i, k + 2], values[i, k + 3],
                           values[i, k + 4], values[i, k + 5], values[i, k + 6], values[i, k + 7],
                           dl1, dl2, p, mech,
                           (pre[i, c], pre[i, c + 1], pre[i, c + 2], pre[i, c + 3], pre[i, c + 4],
                            pre[i, c + 5], pre[i, c + 6], pre[i, c + 7], pre[i, c + 8],
                            pre[i, c + 9], pre[i, c + 10], pre[i, c + 11]))
    return write_update(r, out, flags, i, k, N_FLAGS * h)


@njit(cache=True, inline="always", error_model="numpy")
def cell_increment_hertz(values, i, dl1, dl2, p, out, flags, mech, h):
    """:func:`cell_increment_prepared` of Hertz-Mindlin contacts, which prepare nothing
    (:func:`prepared`): hexagon h of cell i by :func:`cell_update_mech`'s own update."""
    k = N_FIELDS * h
    r = _hertz_update(values[i, k], values[i, k + 1], values[i, k + 2], values[i, k + 3],
                      values[i, k + 4], values[i, k + 5], values[i, k + 6], values[i, k + 7], dl1,
                      dl2, p, mech)
    return write_update(r, out, flags, i, k, N_FLAGS * h)


@njit(cache=True, inline="always", error_model="numpy")
def cell_update_linear(d1, d2, a, n1, n2, t1, l1, l2, dl1, dl2, p, mech, st):
    """:func:`cell_update_mech` of linear contacts, from the cell's :func:`regime_state` ``st``."""
    (a11, a13, a21, a23, a31, a33, rhs3, sliding, xi, c11, c12, c13,
     det) = regime_increment(d1, n1, t1, dl1, dl2, p, st)
    dd1, dd2, da, det = _solve3_with(a11, 1.0, a13, a21, 0.0, a23, a31, -1.0, a33, c11, c12, c13,
                                     det, dl1, dl2, rhs3)
    n1_new, n2_new, t1_new = linear_forces(d1, n1, n2, t1, dd1, dd2, da, p)
    r = finish_update_mech(d1, d2, a, l1, l2, dl1, dl2, dd1, dd2, da, n1_new, n2_new, t1_new,
                           sliding, xi, p, mech)
    return ((det != 0.0 and r[0]), r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8], r[9], r[10],
            r[11], r[12], r[13])


@njit(cache=True, inline="always", error_model="numpy")
def cell_jacobian(d1, d2, a, n1, n2, t1, l1, l2, dl1, dl2, p):
    """Derivatives of a cell's (V σnn, V σtt) after the increment (dl1, dl2) (eq. 1.12 of the
    state :func:`cell_update` gives) with respect to dl1 and dl2, in the regime the increment
    takes: ``(ok, dvnn/ddl1, dvnn/ddl2, dvtt/ddl1, dvtt/ddl2)``.

    Derived by hand (docs/fem.md, "The material tangent"): in a regime, (δd1, δd2, δα) =
    A⁻¹ (dl1, dl2, rhs3) (:func:`_regime`), so its columns for dl1 and dl2 are A⁻¹ e1 and
    A⁻¹ e2; the new forces follow eqs. 1.8-1.9 (on the Coulomb cone when sliding), an open cell
    carries none, and the extra contacts of docs/model.md step 3 depend on l1, l2. ``ok`` is
    False where :func:`cell_update` would fail. With Hertz-Mindlin contacts
    (:func:`_hertz_jacobian`) the solution is not affine in (dl1, dl2): its derivatives follow
    from the implicit function theorem on eq. 1.7's third row at the solution."""
    if p[P_HERTZ] != 0.0:
        return _hertz_jacobian(d1, d2, a, n1, n2, t1, l1, l2, dl1, dl2, p)
    a11, a13, a21, a23, a31, a33, rhs3, sliding, xi = _regime(d1, a, n1, t1, dl1, dl2, p)
    dd1, dd2, da, det = _solve3(a11, 1.0, a13, a21, 0.0, a23, a31, -1.0, a33, dl1, dl2, rhs3)
    n1_new, n2_new, t1_new = linear_forces(d1, n1, n2, t1, dd1, dd2, da, p)
    r = finish_update(d1, d2, a, l1, l2, dl1, dl2, dd1, dd2, da, n1_new, n2_new, t1_new, sliding,
                      xi, p)
    carries = not (r[10] or r[11])  # an open cell's forces are zero whatever the increment
    nn1, tt1 = _jacobian_column(a11, a13, a21, a23, a31, a33, 1.0, 0.0, sliding, xi, carries,
                                d1, r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8], p)
    nn2, tt2 = _jacobian_column(a11, a13, a21, a23, a31, a33, 0.0, 1.0, sliding, xi, carries,
                                d1, r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8], p)
    return det != 0.0 and r[0], nn1, nn2, tt1, tt2


@njit(cache=True, inline="always", error_model="numpy")
def _jacobian_column(a11, a13, a21, a23, a31, a33, e1, e2, sliding, xi, carries, d1, d1n, d2n,
                     an, n1n, n2n, t1n, l1n, l2n, p):
    """d(V σnn, V σtt) along the increment direction (dl1, dl2) = (e1, e2) of
    :func:`cell_jacobian`, at the new state (d1n, ..., l2n) from d1."""
    kn = p[P_KN]
    x1, x2, xa, _ = _solve3(a11, 1.0, a13, a21, 0.0, a23, a31, -1.0, a33, e1, e2, 0.0)
    dn1 = -kn * x1
    dt1 = xi * p[P_TAN] * dn1 if sliding else p[P_KT] * d1 * xa
    return _vsigma_slope(x1, x2, xa, dn1, -kn * x2, dt1, e1, e2, carries, d1n, d2n, an, n1n,
                         n2n, t1n, l1n, l2n, p)


@njit(cache=True, inline="always", error_model="numpy")
def _vsigma_slope(x1, x2, xa, dn1, dn2, dt1, e1, e2, carries, d1n, d2n, an, n1n, n2n, t1n, l1n,
                  l2n, p):
    """d(V σnn, V σtt) (eq. 1.12 and the extra contacts) of a cell at the new state (d1n, ...,
    l2n) whose (δd1, δd2, δα) and forces move by (x1, x2, xa) and (dn1, dn2, dt1) along the
    increment direction (e1, e2)."""
    two_r = 2.0 * p[P_R]
    c = math.cos(an)
    s = math.sin(an)
    dc = -s * xa
    ds = c * xa
    jnn = 0.0
    jtt = 0.0
    if carries:
        # eq. 1.12: 4 N1 d1 c² + 4 T1 d1 c s + 2 N2 d2 and 4 N1 d1 s² - 4 T1 d1 c s
        shear = 4.0 * (dt1 * d1n * c * s + t1n * x1 * c * s + t1n * d1n * (dc * s + c * ds))
        jnn = (4.0 * (dn1 * d1n * c * c + n1n * x1 * c * c + 2.0 * n1n * d1n * c * dc) + shear
               + 2.0 * (dn2 * d2n + n2n * x2))
        jtt = 4.0 * (dn1 * d1n * s * s + n1n * x1 * s * s + 2.0 * n1n * d1n * s * ds) - shear
    if l1n <= two_r:  # grains 1-4 touch: F(2r - l1) l1 on V σnn
        # l1' = l1 - d1 cos(α) + dl1 + d1' cos(α') (eq. 1.21), else l1 + dl1
        dl1n = e1 + x1 * c + d1n * dc if p[P_CONSISTENT] != 0.0 else e1
        jnn += hertz.extra_slope(p[P_KN], p[P_HERTZ], two_r, l1n) * dl1n
    if l2n <= two_r:  # grains 2-6 and 3-5: 2 F(2r - l2) l2 on V σtt
        jtt += 2.0 * hertz.extra_slope(p[P_KN], p[P_HERTZ], two_r, l2n) * e2
    return jnn, jtt


@njit(cache=True, error_model="numpy")  # a call, not inlined: keeps the linear path lean
def _hertz_jacobian(d1, d2, a, n1, n2, t1, l1, l2, dl1, dl2, p):
    """:func:`cell_jacobian` of Hertz-Mindlin contacts: the columns of the solution's
    derivatives along dl1 and dl2 by :func:`hmodel.cell.hertz.column` (the third row of eq. 1.7
    differentiated at the solution, with the tangents at its end), then eq. 1.12
    differentiated (:func:`_vsigma_slope`)."""
    ok, dd1, dd2, da, f1, f2, t1s, sliding, xi, b1, b2, coef, gt, kt = _hertz_regime(
        d1, d2, a, n1, n2, t1, dl1, dl2, p)
    r = finish_update(d1, d2, a, l1, l2, dl1, dl2, dd1, dd2, da, f1, f2, t1s, sliding, xi, p)
    carries = not (r[10] or r[11])
    c = p[P_HERTZ]
    a11, a13, a21, a23 = _compatibility(d1, math.cos(a), math.sin(a), p)
    q, _, w, _ = hertz.affine(a11, a13, a21, a23, 0.0, 0.0)
    ktd1 = kt * d1
    xitan = xi * p[P_TAN]
    x1, x2, xa, dn1, dn2, dt1 = hertz.column(c, b1, b2, q, w, coef, gt, sliding, ktd1, xitan, 1.0,
                                             0.0)
    nn1, tt1 = _vsigma_slope(x1, x2, xa, dn1, dn2, dt1, 1.0, 0.0, carries, r[1], r[2], r[3], r[4],
                             r[5], r[6], r[7], r[8], p)
    x1, x2, xa, dn1, dn2, dt1 = hertz.column(c, b1, b2, q, w, coef, gt, sliding, ktd1, xitan,
                                             -a13 / a23, 1.0 / a23)
    nn2, tt2 = _vsigma_slope(x1, x2, xa, dn1, dn2, dt1, 0.0, 1.0, carries, r[1], r[2], r[3], r[4],
                             r[5], r[6], r[7], r[8], p)
    return ok and r[0], nn1, nn2, tt1, tt2


@njit(cache=True, inline="always", error_model="numpy")
def write_update(r, out, flags, i, k, f):
    """Write a :func:`cell_update` result ``r`` into ``out[i, k:k + 8]`` and
    ``flags[i, f:f + 5]`` (k, f: where the cell's fields and flags start: 0 for an H-cell, 8
    and 5 for a bi-hexagon's hexagon B); returns its ``ok``."""
    out[i, k] = r[1]
    out[i, k + 1] = r[2]
    out[i, k + 2] = r[3]
    out[i, k + 3] = r[4]
    out[i, k + 4] = r[5]
    out[i, k + 5] = r[6]
    out[i, k + 6] = r[7]
    out[i, k + 7] = r[8]
    flags[i, f] = r[9]
    flags[i, f + 1] = r[10]
    flags[i, f + 2] = r[11]
    flags[i, f + 3] = r[12]
    flags[i, f + 4] = r[13]
    return r[0]


@njit(cache=True, inline="always", error_model="numpy")
def cell_increment(values, i, dl1, dl2, p, out, flags, k, f):
    """Advance cell i (its fields ``values[i, k:k + 8]``) by (dl1, dl2); write its new state
    into ``out[i, k:k + 8]`` and ``flags[i, f:f + 5]`` (:func:`cell_update`; k = f = 0 for an
    H-cell's states (n, 8)).

    Returns False when the system of eq. 1.7 is singular or the result is not finite.
    """
    return cell_increment_mech(values, i, dl1, dl2, p, out, flags, k, f, MECH_ANY)


@njit(cache=True, inline="always", error_model="numpy")
def cell_increment_mech(values, i, dl1, dl2, p, out, flags, k, f, mech):
    """:func:`cell_increment` by :func:`cell_update_mech` of ``mech``."""
    r = cell_update_mech(values[i, k], values[i, k + 1], values[i, k + 2], values[i, k + 3],
                         values[i, k + 4], values[i, k + 5], values[i, k + 6], values[i, k + 7],
                         dl1, dl2, p, mech)
    return write_update(r, out, flags, i, k, f)


@njit(cache=True, inline="always", error_model="numpy")
def sliding_lambda(a, n1, t1, xi, p):
    """Right-hand side λ of eq. 1.7's third row while sliding in the direction ξ (eq. 1.10),
    of a cell at (α, N1, T1)."""
    return sliding_force(a, n1, t1, xi, p) / p[P_KN]


@njit(cache=True, inline="always", error_model="numpy")
def sliding_force(a, n1, t1, xi, p):
    """kn λ of :func:`sliding_lambda`: the third row's right-hand side in forces, as the
    Hertz-Mindlin row takes it (its stiffness is no constant)."""
    return _sliding_force(p[P_G2] + math.sin(a), n1, t1, xi, p)


@njit(cache=True, inline="always", error_model="numpy")
def _sliding_force(gs, n1, t1, xi, p):
    """:func:`sliding_force` given gs = g2 + sin α."""
    if p[P_EQ_RHS] != 0.0:
        return gs * (xi * p[P_TAN] * n1 - t1)
    return xi * gs * (p[P_TAN] * n1 - t1)  # eq. 1.10 as corrected in docs/model.md


@njit(cache=True, inline="always", error_model="numpy")
def linear_forces(d1, n1, n2, t1, dd1, dd2, da, p):
    """New forces of linear contacts (eqs. 1.8-1.9), (N1, N2, T1 without sliding):
    δN = −kn δd, δT1 = kt d1 δα."""
    kn = p[P_KN]
    return n1 - kn * dd1, n2 - kn * dd2, t1 + p[P_KT] * d1 * da


@njit(cache=True, inline="always", error_model="numpy")
def finish_update(d1, d2, a, l1, l2, dl1, dl2, dd1, dd2, da, n1_new, n2_new, t1_new, sliding, xi,
                  p):
    """:func:`finish_update_mech` of the cell the packed parameters ``p`` say."""
    return finish_update_mech(d1, d2, a, l1, l2, dl1, dl2, dd1, dd2, da, n1_new, n2_new, t1_new,
                              sliding, xi, p, MECH_ANY)


@njit(cache=True, inline="always", error_model="numpy")
def finish_update_mech(d1, d2, a, l1, l2, dl1, dl2, dd1, dd2, da, n1_new, n2_new, t1_new,
                       sliding, xi, p, mech):
    """New state of a cell (its eight fields, scalars) from the solution (δd1, δd2, δα) of eq.
    1.7 in its regime and the contact law's new forces (:func:`linear_forces`, or those of
    Hertz-Mindlin contacts): ``(ok, d1, d2, α, N1, N2, T1, l1, l2, sliding, open1, open2,
    touch14, touch26)``.

    T1 on the Coulomb cone when sliding, lengths, openings and extra contacts (docs/model.md
    step 3); ``ok`` is False when the result is not finite.
    """
    two_r = 2.0 * p[P_R]
    if sliding:  # on the cone (eq. 1.3)
        t1_new = xi * p[P_TAN] * n1_new
    d1_new = d1 + dd1
    d2_new = d2 + dd2
    a_new = a + da
    if p[P_CONSISTENT] != 0.0:  # dl1 acted on l1* = l1 - d1 cos(alpha) (eq. 1.21)
        l1_new = l1 - d1 * math.cos(a) + dl1 + d1_new * math.cos(a_new)
    else:
        l1_new = l1 + dl1
    l2_new = l2 + dl2
    # A contact is open when its grains separate (d > 2r, docs/model.md step 3) or when it would
    # carry tension: after a cell was emptied by the *other* contact opening, the incremental
    # force no longer equals kn (2r - d), and a cohesionless contact cannot pull.
    open1 = d1_new > two_r or n1_new < 0.0
    open2 = d2_new > two_r or n2_new < 0.0
    if open1 or open2:  # lost contact: the cell carries no force (Fig. 1.5)
        n1_new = 0.0
        n2_new = 0.0
        t1_new = 0.0
        sliding = False
        # renewal >>> (inside the opening branch: a cell that carries pays nothing for it)
        if mech != MECH_NONE and p[P_RENEW] == RENEW_CELL:  # docs/mechanisms.md, "Renewal"
            reborn, rd1, rd2, ra, rl1, rl2 = reborn_cell(d1_new, d2_new, a_new, two_r)
            if reborn:
                d1_new, d2_new, a_new, l1_new, l2_new = rd1, rd2, ra, rl1, rl2
        # renewal <<<
    ok = math.isfinite(d1_new) and math.isfinite(d2_new) and math.isfinite(a_new)
    ok = ok and math.isfinite(n1_new) and math.isfinite(n2_new) and math.isfinite(t1_new)
    return (ok, d1_new, d2_new, a_new, n1_new, n2_new, t1_new, l1_new, l2_new, sliding, open1,
            open2, l1_new <= two_r, l2_new <= two_r)  # grains 1-4, 2-6 and 3-5 touch (Fig. 1.6)


@njit(cache=True, error_model="numpy")
def finish_increment(values, i, dl1, dl2, dd1, dd2, da, sliding, xi, p, out, flags):
    """:func:`finish_update` of H-cell ``values[i]`` (8 fields) written into ``out[i]`` and
    ``flags[i]``; returns False when the result is not finite."""
    n1_new, n2_new, t1_new = linear_forces(values[i, 0], values[i, 3], values[i, 4], values[i, 5],
                                           dd1, dd2, da, p)
    r = finish_update(values[i, 0], values[i, 1], values[i, 2], values[i, 6], values[i, 7], dl1,
                      dl2, dd1, dd2, da, n1_new, n2_new, t1_new, sliding, xi, p)
    return write_update(r, out, flags, i, 0, 0)


@njit(cache=True, error_model="numpy")
def step_kernel(values, dl, p, out, flags):
    """Advance every cell; ``values``/``out`` (n, 8), ``dl`` (n, 2), ``flags`` (n, 5).

    Returns the index of the first failed cell, or -1.
    """
    mech = cell_mechanisms(p)
    if mech == MECH_NONE:
        return _step_loop(values, dl, p, out, flags, MECH_NONE)
    return _step_loop(values, dl, p, out, flags, MECH_ANY)


@njit(cache=True, error_model="numpy")
def _step_loop(values, dl, p, out, flags, mech):
    """:func:`step_kernel`'s loop of the cell ``mech`` (a literal)."""
    literally(mech)
    bad = -1
    for i in range(values.shape[0]):
        ok = cell_increment_mech(values, i, dl[i, 0], dl[i, 1], p, out, flags, 0, 0, mech)
        if not ok and bad < 0:
            bad = i
    return bad


class ClosedFormSolver(CellSolver):
    """The H-cell solved in closed form (eq. 1.7). Implements :class:`hmodel.cell.CellSolver`."""

    name = "closed-form"
    #: exact to round-off: Newton's own tolerance holds
    stress_rtol = 0.0
    #: measured: about 570 B a cell (peak RSS of drained biaxial runs at nθ = 2·10⁴ and 2·10⁵)
    bytes_per_cell = 1024
    n_lengths = 2
    state_kind = STATE_H_CELL
    #: a cell's α0 is its state's alpha before any increment: cells may start apart
    spread_alpha0 = True
    #: eq. 1.7 of Hertz-Mindlin contacts, and cells reborn (docs/mechanisms.md; ``mix`` by the
    #: REV, which knows the mean box area: hmodel.rev.kernels)
    mechanisms = frozenset({"contact=hertz-mindlin", "renewal=rebirth", "renewal=mix"})

    @classmethod
    def from_spec(cls, spec: str = "closed-form") -> "ClosedFormSolver":
        """The solver of the spec ``closed-form`` (it takes no options)."""
        if spec != "closed-form":
            raise InputError(f"the closed-form solver takes no options, got {spec!r}")
        return cls()

    def initial(self, params: Params, shape: tuple[int, ...] = ()) -> CellState:
        return CellState.initial(params, shape)

    def initial_cells(self, params: Params, alpha0: np.ndarray) -> CellState:
        return initial_cells(params, np.asarray(alpha0, float))

    def meso(self, params: Params, state: CellState) -> None:
        """None: an H-cell's stress is eq. 1.12 of its fields (the REV computes it)."""
        return None

    def kernel(self, params: Params) -> CellKernel:
        """Eq. 1.7 in the compiled loading path."""
        return CellKernel(kernel_params(params))

    def fractions(self, params: Params, state: CellState) -> dict[str, np.ndarray]:
        """None beyond the flags."""
        return {}

    def step(self, params: Params, state: CellState, dl1, dl2) -> tuple[CellState, CellFlags]:
        """One increment of every cell.

        Parameters
        ----------
        params : Params
        state : CellState
            State before the increment, leading shape S.
        dl1, dl2 : array_like, broadcastable to S
            Increments of the cell lengths on which the strain acts [m]: l1, l2 of eq. 1.2
            (l1* of eq. 1.21 with ``volume="hexagon-consistent"``). Negative is shortening.

        Returns
        -------
        (CellState, CellFlags)
            The state after the increment and its diagnostics.
        """
        shape = state.shape
        values = np.ascontiguousarray(state.values.reshape(-1, len(FIELDS)))
        dl = np.empty((values.shape[0], 2))
        dl[:, 0] = np.broadcast_to(dl1, shape).reshape(-1)
        dl[:, 1] = np.broadcast_to(dl2, shape).reshape(-1)
        out = np.empty_like(values)
        flags = np.empty((values.shape[0], len(FLAGS)), dtype=np.bool_)
        bad = step_kernel(values, dl, kernel_params(params), out, flags)
        if bad >= 0:
            raise SolverError(
                f"cell increment could not be solved (singular eq. 1.7 or non-finite result) "
                f"for cell {np.unravel_index(bad, shape) if shape else ()} with "
                f"state {dict(zip(FIELDS, values[bad].round(12)))} and dl=({dl[bad, 0]:.3g}, {dl[bad, 1]:.3g})")
        return CellState(out.reshape(*shape, len(FIELDS))), CellFlags(flags.reshape(*shape, len(FLAGS)))
