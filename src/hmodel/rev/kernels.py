"""Compiled loops of the REV: strain localization (eq. 1.1) and stress averaging (eq. 1.15),
and the 2D REV's fused trial of one material point (:func:`trial`, for the compiled loading
path and the FEM material).

In :func:`localize` and :func:`average` arrays are flat over (material point, direction): cell
``k = b*n_theta + i``. The trial reads its geometry as the 3D REV's does
(:mod:`hmodel.rev.kernels3d`): one row per cell, here (cos², sin², sin·cos and their weighted
versions) (:data:`GEO_WIDTH`, :meth:`hmodel.rev.Rev.kernel_inputs`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import literally, njit

from ..cell.base import LAW_COMPLIANCE, LAW_MESO, P_LAW
from ..cell.closed_form import (
    MECH_ANY,
    MECH_NONE,
    P_HERTZ,
    P_KN,
    P_R,
    P_RENEW,
    REGIME_WIDTH,
    cell_increment_prepared,
    cell_jacobian,
    cell_mechanisms,
    prepare_cell,
    prepared,
)
from ..cell import hertz_batch
from ..cell.compliance_kernel import compliance_increment
from ..cell.hertz_batch import DL1, DL2
from ..cell.meso_kernel import meso_increment
from ..cell.mesostress import vsigma_local
from ..cell.renewal import RENEW_MIX, mix_rebirth

# Localization modes: on which lengths the strain acts (docs/model.md, step 5).
LOC_CELL, LOC_BOX, LOC_VIRTUAL = 0, 1, 2
#: Per-cell inputs of the 2D trial: cos², sin², sin·cos of the direction, then each times its
#: weight (eq. 1.17).
GEO_WIDTH = 6


@njit(cache=True, inline="always")
def cell_dl(values, k, e11, e22, e12, c2, s2, sc, mode, radius):
    """(dl1, dl2) of cell k of packed states ``values`` at direction (cos², sin², sin·cos).

    dl = -(L1 deps_nn, L2 deps_tt) (eq. 1.1 with shear), where L1, L2 are l1, l2
    (``LOC_CELL``), l1 + 2r, l2 + 2r (``LOC_BOX``, eq. 1.19) or the virtual rectangle
    l1* = l1 - d1 cos(alpha), l2 (``LOC_VIRTUAL``, eq. 1.21).
    """
    enn = e11 * c2 + e22 * s2 + 2.0 * e12 * sc
    ett = e11 * s2 + e22 * c2 - 2.0 * e12 * sc
    l1, l2 = values[k, 6], values[k, 7]
    if mode == LOC_BOX:
        return -(l1 + 2.0 * radius) * enn, -(l2 + 2.0 * radius) * ett
    if mode == LOC_VIRTUAL:
        return -(l1 - values[k, 0] * math.cos(values[k, 2])) * enn, -l2 * ett
    return -l1 * enn, -l2 * ett


@njit(cache=True)
def localize(values, deps, cos2, sin2, sincos, mode, radius, dl):
    """dl[k] = (dl1, dl2) of every cell ``k = b*n_theta + i`` (see :func:`cell_dl`)."""
    n_theta = cos2.shape[0]
    for b in range(deps.shape[0]):
        for i in range(n_theta):
            k = b * n_theta + i
            dl[k, 0], dl[k, 1] = cell_dl(values, k, deps[b, 0], deps[b, 1], deps[b, 2], cos2[i],
                                         sin2[i], sincos[i], mode, radius)


@njit(cache=True, inline="always")
def weighted_global(vnn, vtt, wc2, ws2, wsc):
    """A cell's (V sigma_nn, V sigma_tt) rotated to (11, 22, 12) and weighted (eqs. 1.15-1.16)."""
    return vnn * wc2 + vtt * ws2, vnn * ws2 + vtt * wc2, (vnn - vtt) * wsc


@njit(cache=True, error_model="numpy")
def mean_box_area(values, geo):
    """The REV's mean box area Σ w l1·l2 / Σ w of one point's cells ``values`` (n, 8), w the
    directions' weights (``geo[:, 3] + geo[:, 4]`` = w cos² + w sin², :data:`GEO_WIDTH`): the
    volume on the cells' own measure, which ``volume="hexagon"`` carries as exp(-tr ε)
    (docs/mechanisms.md, "Rebirth at the mean box area")."""
    num = 0.0
    den = 0.0
    for i in range(values.shape[0]):
        w = geo[i, 3] + geo[i, 4]
        num += w * values[i, 6] * values[i, 7]
        den += w
    return num / den


