"""Compiled loops of the REV: strain localization (eq. 1.1) and stress averaging (eq. 1.15).

Arrays are flat over (material point, direction): cell ``k = b*n_theta + i``.
"""

from __future__ import annotations

import math

from numba import njit

from ..cell.mesostress import vsigma_local

# Localization modes: on which lengths the strain acts (DESIGN.md step 5).
LOC_CELL, LOC_BOX, LOC_VIRTUAL = 0, 1, 2


@njit(cache=True)
def localize(values, deps, cos2, sin2, sincos, mode, radius, dl):
    """dl[k] = -(L1, L2) * (deps_nn, deps_tt) for every cell (eq. 1.1 with shear).

    L1, L2 are l1, l2 (``LOC_CELL``), l1 + 2r, l2 + 2r (``LOC_BOX``, eq. 1.19) or the virtual
    rectangle l1* = l1 - d1 cos(alpha), l2 (``LOC_VIRTUAL``, eq. 1.21).
    """
    n_theta = cos2.shape[0]
    for b in range(deps.shape[0]):
        e11 = deps[b, 0]
        e22 = deps[b, 1]
        e12 = deps[b, 2]
        for i in range(n_theta):
            k = b * n_theta + i
            enn = e11 * cos2[i] + e22 * sin2[i] + 2.0 * e12 * sincos[i]
            ett = e11 * sin2[i] + e22 * cos2[i] - 2.0 * e12 * sincos[i]
            l1 = values[k, 6]
            l2 = values[k, 7]
            if mode == LOC_BOX:
                l1 += 2.0 * radius
                l2 += 2.0 * radius
            elif mode == LOC_VIRTUAL:
                l1 -= values[k, 0] * math.cos(values[k, 2])
            dl[k, 0] = -l1 * enn
            dl[k, 1] = -l2 * ett


@njit(cache=True)
def average(values, wcos2, wsin2, wsincos, kn, radius, vsig):
    """vsig[b] = sum_i w_i V_i sigma_i in the global frame (eqs. 1.12, 1.15, 1.16).

    Weighted trigonometric factors are precomputed: w*cos^2, w*sin^2, w*sin*cos.
    """
    n_theta = wcos2.shape[0]
    two_r = 2.0 * radius
    for b in range(vsig.shape[0]):
        s11 = 0.0
        s22 = 0.0
        s12 = 0.0
        for i in range(n_theta):
            vnn, vtt = vsigma_local(values[b * n_theta + i], kn, two_r)
            s11 += vnn * wcos2[i] + vtt * wsin2[i]
            s22 += vnn * wsin2[i] + vtt * wcos2[i]
            s12 += (vnn - vtt) * wsincos[i]
        vsig[b, 0] = s11
        vsig[b, 1] = s22
        vsig[b, 2] = s12
