"""Compiled REV trial of the 3D model (docs/model3d.md): one material point's :meth:`Rev3D.step`
fused in one loop over its bi-hexagons, for the compiled loading path
(:mod:`hmodel.loading.compiled`, :mod:`hmodel.loading.compiled3d`).

The same operations as ``Rev3D.localize``, ``BiHexSolver.step`` and ``Rev3D.stress``, in the
same order within each cell (the sums over cells and components are in another order than
NumPy's contractions: results agree to round-off): the normal strains along the cell's axes
from the projector rows (``rev3d.projector``), δl_k = -L_k ε_kk (eq. 1.1 lifted), the two
hexagons' 2D increments sharing δl1 (:func:`hmodel.cell.bihex.bihex_increment`), the cell-frame
V σ (:func:`hmodel.cell.bihex.bihex_vsigma`) rotated by the weighted dyads e_k ⊗ e_k and summed,
divided by the macro volume V0 det(I - ε).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..cell import hertz_batch
from ..cell.bihex import (
    bihex_hertz_increments,
    bihex_increment,
    bihex_prepared_width,
    bihex_vsigma,
    cross_contact,
)
from ..cell.closed_form import (
    MECH_ANY,
    MECH_NONE,
    P_CROSS,
    P_HERTZ,
    P_KN,
    P_R,
    P_RENEW,
    cell_increment_prepared,
    cell_mechanisms,
)
from ..cell.hertz_batch import DL1, DL2
from ..cell.renewal import RENEW_MIX, bihex_open, mix_rebirth_bihex
from .kernels import LOC_BOX, new_prepared

#: Per-cell kernel inputs (:func:`geometry`): the projector's 3 x 6 rows, then the weighted
#: dyads' 3 x 6.
GEO_WIDTH = 36


def geometry(proj: np.ndarray, wdyads: np.ndarray) -> np.ndarray:
    """Kernel inputs (C, 36) of cells with projector rows ``proj`` (C, 3, 6) and weighted dyads
    ``wdyads`` (C, 3, 6) (``Rev3D._proj``, ``Rev3D._wdyads``)."""
    C = proj.shape[0]
    return np.ascontiguousarray(np.concatenate([proj.reshape(C, 18), wdyads.reshape(C, 18)], axis=1))


@njit(cache=True, inline="always", error_model="numpy")
def det_i_minus(t):
    """det(I - ε) of a Voigt strain t (6,) = (11, 22, 33, 23, 13, 12), tensor shear."""
    a, b, c = 1.0 - t[0], 1.0 - t[1], 1.0 - t[2]
    d, e, f = -t[3], -t[4], -t[5]  # (2,3), (1,3), (1,2) entries of I - ε
    return a * (b * c - d * d) - f * (f * c - d * e) + e * (f * d - b * e)


@njit(cache=True, error_model="numpy")
def mean_box_volume(values, geo):
    """The REV's mean box Σ w l1·l2·l3 / Σ w of one point's bi-hexagons ``values`` (C, 16), w
    the cells' weights (the trace of the weighted dyad e1 ⊗ e1: ``geo[:, 18:21]``)."""
    num = 0.0
    den = 0.0
    for i in range(values.shape[0]):
        w = geo[i, 18] + geo[i, 19] + geo[i, 20]
        num += w * values[i, 6] * values[i, 7] * values[i, 15]
        den += w
    return num / den


@njit(cache=True, error_model="numpy")
def renew_mix3d(values, out, flags, geo, dl1, two_r):
    """``renewal="mix"`` on bi-hexagons stepped outside the fused trial (the generic path,
    ``Rev3D.step``), as :func:`bihex_trial` does: arrays (B, C, ...), ``geo`` (C, 36)."""
    for b in range(values.shape[0]):
        area = mean_box_volume(values[b], geo)
        for i in range(values.shape[1]):
            mix_rebirth_bihex(out[b], flags[b], i, area, dl1[b, i] < 0.0, two_r)


@njit(cache=True, inline="always", error_model="numpy")
def cell_lengths(values, geo, i, d0, d1, d2, d3, d4, d5, add):
    """(δl1, δl2, δl3) of bi-hexagon i by the strain increment (d0, ..., d5): the normal
    strains along its axes from its projector rows, δl_k = -L_k ε_kk (L_k its length, + ``add``,
    2r of the box volume)."""
    e0 = (geo[i, 0] * d0 + geo[i, 1] * d1 + geo[i, 2] * d2 + geo[i, 3] * d3 + geo[i, 4] * d4
          + geo[i, 5] * d5)
    e1 = (geo[i, 6] * d0 + geo[i, 7] * d1 + geo[i, 8] * d2 + geo[i, 9] * d3 + geo[i, 10] * d4
          + geo[i, 11] * d5)
    e2 = (geo[i, 12] * d0 + geo[i, 13] * d1 + geo[i, 14] * d2 + geo[i, 15] * d3
          + geo[i, 16] * d4 + geo[i, 17] * d5)
    return -(values[i, 6] + add) * e0, -(values[i, 7] + add) * e1, -(values[i, 15] + add) * e2


@njit(cache=True, error_model="numpy")
def bihex_trial(values, eps, deps, geo, p, mode, volume0, out, flags, sig):
    """:meth:`Rev3D.step` of one material point: cells ``values`` (C, 16) at strain ``eps`` (6,)
    by the strain increment ``deps`` (6,) -> cells ``out``, flags ``flags`` (C, 11), stress
    ``sig`` (6,); ``geo`` (C, 36) (:func:`geometry`), ``p`` the closed form's packed parameters,
    ``mode`` ``LOC_BOX`` (the ``box`` volume: lengths + 2r) or not. Returns False when a cell
    increment failed."""
    return bihex_trial_prepared(values, eps, deps, geo, p, mode, volume0, out, flags, sig,
                                new_prepared(values, p, bihex_prepared_width(p)))