@njit(cache=True, error_model="numpy")
def renew_mix(values, out, flags, geo, dl1, two_r):
    """``renewal="mix"`` on cells stepped outside the fused trial (the generic path,
    :meth:`hmodel.rev.Rev.step`): every cell of point b that opened in the increment
    (``flags[b, i]``: open1 or open2) reborn by :func:`hmodel.cell.renewal.mix_rebirth` at the
    mean box area of the point's cells at the start of the increment ``values[b]``, on the
    branch its axis takes (``dl1[b, i]`` < 0: shortened). Arrays (B, n, ...), ``geo`` (n, 6)."""
    for b in range(values.shape[0]):
        area = mean_box_area(values[b], geo)
        for i in range(values.shape[1]):
            if flags[b, i, 1] or flags[b, i, 2]:
                mix_rebirth(out[b], flags[b], i, area, dl1[b, i] < 0.0, two_r)


@njit(cache=True)
def average(values, wcos2, wsin2, wsincos, kn, hertz, sets, radius, vsig):
    """vsig[b] = sum_i w_i V_i sigma_i in the global frame (eqs. 1.12, 1.15, 1.16).

    Weighted trigonometric factors are precomputed per parameter set (K, n_theta): w*cos^2,
    w*sin^2, w*sin*cos; kn (K,) and the Hertz constants (K,) of the extra contacts (0: linear,
    :func:`hmodel.cell.mesostress.vsigma_local`); point b has set ``sets[b]``.
    """
    n_theta = wcos2.shape[1]
    two_r = 2.0 * radius
    for b in range(vsig.shape[0]):
        k = sets[b]
        s11 = 0.0
        s22 = 0.0
        s12 = 0.0
        for i in range(n_theta):
            vnn, vtt = vsigma_local(values, b * n_theta + i, kn[k], hertz[k], two_r)
            a11, a22, a12 = weighted_global(vnn, vtt, wcos2[k, i], wsin2[k, i], wsincos[k, i])
            s11 += a11
            s22 += a22
            s12 += a12
        vsig[b, 0] = s11
        vsig[b, 1] = s22
        vsig[b, 2] = s12


@njit(cache=True, inline="always", error_model="numpy")
def prepared_width(p, resp):
    """Width of the per-cell inputs of a point's trial that its committed cells fix
    (:func:`prepare`), with packed parameters ``p`` and learned responses ``resp`` (n, R; R = 0:
    none): a closed-form cell's with linear contacts
    (:func:`hmodel.cell.closed_form.regime_state`); none for other cells
    (:func:`hmodel.cell.closed_form.prepared`)."""
    if resp.shape[1] == 0 and prepared(p):
        return REGIME_WIDTH
    return 0


@njit(cache=True, error_model="numpy")
def prepare(values, p, pre):
    """``pre[i]``: the part of eq. 1.7 that cell i's committed state ``values[i]`` fixes
    (:func:`hmodel.cell.closed_form.prepare_cell`: an H-cell's, or each hexagon's of a
    bi-hexagon), for every trial from that state (:func:`trial_prepared`,
    :func:`hmodel.rev.kernels3d.bihex_trial_prepared`); nothing where ``pre`` is (n, 0)
    (:func:`prepared_width`, :func:`hmodel.cell.bihex.bihex_prepared_width`).

    Newton makes several trials from one committed state, and the cells' trigonometry, their
    matrices of eq. 1.7 and the matrices' cofactors are the same in all of them: computed once
    here with the same expressions, they are the same values to the last bit."""
    if pre.shape[1] == 0:
        return
    for i in range(values.shape[0]):
        prepare_cell(values, i, p, pre)


@njit(cache=True, error_model="numpy")
def new_prepared(values, p, width):
    """A new array (n, ``width``) of :func:`prepare`'s inputs of cells ``values``: ``width`` the
    2D REV's :func:`prepared_width` or the 3D REV's
    (:func:`hmodel.cell.bihex.bihex_prepared_width`)."""
    pre = np.empty((values.shape[0], width))
    prepare(values, p, pre)
    return pre


