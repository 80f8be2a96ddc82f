"""Compiled loops of the REV: strain localization (eq. 1.1) and stress averaging (eq. 1.15).

Arrays are flat over (material point, direction): cell ``k = b*n_theta + i``.
"""

from __future__ import annotations

import math

from numba import njit

from ..cell.mesostress import vsigma_local

# Localization modes: on which lengths the strain acts (docs/model.md, step 5).
LOC_CELL, LOC_BOX, LOC_VIRTUAL = 0, 1, 2


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


@njit(cache=True)
def average(values, wcos2, wsin2, wsincos, kn, sets, radius, vsig):
    """vsig[b] = sum_i w_i V_i sigma_i in the global frame (eqs. 1.12, 1.15, 1.16).

    Weighted trigonometric factors are precomputed per parameter set (K, n_theta): w*cos^2,
    w*sin^2, w*sin*cos; kn (K,); point b has set ``sets[b]``.
    """
    n_theta = wcos2.shape[1]
    two_r = 2.0 * radius
    for b in range(vsig.shape[0]):
        k = sets[b]
        s11 = 0.0
        s22 = 0.0
        s12 = 0.0
        for i in range(n_theta):
            vnn, vtt = vsigma_local(values, b * n_theta + i, kn[k], two_r)
            a11, a22, a12 = weighted_global(vnn, vtt, wcos2[k, i], wsin2[k, i], wsincos[k, i])
            s11 += a11
            s22 += a22
            s12 += a12
        vsig[b, 0] = s11
        vsig[b, 1] = s22
        vsig[b, 2] = s12