@njit(cache=True, error_model="numpy")
def bihex_trial_prepared(values, eps, deps, geo, p, mode, volume0, out, flags, sig, pre):
    """:func:`bihex_trial` given its state-only inputs ``pre`` (:func:`hmodel.rev.kernels.prepare`
    of ``values``, of width :func:`hmodel.cell.bihex.bihex_prepared_width`), for a caller that
    makes several trials from one committed state (Newton's): both hexagons' trigonometry,
    matrices of eq. 1.7 and cofactors, the same values to the last bit."""
    if cell_mechanisms(p) == MECH_NONE:  # the published cell's loop: none of the mechanisms' code
        return _bihex_trial_core(values, eps, deps, geo, p, mode, volume0, out, flags, sig, pre,
                                 None)
    return _bihex_trial_core(values, eps, deps, geo, p, mode, volume0, out, flags, sig, pre,
                             MECH_ANY)


@njit(cache=True, error_model="numpy")
def _bihex_trial_core(values, eps, deps, geo, p, mode, volume0, out, flags, sig, pre, mech):
    # A loop of its own for the published bi-hexagon (``mech`` None; else MECH_ANY), as the 2D
    # trial's, holding none of the mechanisms' code (contacts between the hexagons,
    # Hertz-Mindlin, renewal). None, not the literal MECH_NONE: Numba prunes a test of an
    # argument on None before it types the code, where a literal's dead branch is typed and
    # compiled all the same (the trial's compile time 16 -> 43 s;
    # docs/notes/2026-12-07-per-state-preparation-3d.md)
    two_r = 2.0 * p[P_R]
    kn = p[P_KN]
    hertz = 0.0 if mech is None else p[P_HERTZ]
    cross = 0.0 if mech is None else p[P_CROSS]
    add = two_r if mode == LOC_BOX else 0.0
    # renewal=mix: a REV quantity, the mean box l1·l2·l3 at the start of the increment
    mix = False if mech is None else p[P_RENEW] == RENEW_MIX
    area = mean_box_volume(values, geo) if mix else 0.0
    d0, d1, d2, d3, d4, d5 = deps[0], deps[1], deps[2], deps[3], deps[4], deps[5]
    s0 = s1 = s2 = s3 = s4 = s5 = 0.0
    ok = True
    # Indexed in place, no row views (closed_form.cell_update says why).
    # Hertz-Mindlin contacts (no contacts between the hexagons): every hexagon's increment at
    # once (hmodel.cell.hertz_batch says why)
    batch = mech is not None and p[P_CROSS] == 0.0 and p[P_HERTZ] != 0.0
    work_a = pre  # read below only where batch
    if batch:
        work_a = hertz_batch.work(values.shape[0])
        work_b = hertz_batch.work(values.shape[0])
        for i in range(values.shape[0]):
            dl1, dl2, dl3 = cell_lengths(values, geo, i, d0, d1, d2, d3, d4, d5, add)
            work_a[DL1, i] = work_b[DL1, i] = dl1
            work_a[DL2, i] = dl2
            work_b[DL2, i] = dl3
        ok = bihex_hertz_increments(values, work_a, work_b, p, out, flags)
    for i in range(values.shape[0]):
        if batch:  # the cell's increment made above
            dl1 = work_a[DL1, i]
        else:
            dl1, dl2, dl3 = cell_lengths(values, geo, i, d0, d1, d2, d3, d4, d5, add)
            if mech is None:
                # bihex_increment's published case written out: through it (a function inlined
                # into this loop, the hexagons' updates inlined into it) the trial ran about
                # three times as slow (docs/notes/2026-12-07-per-state-preparation-3d.md)
                ok_a = cell_increment_prepared(values, i, dl1, dl2, p, out, flags, MECH_NONE, pre,
                                               0)
                ok &= cell_increment_prepared(values, i, dl1, dl3, p, out, flags, MECH_NONE, pre,
                                              1) and ok_a
                flags[i, 10] = cross_contact(0.5 * (out[i, 1] - out[i, 9]), out[i, 7],
                                             out[i, 15], two_r)
            else:
                ok &= bihex_increment(values, i, dl1, dl2, dl3, p, out, flags, pre, mech)
        # docs/mechanisms.md, "Rebirth at the mean box area"; the call only for an open cell:
        # made for every cell, it cost a third of the sand variant's update
        if mix and bihex_open(flags, i):
            mix_rebirth_bihex(out, flags, i, area, dl1 < 0.0, two_r)
        nn, t1, t2 = bihex_vsigma(out, i, kn, hertz, two_r, cross)
        s0 += nn * geo[i, 18] + t1 * geo[i, 24] + t2 * geo[i, 30]
        s1 += nn * geo[i, 19] + t1 * geo[i, 25] + t2 * geo[i, 31]
        s2 += nn * geo[i, 20] + t1 * geo[i, 26] + t2 * geo[i, 32]
        s3 += nn * geo[i, 21] + t1 * geo[i, 27] + t2 * geo[i, 33]
        s4 += nn * geo[i, 22] + t1 * geo[i, 28] + t2 * geo[i, 34]
        s5 += nn * geo[i, 23] + t1 * geo[i, 29] + t2 * geo[i, 35]
    t = eps + deps  # total strain after the trial: the macro volume V0 det(I - eps)
    vol = volume0 * det_i_minus(t)
    sig[0] = s0 / vol
    sig[1] = s1 / vol
    sig[2] = s2 / vol
    sig[3] = s3 / vol
    sig[4] = s4 / vol
    sig[5] = s5 / vol
    return ok