@njit(cache=True, error_model="numpy")
def trial(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp):
    """REV step of one material point: cells ``values`` (n, n_fields) -> ``out``, stress -> ``sig``.

    Same operations, in the same order, as ``Rev.localize``, the cell solver and ``Rev.stress``:
    the closed-form cell kernel, or with learned responses ``resp`` (n, R > 0) the law at
    ``p[P_LAW]``: the meso surrogate's trial (``meso_kernel.meso_increment``) or learned
    compliances (``compliance_kernel.compliance_increment``). Returns False when a cell increment
    failed.
    """
    return trial_prepared(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp,
                          new_prepared(values, p, prepared_width(p, resp)))


@njit(cache=True, error_model="numpy")
def trial_prepared(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp, pre):
    """:func:`trial` given its state-only inputs ``pre`` (:func:`prepare` of ``values``), for a
    caller that makes several trials from one committed state."""
    mech = cell_mechanisms(p) if resp.shape[1] == 0 else MECH_ANY
    if mech == MECH_NONE:  # the published cell's loop: none of the mechanisms' code in it
        return _trial_core(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp,
                           False, deps, sig, MECH_NONE, pre)
    return _trial_core(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp, False,
                       deps, sig, MECH_ANY, pre)


@njit(cache=True, error_model="numpy")
def trial_tangent(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp, u, dsig):
    """:func:`trial` of a meso surrogate that also gives ``dsig``, the derivative of the stress
    along the strain direction ``u`` (3,): exact within every cell's regime."""
    return _trial_core(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp, True, u,
                       dsig, MECH_ANY, np.empty((values.shape[0], 0)))


@njit(cache=True, error_model="numpy")
def _trial_core(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp, tangent, u, dsig,
                mech, pre):
    literally(mech)  # a loop of its own per cell (closed_form.MECH_NONE, ...)
    two_r = 2.0 * p[P_R]
    kn = p[P_KN]
    hertz = 0.0 if mech == MECH_NONE else p[P_HERTZ]
    e11, e22, e12 = deps[0], deps[1], deps[2]
    s11 = 0.0
    s22 = 0.0
    s12 = 0.0
    d11 = 0.0
    d22 = 0.0
    d12 = 0.0
    dv = np.empty(2)
    ok = True
    law = p[P_LAW] if resp.shape[1] > 0 else 0.0
    meso = law == LAW_MESO
    # renewal=mix: a REV quantity, the mean box area at the start of the increment
    mix = mech != MECH_NONE and law == 0.0 and p[P_RENEW] == RENEW_MIX
    area = mean_box_area(values, geo) if mix else 0.0
    # Hertz-Mindlin contacts: every cell's increment at once (hertz_batch says why)
    batch = mech != MECH_NONE and law == 0.0 and p[P_HERTZ] != 0.0
    work = pre  # read below only where batch
    if batch:
        work = hertz_batch.work(values.shape[0])
        for i in range(values.shape[0]):
            work[DL1, i], work[DL2, i] = cell_dl(values, i, e11, e22, e12, geo[i, 0], geo[i, 1],
                                                 geo[i, 2], mode, p[P_R])
        ok = hertz_batch.update(values, work, p, out, flags, mech, 0)
    for i in range(values.shape[0]):
        if batch:  # the cell's increment made above
            dl1 = work[DL1, i]
        else:
            dl1, dl2 = cell_dl(values, i, e11, e22, e12, geo[i, 0], geo[i, 1], geo[i, 2], mode,
                               p[P_R])
        if meso:
            ddl1 = ddl2 = 0.0
            if tangent:  # cell_dl is linear in the strain: its derivative along u is cell_dl(u)
                ddl1, ddl2 = cell_dl(values, i, u[0], u[1], u[2], geo[i, 0], geo[i, 1], geo[i, 2], mode,
                                     p[P_R])
            ok &= meso_increment(values, i, dl1, dl2, p, resp, out, flags, tangent, ddl1, ddl2, dv)
            vnn, vtt = out[i, 8], out[i, 9]  # V sigma_nt = 0
            if tangent:
                b11, b22, b12 = weighted_global(dv[0], dv[1], geo[i, 3], geo[i, 4], geo[i, 5])
                d11 += b11
                d22 += b22
                d12 += b12
        else:
            if law == LAW_COMPLIANCE:
                ok &= compliance_increment(values, i, dl1, dl2, resp, p, out, flags)
            else:
                if not batch:  # linear contacts' state-only part read from ``pre`` (prepare)
                    ok &= cell_increment_prepared(values, i, dl1, dl2, p, out, flags, mech, pre, 0)
                if mix and (flags[i, 1] or flags[i, 2]):  # docs/mechanisms.md, "Renewal"
                    mix_rebirth(out, flags, i, area, dl1 < 0.0, two_r)
            vnn, vtt = vsigma_local(out, i, kn, hertz, two_r)
        a11, a22, a12 = weighted_global(vnn, vtt, geo[i, 3], geo[i, 4], geo[i, 5])
        s11 += a11
        s22 += a22
        s12 += a12
    t11 = eps[0] + e11  # total strain after the trial: the macro volume V0 det(I - eps)
    t22 = eps[1] + e22
    t12 = eps[2] + e12
    v = volume0 * ((1 - t11) * (1 - t22) - t12 ** 2)
    sig[0] = s11 / v
    sig[1] = s22 / v
    sig[2] = s12 / v
    if tangent:  # d(S / V) = dS / V - sig dV / V
        dvol = volume0 * (-(1 - t22) * u[0] - (1 - t11) * u[1] - 2.0 * t12 * u[2])
        dsig[0] = (d11 - sig[0] * dvol) / v
        dsig[1] = (d22 - sig[1] * dvol) / v
        dsig[2] = (d12 - sig[2] * dvol) / v
    return ok


