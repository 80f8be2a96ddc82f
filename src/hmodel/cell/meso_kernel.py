"""A cell increment with a learned response, as a compiled per-cell kernel (the REV's fast path).

It lives with the cells, below the loading drivers and the surrogates that both use it: the
``meso`` surrogates (:mod:`hmodel.surrogate.formulations.meso`) learn the response, this applies it.
A meso network sees the state only, so within one increment every Newton trial of a material
point applies the same learned response to another strain: ``dz = A e + sum_k <n_k . e - c_k^2>
B_k``, then the way back (``MesoFormulation._advanced`` in :mod:`hmodel.surrogate.formulations.meso`). :func:`meso_increment` is that
trial for one cell, in the same operations as the NumPy way back; the compiled loading driver
(:mod:`hmodel.loading.compiled`) runs it inside its Newton loop, so a trial costs no Python
call and no network evaluation. :func:`pack_responses` lays the responses of a batch of states
out as rows of one array; :func:`kernel_params` packs the formulation's constants after the
closed-form kernel's parameters.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..cell.base import LAW_MESO, P_LAW
from ..cell.closed_form import P_HERTZ, P_KN, P_R, P_TAN, kernel_params as cell_kernel_params
from ..cell.hertz import extra_slope
from ..cell.mesostress import contact_vsigma, vsigma_local
from ..params import Params

# Indices of the meso constants in the packed parameters (after the closed form's 7 and the law).
Q_E1, Q_E2, Q_L, Q_GAP, Q_REACH, Q_RN, Q_RT, Q_RAMP, Q_SCALES = range(P_LAW + 1, P_LAW + 10)


def kernel_params(formulation, params: Params) -> np.ndarray:
    """The closed-form kernel's parameters, the law (:data:`~hmodel.cell.base.LAW_MESO`),
    then the meso constants: 1/(l0 m0) along n and t
    (e = -dl/(l0 m0)), the number of learned fields L, the gap tolerance, the cage (reach, r_n,
    r_t, 1/(reach ramp)) and the learned fields' scales times m0."""
    reach, r_n, r_t = formulation._cage
    scales = formulation._scales() * formulation.m0
    m0 = formulation.m0
    return np.concatenate([cell_kernel_params(params), [
        LAW_MESO, 1.0 / (params.l10 * m0), 1.0 / (params.l20 * m0), len(scales), formulation.gap_tol, reach,
        r_n, r_t, 1.0 / (reach * formulation.cage_ramp) if reach else 0.0], scales])


def pack_responses(response: tuple, values: np.ndarray) -> np.ndarray:
    """Rows (n, 2L + K (3 + L) + 2) of a response (A (n, L, 2), n_k (n, K, 2), c_k^2 (n, K),
    B_k (n, K, L)) of summary states ``values`` (n, 11): A row-major, then per mechanism n_k,
    c_k = sqrt(c_k^2) (the network's own output: the trial squares it) and B_k, then cos and sin
    of the states' alpha (a trial turns alpha by little: its cos and sin follow by the angle-sum
    formulas, cheaper than two libm calls per cell-trial)."""
    A, nk, c2, B = response
    n, L, K = A.shape[0], A.shape[1], c2.shape[1]
    out = np.empty((n, 2 * L + K * (3 + L) + 2))
    _pack(A, nk, c2, B, values, out)  # one compiled pass over the rows, no temporaries
    return out


def pack_outputs(out: np.ndarray, n_learned: int, values: np.ndarray,
                 wide: np.ndarray | None = None) -> np.ndarray:
    """:func:`pack_responses` of one network's outputs (n, 2L + K (L + 3)) (``response(out)``),
    whose layout the packed rows are (with c_k, not c_k^2), then cos and sin of alpha. With
    ``wide``, an array (n, width + 2) whose first columns ``out`` is (``Surrogate.forward``'s
    ``spare``), only the last two are written: no copy of the outputs, which sit on the REV's
    path once per increment."""
    n, width = out.shape
    if wide is None:
        wide = np.empty((n, width + 2))
        wide[:, :width] = out
    np.cos(values[:, 2], out=wide[:, width])
    np.sin(values[:, 2], out=wide[:, width + 1])
    return wide


@njit(cache=True, error_model="numpy")
def _pack(A, nk, c2, B, values, out):
    n, L, K = A.shape[0], A.shape[1], c2.shape[1]
    for i in range(n):
        j = 0
        for a in range(L):
            out[i, j] = A[i, a, 0]
            out[i, j + 1] = A[i, a, 1]
            j += 2
        for k in range(K):
            out[i, j] = nk[i, k, 0]
            out[i, j + 1] = nk[i, k, 1]
            out[i, j + 2] = math.sqrt(c2[i, k])
            j += 3
            for a in range(L):
                out[i, j] = B[i, k, a]
                j += 1
        out[i, j] = math.cos(values[i, 2])
        out[i, j + 1] = math.sin(values[i, 2])


@njit(cache=True, inline="always", error_model="numpy")
def _turned(c0, s0, a, da):
    """(cos, sin) of a = a0 + da from c0, s0 = cos a0, sin a0: Taylor series of da to the
    rounding of float64 for |da| <= 0.02 (the next terms < 1e-20), libm beyond."""
    if abs(da) > 0.02:
        return math.cos(a), math.sin(a)
    d2 = da * da
    cd = 1.0 - d2 * (0.5 - d2 * (1.0 / 24 - d2 * (1.0 / 720 - d2 / 40320)))
    sd = da * (1.0 - d2 * (1.0 / 6 - d2 * (1.0 / 120 - d2 / 5040)))
    return c0 * cd - s0 * sd, s0 * cd + c0 * sd


@njit(cache=True, inline="always", error_model="numpy")
def _times_tangent(r, i, e1, e2, richer):
    """A e: the response's tangent (rows 0-11 of r[i], row-major) times the strain (e1, e2)."""
    return (r[i, 0] * e1 + r[i, 1] * e2, r[i, 2] * e1 + r[i, 3] * e2, r[i, 4] * e1 + r[i, 5] * e2,
            r[i, 6] * e1 + r[i, 7] * e2, r[i, 8] * e1 + r[i, 9] * e2 if richer else 0.0,
            r[i, 10] * e1 + r[i, 11] * e2 if richer else 0.0)


@njit(cache=True, inline="always", error_model="numpy")
def _plus_flow(r, i, b, c, richer, z0, z1, z2, z3, z4, z5):
    """z + c B_k, the mechanism's flow B_k at r[i, b:]."""
    return (z0 + c * r[i, b], z1 + c * r[i, b + 1], z2 + c * r[i, b + 2], z3 + c * r[i, b + 3],
            z4 + c * r[i, b + 4] if richer else z4, z5 + c * r[i, b + 5] if richer else z5)