@njit(cache=True, error_model="numpy")
def closed_form_tangent(values, eps, deps, geo, p, mode, volume0, sig, D):
    """The exact tangent ``D`` (3, 3), dsig_i / ddeps_j, of the closed form's :func:`trial` at
    ``deps`` whose stress is ``sig``, in the regime each cell takes there (one pass over the
    cells, where forward differences take three trials). Returns False where a cell increment
    fails.

    Chain rule through the operations of :func:`trial`: the localization (eq. 1.1, linear in
    the strain, so its derivative along e_j is itself at e_j), the cells' own Jacobians
    (:func:`hmodel.cell.closed_form.cell_jacobian`), the weighted rotation to the global frame
    (eqs. 1.15-1.16, linear) and the macro volume V0 det(I - eps): d(S / V) = dS / V - sig dV / V.
    """
    e11, e22, e12 = deps[0], deps[1], deps[2]
    D[:, :] = 0.0
    ok = True
    for i in range(values.shape[0]):
        dl1, dl2 = cell_dl(values, i, e11, e22, e12, geo[i, 0], geo[i, 1], geo[i, 2], mode, p[P_R])
        good, j11, j12, j21, j22 = cell_jacobian(
            values[i, 0], values[i, 1], values[i, 2], values[i, 3], values[i, 4], values[i, 5],
            values[i, 6], values[i, 7], dl1, dl2, p)
        ok &= good
        for j in range(3):
            u1, u2 = cell_dl(values, i, 1.0 if j == 0 else 0.0, 1.0 if j == 1 else 0.0,
                             1.0 if j == 2 else 0.0, geo[i, 0], geo[i, 1], geo[i, 2], mode, p[P_R])
            b11, b22, b12 = weighted_global(j11 * u1 + j12 * u2, j21 * u1 + j22 * u2, geo[i, 3],
                                            geo[i, 4], geo[i, 5])
            D[0, j] += b11
            D[1, j] += b22
            D[2, j] += b12
    t11 = eps[0] + e11
    t22 = eps[1] + e22
    t12 = eps[2] + e12
    v = volume0 * ((1 - t11) * (1 - t22) - t12 ** 2)
    dvol = (-volume0 * (1 - t22), -volume0 * (1 - t11), -2.0 * volume0 * t12)
    for j in range(3):
        for k in range(3):
            D[k, j] = (D[k, j] - sig[k] * dvol[j]) / v
    return ok