@njit(cache=True, error_model="numpy")
def meso_increment(values, i, dl1, dl2, p, resp, out, flags, tangent, ddl1, ddl2, dv):
    """Advance the summary state ``values[i]`` (11,) of cell i by length increments (dl1, dl2)
    with its packed response ``resp[i]``; write the new state into ``out[i]`` and its flags into
    ``flags[i]``; returns False when the new state is not finite. The steps of
    ``MesoFormulation.step_cells``: e = de/m0 with de = -dl/l0, the response, then
    ``MesoFormulation._advanced`` and ``advance``'s flags. (Rows are indexed, never sliced: a
    slice is an array view Numba builds at every call, which costs more than the trial's own
    arithmetic.)

    With ``tangent`` (a literal at each call site, so that the plain trial compiles without it),
    also the derivative of the new (V sigma_nn, V sigma_tt) along the length increments
    (ddl1, ddl2), into ``dv`` (2,): exact within the cell's regime (which mechanisms load, which
    forces are clipped or capped, the cage gate's branch)."""
    e1 = -dl1 * p[Q_E1]
    e2 = -dl2 * p[Q_E2]
    f1 = -ddl1 * p[Q_E1]
    f2 = -ddl2 * p[Q_E2]
    L = int(p[Q_L])
    richer = L > 4
    r = resp
    # dz/m0 of the learned fields alpha, N1, N2, T1 (and Vs_nn, Vs_tt): the tangent, then every
    # mechanism that loads (and their derivatives g along the direction)
    z0, z1, z2, z3, z4, z5 = _times_tangent(r, i, e1, e2, richer)
    g0 = g1 = g2 = g3 = g4 = g5 = 0.0
    if tangent:
        g0, g1, g2, g3, g4, g5 = _times_tangent(r, i, f1, f2, richer)
    R = r.shape[1] - 2  # then cos, sin of the state's alpha
    for b in range(2 * L, R, L + 3):
        load = r[i, b] * e1 + r[i, b + 1] * e2 - r[i, b + 2] * r[i, b + 2]
        if load > 0.0:
            z0, z1, z2, z3, z4, z5 = _plus_flow(r, i, b + 3, load, richer, z0, z1, z2, z3, z4, z5)
            if tangent:
                g0, g1, g2, g3, g4, g5 = _plus_flow(r, i, b + 3, r[i, b] * f1 + r[i, b + 1] * f2, richer,
                                                    g0, g1, g2, g3, g4, g5)
    s = Q_SCALES
    da = z0 * p[s]
    a = values[i, 2] + da
    u1 = values[i, 3] + z1 * p[s + 1]
    u2 = values[i, 4] + z2 * p[s + 2]
    u3 = values[i, 5] + z3 * p[s + 3]
    r_grain, tan_phi = p[P_R], p[P_TAN]
    two_r = 2.0 * r_grain
    ca, sa = _turned(r[i, R], r[i, R + 1], a, da)
    l1, l2 = values[i, 6] + dl1, values[i, 7] + dl2
    d1 = l2 / (2.0 * sa)  # eq. 1.2
    d2 = l1 - 2.0 * d1 * ca
    apart = two_r * (1.0 + p[Q_GAP])
    n1 = max(u1, 0.0) if d1 < apart else 0.0
    n2 = max(u2, 0.0) if d2 < apart else 0.0
    t1 = min(max(u3, -tan_phi * n1), tan_phi * n1)  # eq. 1.3
    o = out
    o[i, 0], o[i, 1], o[i, 2], o[i, 3], o[i, 4], o[i, 5], o[i, 6], o[i, 7] = d1, d2, a, n1, n2, t1, l1, l2
    if tangent:  # the same steps, differentiated
        d_a = g0 * p[s]
        dca, dsa = -sa * d_a, ca * d_a
        dd1 = ddl2 / (2.0 * sa) - d1 * dsa / sa
        dd2 = ddl1 - 2.0 * (dd1 * ca + d1 * dca)
        dn1 = g1 * p[s + 1] if (d1 < apart and u1 > 0.0) else 0.0
        dn2 = g2 * p[s + 2] if (d2 < apart and u2 > 0.0) else 0.0
        if u3 >= tan_phi * n1:
            dt1 = tan_phi * dn1
        elif u3 <= -tan_phi * n1:
            dt1 = -tan_phi * dn1
        else:
            dt1 = g3 * p[s + 3]
        # eq. 1.12 differentiated
        c2, s2, cs = ca * ca, sa * sa, ca * sa
        dc2, ds2, dcs = 2.0 * ca * dca, 2.0 * sa * dsa, dca * sa + ca * dsa
        dhnn = (4.0 * (dn1 * d1 * c2 + n1 * dd1 * c2 + n1 * d1 * dc2)
                + 4.0 * (dt1 * d1 * cs + t1 * dd1 * cs + t1 * d1 * dcs) + 2.0 * (dn2 * d2 + n2 * dd2))
        dhtt = (4.0 * (dn1 * d1 * s2 + n1 * dd1 * s2 + n1 * d1 * ds2)
                - 4.0 * (dt1 * d1 * cs + t1 * dd1 * cs + t1 * d1 * dcs))
    if richer:  # the learned V sigma, compressive
        vnn = max(values[i, 8] + z4 * p[s + 4], 0.0)
        vtt = max(values[i, 9] + z5 * p[s + 5], 0.0)
        if tangent:
            dvnn = g4 * p[s + 4] if vnn > 0.0 else 0.0
            dvtt = g5 * p[s + 5] if vtt > 0.0 else 0.0
        reach = p[Q_REACH]
        if reach > 0.0:  # the loose-cage gate (MesoFormulation._advanced)
            diag = math.sqrt((d2 / 2) ** 2 + (l2 / 2) ** 2)
            along_n = l1 / 2 - p[Q_RN] <= diag - p[Q_RT]
            clearance = l1 / 2 - p[Q_RN] if along_n else diag - p[Q_RT]
            w_raw = (reach * (1.0 + p[Q_GAP]) - clearance) * p[Q_RAMP]
            w = min(max(w_raw, 0.0), 1.0)
            hnn, htt = contact_vsigma(d1, d2, ca, sa, n1, n2, t1)  # eq. 1.12
            if tangent:
                dclear = ddl1 / 2 if along_n else (d2 * dd2 + l2 * ddl2) / (4.0 * diag)
                dw = -dclear * p[Q_RAMP] if 0.0 < w_raw < 1.0 else 0.0
                dvnn = dhnn + dw * (vnn - hnn) + w * (dvnn - dhnn)
                dvtt = dhtt + dw * (vtt - htt) + w * (dvtt - dhtt)
            vnn, vtt = hnn + w * (vnn - hnn), htt + w * (vtt - htt)
    else:  # an H-cell: eq. 1.12 of the fields
        vnn, vtt = vsigma_local(o, i, p[P_KN], p[P_HERTZ], two_r)
        if tangent:
            dvnn, dvtt = dhnn, dhtt
            if l1 <= two_r:  # the extra contacts of vsigma_local
                dvnn += extra_slope(p[P_KN], p[P_HERTZ], two_r, l1) * ddl1
            if l2 <= two_r:
                dvtt += 2.0 * extra_slope(p[P_KN], p[P_HERTZ], two_r, l2) * ddl2
    if tangent:
        dv[0], dv[1] = dvnn, dvtt
    o[i, 8], o[i, 9], o[i, 10] = vnn, vtt, 0.0
    flags[i, 0] = n1 > 0 and abs(t1) >= tan_phi * n1 * (1 - 1e-9)
    flags[i, 1] = n1 == 0
    flags[i, 2] = n2 == 0
    flags[i, 3] = l1 <= two_r
    flags[i, 4] = l2 <= two_r
    return math.isfinite(d1 + d2 + a + n1 + n2 + t1 + vnn + vtt)


@njit(cache=True, error_model="numpy")
def advance_cells(values, dl, p, resp):
    """Every cell of ``values`` (n, 11) advanced by its length increments ``dl`` (n, 2) with
    its packed response: :func:`meso_increment` over a batch (the solver's ``step``); returns
    the new states, the flags and whether all are finite."""
    out = np.empty_like(values)
    flags = np.empty((values.shape[0], 5), dtype=np.bool_)
    unused = np.empty(2)
    ok = True
    for i in range(values.shape[0]):
        ok &= meso_increment(values, i, dl[i, 0], dl[i, 1], p, resp, out, flags, False, 0.0, 0.0, unused)
    return out, flags, ok
