"""Compiled loading segments for every cell solver with a compiled increment (the fast path).

:func:`hmodel.loading.control.solve_increment` drives any cell solver from Python; each round
of Newton trials is a batched REV call, and for one material point at nθ = 360 the Python
overhead exceeds the cell computation many times over. When the cell solver has a compiled
increment (:meth:`hmodel.cell.CellSolver.kernel`: the closed form, a ``meso`` or ``compliance``
surrogate), a whole segment instead runs in one Numba kernel: per increment and per material
point, the one Newton of :mod:`hmodel.loading.newton`, its trials evaluated here with
localization (eq. 1.1), the cell increment and averaging (eq. 1.15) fused in one loop over
directions (:func:`trial`).

The kernels are written for n components: n = 3 runs the H-cell trial above, n = 6 the 3D REV's
bi-hexagon trial (:func:`hmodel.rev.kernels3d.bihex_trial`, :func:`any_trial`), whose backend
is :class:`hmodel.loading.compiled3d.CompiledSegment3D`; Newton, the event loop, the batched
per-point kernel and the hand-back to the generic driver are the same code.

A learned cell response (``meso`` and ``compliance`` surrogates) sees the state only, so each
increment starts with one evaluation of every cell of every point (:func:`cell_responses`,
which may refuse cells outside a training domain), and every trial of the increment applies
that response, in :func:`hmodel.cell.meso_kernel.meso_increment` or
:func:`hmodel.cell.compliance_kernel.compliance_increment` (the law packed in the kernel's
parameters). Where one stress row is controlled, each trial of a meso response also gives the
exact stress slope along the free strain direction (:func:`trial_tangent`), in place of
Broyden's secant there.

The kernel has the generic driver's event fallback (a stress target inside the jump of a cell
event, see ``solve_increment``). An increment it still cannot converge is handed back to the
generic driver, which then either solves it or raises its error with the strain reached; the
kernel resumes after it. Results equal the generic path's to the Newton tolerance
(``tests/test_compiled.py``, ``tests/test_meso_compiled.py``).
"""

from __future__ import annotations

import types

import numpy as np
from numba import njit, prange

from ..cell.base import LAW_COMPLIANCE, LAW_MESO, P_LAW
from ..cell.closed_form import P_KN, P_R, cell_increment, cell_jacobian
from ..cell.compliance_kernel import compliance_increment
from ..cell.meso_kernel import meso_increment
from ..cell.mesostress import vsigma_local
from ..cell.state import CellFlags, CellState
from ..errors import InputError, PointFailure
from ..rev import Rev, RevState
from ..rev.kernels import cell_dl, weighted_global
from ..rev.kernels3d import bihex_trial
from .control import Control, Tangent, solve_increment
from .newton import (
    ASK_SLOPE,
    ASK_TANGENT,
    ASK_TRIAL,
    BSIG,
    BX,
    C_FD,
    COMMIT_EVENT,
    COMMIT_SOLUTION,
    SIG,
    XN,
    NewtonSettings,
    X,
    after_newton,
    begin,
    block,
    event_targets,
    free_direction,
    segment_targets,
    told_tangent,
    told_trial,
    workspace_size,
)
from .result import FRACTIONS

# Outcome of solve_point (one increment of one material point).
OK, NOT_CONVERGED = 0, 1


def supports(rev: Rev) -> bool:
    """Whether ``rev`` can run compiled segments: its cell solver has a compiled increment
    (:meth:`hmodel.cell.CellSolver.kernel`)."""
    return rev.kernel is not None


def kernel_inputs(rev: Rev, k: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(geo, p) for :func:`trial` of a point of parameter set k: the direction factors cos²,
    sin², sin·cos and their weighted versions (6, n_theta), and the solver kernel's packed
    parameters. A 2D REV's only (the 3D REV's: :func:`hmodel.loading.compiled3d.kernel_inputs3d`)."""
    if rev.n_components != 3:
        raise InputError(f"these compiled kernel inputs (and the stability probes built on them) are "
                         f"the 2D REV's, got a REV of {rev.n_components} components")
    d = rev.directions
    w = rev.weights[k]
    geo = np.ascontiguousarray(np.stack([d.cos2, d.sin2, d.sincos, w * d.cos2, w * d.sin2,
                                         w * d.sincos]))
    return geo, rev.kernels[k].params


def batch_inputs(rev: Rev) -> tuple[np.ndarray, np.ndarray]:
    """:func:`kernel_inputs` of every parameter set, stacked: (K, 6, n_theta) and (K, P)."""
    parts = [kernel_inputs(rev, k) for k in range(rev.n_sets)]
    return (np.ascontiguousarray(np.stack([g for g, _ in parts])),
            np.ascontiguousarray(np.stack([p for _, p in parts])))


def cell_responses(rev: Rev, values: np.ndarray, sets: np.ndarray | None = None) -> np.ndarray:
    """Per-cell inputs of :func:`trial` that depend on the cells' states (B, n_theta, n_fields)
    of points with parameter sets ``sets`` (B,) (None: the first for all): a learned response's
    packed rows (..., R), one evaluation per set present (which may refuse cells outside a
    training domain); nothing (..., 0) for the closed form."""
    if sets is None or rev.n_sets == 1:
        return cell_responses_of(rev.kernel, values)
    parts = {k: cell_responses_of(rev.kernels[k], values[sets == k]) for k in np.unique(sets)}
    first = next(iter(parts.values()))
    out = np.empty((*values.shape[:-1], first.shape[-1]))
    for k, part in parts.items():
        out[sets == k] = part
    return out


def cell_responses_of(kernel, values: np.ndarray) -> np.ndarray:
    """:func:`cell_responses` of cells (..., n_fields) that share one kernel."""
    if not kernel.learned:
        return np.empty((*values.shape[:-1], 0))
    flat = np.ascontiguousarray(values.reshape(-1, values.shape[-1]))
    packed = kernel.responses(flat)
    return packed.reshape(*values.shape[:-1], packed.shape[-1])


@njit(cache=True, error_model="numpy")
def trial(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp):
    """REV step of one material point: cells ``values`` (n, n_fields) -> ``out``, stress -> ``sig``.

    Same operations, in the same order, as ``Rev.localize``, the cell solver and ``Rev.stress``:
    the closed-form cell kernel, or with learned responses ``resp`` (n, R > 0) the law at
    ``p[P_LAW]``: the meso surrogate's trial (``meso_kernel.meso_increment``) or learned
    compliances (``compliance_kernel.compliance_increment``). Returns False when a cell increment
    failed.
    """
    return _trial_core(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp, False,
                       deps, sig)


@njit(cache=True, error_model="numpy")
def trial_tangent(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp, u, dsig):
    """:func:`trial` of a meso surrogate that also gives ``dsig``, the derivative of the stress
    along the strain direction ``u`` (3,): exact within every cell's regime."""
    return _trial_core(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp, True, u,
                       dsig)


@njit(cache=True, error_model="numpy")
def _trial_core(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp, tangent, u, dsig):
    cos2, sin2, sincos, wcos2, wsin2, wsincos = geo[0], geo[1], geo[2], geo[3], geo[4], geo[5]
    two_r = 2.0 * p[P_R]
    kn = p[P_KN]
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
    for i in range(values.shape[0]):
        dl1, dl2 = cell_dl(values, i, e11, e22, e12, cos2[i], sin2[i], sincos[i], mode, p[P_R])
        if meso:
            ddl1 = ddl2 = 0.0
            if tangent:  # cell_dl is linear in the strain: its derivative along u is cell_dl(u)
                ddl1, ddl2 = cell_dl(values, i, u[0], u[1], u[2], cos2[i], sin2[i], sincos[i], mode,
                                     p[P_R])
            ok &= meso_increment(values, i, dl1, dl2, p, resp, out, flags, tangent, ddl1, ddl2, dv)
            vnn, vtt = out[i, 8], out[i, 9]  # V sigma_nt = 0
            if tangent:
                b11, b22, b12 = weighted_global(dv[0], dv[1], wcos2[i], wsin2[i], wsincos[i])
                d11 += b11
                d22 += b22
                d12 += b12
        else:
            if law == LAW_COMPLIANCE:
                ok &= compliance_increment(values, i, dl1, dl2, resp, p, out, flags)
            else:
                ok &= cell_increment(values, i, dl1, dl2, p, out, flags, 0, 0)
            vnn, vtt = vsigma_local(out, i, kn, two_r)
        a11, a22, a12 = weighted_global(vnn, vtt, wcos2[i], wsin2[i], wsincos[i])
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
    cos2, sin2, sincos, wcos2, wsin2, wsincos = geo[0], geo[1], geo[2], geo[3], geo[4], geo[5]
    e11, e22, e12 = deps[0], deps[1], deps[2]
    D[:, :] = 0.0
    ok = True
    for i in range(values.shape[0]):
        dl1, dl2 = cell_dl(values, i, e11, e22, e12, cos2[i], sin2[i], sincos[i], mode, p[P_R])
        good, j11, j12, j21, j22 = cell_jacobian(
            values[i, 0], values[i, 1], values[i, 2], values[i, 3], values[i, 4], values[i, 5],
            values[i, 6], values[i, 7], dl1, dl2, p)
        ok &= good
        for j in range(3):
            u1, u2 = cell_dl(values, i, 1.0 if j == 0 else 0.0, 1.0 if j == 1 else 0.0,
                             1.0 if j == 2 else 0.0, cos2[i], sin2[i], sincos[i], mode, p[P_R])
            b11, b22, b12 = weighted_global(j11 * u1 + j12 * u2, j21 * u1 + j22 * u2, wcos2[i],
                                            wsin2[i], wsincos[i])
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


@njit(cache=True, error_model="numpy")
def any_trial(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp):
    """The REV trial of n = eps.shape[0] components: :func:`trial` (2D, n = 3) or the 3D REV's
    :func:`~hmodel.rev.kernels3d.bihex_trial` (n = 6, closed form, ``resp`` unused)."""
    if eps.shape[0] == 6:
        return bihex_trial(values, eps, deps, geo, p, mode, volume0, out, flags, sig)
    return trial(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp)


@njit(cache=True, error_model="numpy")
def fd_tangent(values, eps, x, geo, p, mode, volume0, h, out, flags, K, resp):
    """K[i, j] = dsig_i / dx_j (n x n) by forward differences at trial increment x (n,): n + 1
    trials."""
    n = x.shape[0]
    sig0 = np.empty(n)
    sig1 = np.empty(n)
    xp = x.copy()
    any_trial(values, eps, xp, geo, p, mode, volume0, out, flags, sig0, resp)
    for j in range(n):
        xp[:] = x
        xp[j] += h
        any_trial(values, eps, xp, geo, p, mode, volume0, out, flags, sig1, resp)
        for i in range(n):
            K[i, j] = (sig1[i] - sig0[i]) / h


@njit(cache=True, error_model="numpy")
def _slope_trial(values, eps, x, geo, p, mode, volume0, out, flags, sig, resp, exact, u, K):
    """:func:`any_trial`; with ``exact`` (a 2D meso surrogate), also the stress slope du along
    u, set into K: K u = du, K unchanged on directions normal to u (a rank-one update)."""
    if not exact:
        return any_trial(values, eps, x, geo, p, mode, volume0, out, flags, sig, resp)
    du = np.empty(3)
    ok = trial_tangent(values, eps, x, geo, p, mode, volume0, out, flags, sig, resp, u, du)
    uu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2]
    for a in range(3):
        c = (du[a] - (K[a, 0] * u[0] + K[a, 1] * u[1] + K[a, 2] * u[2])) / uu
        for j in range(3):
            K[a, j] += c * u[j]
    return ok


@njit(cache=True, inline="always", error_model="numpy")
def _cell_broken(flags, i):
    """Whether cell i with flags ``flags[i]`` (five per hexagon: one H-cell, or a bi-hexagon's
    two and its own) has a contact open in some hexagon (``CellFlags.broken``); indexed in
    place, no row view."""
    out = False
    for h in range(flags.shape[1] // 5):
        out = out or flags[i, 5 * h + 1] or flags[i, 5 * h + 2]
    return out


@njit(cache=True, error_model="numpy")
def _same_events(flags_a, flags_b):
    """Whether the same cells are broken (a contact open) in two trials."""
    for i in range(flags_a.shape[0]):
        if _cell_broken(flags_a, i) != _cell_broken(flags_b, i):
            return False
    return True


@njit(cache=True, error_model="numpy")
def _broken(flags):
    n = 0
    for i in range(flags.shape[0]):
        n += _cell_broken(flags, i)
    return n


@njit(cache=True, error_model="numpy")
def _newton_point(values, eps, sig, K, has_K, S, M, v, geo, p, mode, volume0, c, buf, bufflags,
                  W, resp, guess, trials):
    """The one Newton (:mod:`hmodel.loading.newton`) of one point, its trials evaluated here.

    Returns (outcome, cur, best): ``CONVERGED`` with the solution in ``buf[cur]`` (strain
    increment and stress in ``W[X]``, ``W[SIG]``); ``STALLED`` with the event state in
    ``buf[best]`` (``W[BX]``, ``W[BSIG]``); or a failure. Slots 0-2 of ``buf`` hold the current,
    the best and the next trial (indices, not copies).
    """
    # Meso cells with one stress row: each trial also gives the stress derivative along the
    # strain direction u left free by the strain rows (exact within the cells' regimes)
    u = free_direction(S, M) if resp.shape[1] > 0 and p[P_LAW] == LAW_MESO else np.zeros(0)
    exact = u.shape[0] > 0
    flag = np.zeros(1, dtype=np.bool_)
    n = S.shape[0]
    sig_n = np.empty(n)
    cur = -1
    best = -1
    act = begin(W, K, has_K, S, M, v, sig, c, guess, exact)
    while True:
        nxt = 0  # a slot that is neither the current nor the best trial
        while nxt == cur or nxt == best:
            nxt += 1
        if act == ASK_TANGENT:
            fd_tangent(values, eps, block(W, XN, n).copy(), geo, p, mode, volume0, c[C_FD], buf[nxt],
                       bufflags[nxt], K, resp)
            trials[0] += n + 1
            act = told_tangent(W, K, has_K, S, M, c)
        elif act == ASK_SLOPE:
            _slope_trial(values, eps, block(W, XN, n).copy(), geo, p, mode, volume0, buf[nxt],
                         bufflags[nxt], sig_n, resp, True, u, K)
            trials[0] += 1
            act = told_tangent(W, K, has_K, S, M, c)
        elif act == ASK_TRIAL:
            trials[0] += 1
            ok = _slope_trial(values, eps, block(W, XN, n).copy(), geo, p, mode, volume0, buf[nxt],
                              bufflags[nxt], sig_n, resp, exact, u, K)
            same = cur >= 0 and _same_events(bufflags[nxt], bufflags[cur])
            act = told_trial(W, K, S, M, c, sig_n, ok, _broken(bufflags[nxt]), same, exact, flag)
            cur = nxt
            if flag[0]:
                best = nxt
        else:
            return act, cur, best


@njit(cache=True, error_model="numpy")
def solve_point(values, flags, eps, sig, K, has_K, S, M, v, geo, p, mode, volume0, c, max_events,
                 buf, bufflags, resp, guess, trials):
    """One mixed-control increment of one material point, its state updated in place.

    The event loop of :func:`hmodel.loading.newton.after_newton`, as in
    ``control.solve_increment``: when Newton stalls inside the jump of a cell event, the event
    state is committed and the rest of the increment solved from there
    (:func:`~hmodel.loading.newton.event_targets`). Returns OK, or NOT_CONVERGED with the state
    restored to its start (slot 3 of ``buf`` keeps it).
    """
    n = S.shape[0]
    W = np.empty(workspace_size(n))
    target = v.copy()
    eps0 = eps.copy()
    sig0 = sig.copy()
    event = 0
    while True:
        act, cur, best = _newton_point(values, eps, sig, K, has_K, S, M, target, geo, p, mode,
                                       volume0, c, buf, bufflags, W, resp,
                                       guess if event == 0 else guess[:0], trials)
        then = after_newton(act, event, max_events)
        if then != COMMIT_SOLUTION and then != COMMIT_EVENT:
            break
        if event == 0 and then == COMMIT_EVENT:  # keep the start state, to restore it on failure
            buf[3] = values
            bufflags[3] = flags
        done = then == COMMIT_SOLUTION
        slot, at = (cur, X) if done else (best, BX)
        values[:] = buf[slot]
        flags[:] = bufflags[slot]
        eps += block(W, at, n)
        sig[:] = block(W, SIG if done else BSIG, n)
        if done:
            if S.any():  # a pure strain increment had no Newton: nothing to start the next one
                for j in range(guess.shape[0]):
                    guess[j] = eps[j] - eps0[j]
            return OK
        event_targets(S, target)
        event += 1
    if event > 0:
        values[:] = buf[3]
        flags[:] = bufflags[3]
    eps[:] = eps0
    sig[:] = sig0
    return NOT_CONVERGED


@njit(cache=True, error_model="numpy")
def _record(row, eps, sig, flags):
    """A record row (2m + 4): eps (m), sig (m) and the fractions of hexagons sliding, broken,
    with contact 1-4 (shared by a bi-hexagon's hexagons: counted once per cell) and 2-6 of one
    point's ``flags`` (n, 5 per hexagon), as ``RevState.fractions``."""
    n = flags.shape[0]
    m = eps.shape[0]
    nh = flags.shape[1] // 5
    row[:m] = eps
    row[m:2 * m] = sig
    slid = 0.0
    brk = 0.0
    c14 = 0.0
    c26 = 0.0
    for i in range(n):
        c14 += flags[i, 3]
        for h in range(nh):
            slid += flags[i, 5 * h]
            brk += flags[i, 5 * h + 1] or flags[i, 5 * h + 2]
            c26 += flags[i, 5 * h + 4]
    row[2 * m] = slid / (n * nh)
    row[2 * m + 1] = brk / (n * nh)
    row[2 * m + 2] = c14 / n
    row[2 * m + 3] = c26 / (n * nh)


@njit(cache=True, inline="always")
def _geo_row(geo, k):
    """The row of ``geo`` (K or 1, ...) for parameter set k."""
    return k if geo.shape[0] > 1 else 0


def _steps(values, flags, eps, sig, K, has_K, S, M, start, end, n_steps, k_from, k_end,
           geo, p, mode, volume0, c, max_events, rec, k_rec, stop, resp, guess, trials, sets,
           dropped):
    """Increments k_from[b]..k_end-1 (1-based k of n_steps) of a segment for each of B material
    points of m components (3 or 6).

    Each point runs its increments on its own and stops at the first it fails:
    ``stop[b]`` is that increment (the point's state is the one before it), or k_end when all
    went through. ``rec[k - k_rec, b]`` receives eps (m), sig (m) and the cell fractions
    sliding, broken, contact14, contact26. Point b runs with parameter set ``sets[b]``: its
    rows of ``geo`` (K, ...; one row shared by all sets where the geometry does not depend on
    the set, as in 3D), ``p`` (K, P) and ``volume0`` (K,). The points are independent:
    compiled with ``parallel=True`` (:data:`_run_steps_parallel`) they run on all cores, each
    through all its increments (a point that needs more Newton trials than the others then
    holds up no increment of theirs). A ``dropped`` point (a failed one the caller chose to go
    on without) is left as it is, its records NaN.
    """
    B, n = values.shape[0], values.shape[1]
    for b in prange(B):
        stop[b] = k_end
        if dropped[b]:
            for k in range(k_from[b], k_end):
                rec[k - k_rec, b, :] = np.nan
            continue
        if k_from[b] >= k_end:
            continue
        buf = np.empty((4, n, values.shape[2]))
        bufflags = np.empty((4, n, flags.shape[2]), dtype=np.bool_)
        v = np.empty(S.shape[0])
        # The point's cells copied to arrays of this thread: views into the shared arrays, made
        # per cell in the trials, would all count references on the shared arrays' one counter,
        # which the threads would then take turns to update. The trials index the geometry and
        # parameters in place (no per-cell views), so those are not copied: in 3D the geometry
        # is one (cells, 36) block shared by every point.
        vals = values[b].copy()
        flg = flags[b].copy()
        gb, pb, rb = geo[_geo_row(geo, sets[b])], p[sets[b]], resp[b].copy()
        for k in range(k_from[b], k_end):
            segment_targets(S, start[b], end[b], k, n_steps, v)
            if solve_point(vals, flg, eps[b], sig[b], K[b], has_K[b:b + 1], S, M, v, gb, pb, mode,
                           volume0[sets[b]], c, max_events, buf, bufflags, rb, guess[b],
                           trials[b:b + 1]) != OK:
                stop[b] = k  # solve_point restored the state before increment k
                break
            _record(rec[k - k_rec, b], eps[b], sig[b], flg)
        values[b] = vals
        flags[b] = flg


def _iso_steps(values, flags, eps, sig, geo, p, mode, volume0, sets, step, p0, rec, done, failed,
               resp):
    """Up to ``rec.shape[0]`` isotropic strain increments (step on every normal component, no
    shear: (step, step, 0) in 2D, (step, step, step, 0, 0, 0) in 3D) of every point not
    ``done``, each committed while the mean stress stays below the point's ``p0``; the first
    that would reach it is not, and marks the point ``done``. ``rec[j, b]`` receives the state
    after the point's j-th committed increment (:func:`_record`), NaN where there is none.
    A point whose cell increment fails is marked ``failed`` (and done), its state unchanged.
    Learned responses ``resp`` (B, n, R > 0) belong to the states they were evaluated at: one
    increment per call then (the caller evaluates the network between calls)."""
    B = values.shape[0]
    for b in prange(B):
        rec[:, b, :] = np.nan
        if done[b]:
            continue
        vals = values[b].copy()  # thread-local copies, as in _steps
        flg = flags[b].copy()
        out = np.empty_like(vals)
        oflags = np.empty_like(flg)
        gk = geo[_geo_row(geo, sets[b])]  # indexed in place, not copied: as in _steps
        pk = p[sets[b]]
        rb = resp[b].copy()
        m = eps.shape[1]
        normal = 2 if m == 3 else 3
        x = np.zeros(m)
        x[:normal] = step
        e = eps[b].copy()
        sg = sig[b].copy()
        s = np.empty(m)
        for j in range(rec.shape[0]):
            if not any_trial(vals, e, x, gk, pk, mode, volume0[sets[b]], out, oflags, s, rb):
                failed[b] = True
                done[b] = True
                break
            if (0.5 * (s[0] + s[1]) if m == 3 else (s[0] + s[1] + s[2]) / 3.0) >= p0[b]:
                done[b] = True
                break
            vals[:] = out
            flg[:] = oflags
            e += x
            sg[:] = s
            _record(rec[j, b], e, sg, flg)
        values[b] = vals
        flags[b] = flg
        eps[b] = e
        sig[b] = sg


def _renamed(fn, name: str):
    """``fn`` as a function of another name. Numba's on-disk cache files are named after a
    function's qualified name and line, not its compile options: two dispatchers of one Python
    function (serial and parallel) share one cache entry, and whichever compiled first would be
    loaded by the other (the parallel kernel then ran on one thread)."""
    out = types.FunctionType(fn.__code__, fn.__globals__, name, fn.__defaults__, fn.__closure__)
    out.__qualname__ = name
    out.__doc__ = fn.__doc__
    return out


#: :func:`_steps` on one core, and on all cores for batches of several points (a thread team
#: costs more than it saves when there is one point).
_run_steps = njit(cache=True, error_model="numpy")(_steps)
_run_steps_parallel = njit(cache=True, parallel=True, error_model="numpy")(
    _renamed(_steps, "_steps_parallel"))
_run_iso_steps = njit(cache=True, parallel=True, error_model="numpy")(_iso_steps)


def isotropic_steps(rev: Rev, state: RevState, step: float, p0: np.ndarray, n_max: int,
                    failed: np.ndarray, inputs=batch_inputs) -> tuple[RevState, np.ndarray, np.ndarray]:
    """Up to ``n_max`` isotropic strain increments of ``step`` of every point whose mean
    stress is below its ``p0`` (B,), each stopping before the increment that would reach it
    (the compiled form of the loop in :func:`hmodel.loading.named_paths.consolidate`).

    Returns the new state, whether each point is done (reached p0 or failed; ``failed`` (B,)
    is updated in place) and the records (n, B, 2m + 4) of the committed increments (NaN where a
    point made none): n = n_max, or 1 for learned cells, whose responses are evaluated here for
    the states of this one increment. ``inputs(rev)``: the kernel's (geo, p)
    (:func:`batch_inputs` in 2D)."""
    values = np.array(state.cells.values, dtype=float, order="C")
    flags = np.array(state.flags.flags, dtype=np.bool_, order="C")
    eps = np.array(state.eps, dtype=float, order="C")
    sig = np.array(state.sig, dtype=float, order="C")
    geo, p = inputs(rev)
    done = np.ascontiguousarray(state.p >= p0) | failed
    resp = cell_responses(rev, values, state.sets)
    rec = np.empty((1 if rev.kernel.learned else n_max, state.n_points, 2 * state.n_components + 4))
    _run_iso_steps(values, flags, eps, sig, geo, p, rev.mode, rev.volumes0,
                   state.set_index.astype(np.int64), float(step), np.ascontiguousarray(p0, float),
                   rec, done, failed, resp)
    return RevState(CellState(values), CellFlags(flags), eps, sig, state.sets), done, rec


class CompiledSegment:
    """Runs the increments of one segment through :func:`_run_steps`, chunk by chunk.

    The state lives in arrays owned by this object; :meth:`state` returns it as a new
    :class:`RevState`. ``tangent`` is shared with the generic driver for handed-back increments.
    Written for n components; :meth:`inputs` packs the REV's kernel inputs (the 2D REV's here,
    the 3D REV's in :class:`hmodel.loading.compiled3d.CompiledSegment3D`).
    """

    #: (geo, p) of the kernel: per-set geometry rows and packed cell parameters
    inputs = staticmethod(batch_inputs)

    def __init__(self, rev: Rev, state: RevState, stress_rows, matrix, start, end, n_steps: int,
                 tangent: Tangent, settings: NewtonSettings = NewtonSettings(),
                 failures: dict | None = None):
        self.rev, self.n_steps, self.tangent, self.settings = rev, n_steps, tangent, settings
        #: states kept by a run (none: its records are all there is; see GenericSegment)
        self.states: list[RevState] = []
        #: with a dict, points that fail are dropped (point -> reason) instead of stopping all
        self.failures = failures
        self.dropped = np.array([b in (failures or {}) for b in range(state.n_points)], dtype=np.bool_)
        self.S = np.asarray(stress_rows, dtype=np.bool_)
        self.M = np.ascontiguousarray(matrix, dtype=float)
        self.start = np.ascontiguousarray(start, dtype=float)
        self.end = np.ascontiguousarray(end, dtype=float)
        self.values = np.array(state.cells.values, dtype=float, order="C")
        self.flags = np.array(state.flags.flags, dtype=np.bool_, order="C")
        self.eps = np.array(state.eps, dtype=float, order="C")
        self.sig = np.array(state.sig, dtype=float, order="C")
        B, n = state.n_points, state.n_components
        self.has_K = np.full(B, tangent.K is not None and tangent.K.shape[0] == B)
        self.K = tangent.K.copy() if self.has_K.all() else np.zeros((B, n, n))
        self.geo, self.p = self.inputs(rev)
        self.sets = state.set_index.astype(np.int64)
        self._sets = state.sets  # as the state had them (None: all the first set)
        self.meso = rev.kernel.learned
        # per point: the last increment's strain (Newton's first trial of the next one, where
        # the settings ask for it; NaN: none yet), and the trials made (calls of the cell
        # solver on its n_theta cells)
        self.guess = np.full((B, n if settings.previous_first else 0), np.nan)
        if settings.previous_first and tangent.previous is not None and tangent.previous.shape == (B, n):
            self.guess[:] = tangent.previous
        self.trials = np.zeros(B, dtype=np.int64)
        # the solver's own tolerance floor, as the generic driver takes it (``solve_increment``)
        self.c = settings.packed_for(rev.solver)

    def state(self) -> RevState:
        return RevState(CellState(self.values.copy()), CellFlags(self.flags.copy()),
                        self.eps.copy(), self.sig.copy(), self._sets)

    # Copies of everything :meth:`run` changes, so that a caller can go back to a state between
    # chunks and run the same increments again (a loading program stopping on a criterion
    # re-runs the chunk that crossed it up to the crossing: same increments, same results).
    _MUTABLE = ("values", "flags", "eps", "sig", "K", "has_K", "guess", "trials")

    def snapshot(self) -> dict:
        """Copies of the arrays that :meth:`run` changes (see :meth:`restore`)."""
        return {a: getattr(self, a).copy() for a in self._MUTABLE}

    def restore(self, snap: dict) -> None:
        """Go back to the state of a :meth:`snapshot` (the arrays are copied in place)."""
        for a in self._MUTABLE:
            getattr(self, a)[...] = snap[a]

    def run(self, k_begin: int, k_end: int) -> np.ndarray:
        """Increments k_begin..k_end-1; returns their records (k_end - k_begin, B, 2n + 4)."""
        B, n = self.eps.shape
        rec = np.empty((k_end - k_begin, B, 2 * n + 4))
        # A meso surrogate's responses belong to the states an increment starts from: one
        # increment per kernel call, the network evaluated between them for every cell at once.
        stride = 1 if self.meso else k_end - k_begin
        steps = _run_steps_parallel if B > 1 else _run_steps
        for k0 in range(k_begin, k_end, stride):
            k1 = min(k0 + stride, k_end)
            k_from = np.full(B, k0, dtype=np.int64)
            resp = cell_responses(self.rev, self.values, self._sets)
            while (k_from < k1).any():
                stop = np.empty(B, dtype=np.int64)
                steps(self.values, self.flags, self.eps, self.sig, self.K, self.has_K, self.S,
                      self.M, self.start, self.end, self.n_steps, k_from, k1, self.geo, self.p,
                      self.rev.mode, self.rev.volumes0, self.c, self.settings.max_events, rec,
                      k_begin, stop, resp, self.guess, self.trials, self.sets, self.dropped)
                failed = stop < k1
                for k in np.unique(stop[failed]):  # each failed increment to the generic driver
                    self._hand_back(int(k), stop == k, rec[k - k_begin])
                k_from = np.where(failed, stop + 1, k1)
        self.tangent.K = self.K.copy()
        if self.guess.shape[1]:
            self.tangent.previous = self.guess.copy()
        return rec

    def _hand_back(self, k: int, failed: np.ndarray, rec_row: np.ndarray) -> None:
        """Solve increment k of the failed points with the generic driver (event fallback); with
        a failure dict, the points it cannot solve either are dropped and the others solved."""
        idx = np.flatnonzero(failed)
        while True:
            try:
                return self._hand_back_points(k, idx, rec_row)
            except PointFailure as e:
                if self.failures is None:
                    raise
                points = e.drop_into(self.failures)
                self.dropped[points] = True
                rec_row[points] = np.nan
                idx = idx[~np.isin(idx, points)]
                if not len(idx):
                    return None

    def _hand_back_points(self, k: int, idx: np.ndarray, rec_row: np.ndarray) -> None:
        """Increment k of the points ``idx`` through ``solve_increment``."""
        sub = RevState(CellState(self.values[idx]), CellFlags(self.flags[idx]), self.eps[idx],
                       self.sig[idx], None if self._sets is None else self._sets[idx])
        control = Control.of_step(self.S, self.M, self.start[idx], self.end[idx], k, self.n_steps)
        tangent = Tangent(self.K[idx].copy() if self.has_K[idx].all() else None,
                          self.guess[idx].copy() if self.guess.shape[1] else None)
        try:
            out = solve_increment(self.rev, sub, control, tangent, self.settings)
        except PointFailure as e:  # name the failed points in this segment's batch
            raise e.renumber(idx)
        if self.guess.shape[1]:
            self.guess[idx] = tangent.previous
        self.values[idx], self.flags[idx] = out.cells.values, out.flags.flags
        self.eps[idx], self.sig[idx] = out.eps, out.sig
        self.K[idx], self.has_K[idx] = tangent.K, True
        n = out.n_components
        rec_row[idx, :n], rec_row[idx, n:2 * n] = out.eps, out.sig
        fr = out.fractions()
        rec_row[idx, 2 * n:] = np.stack([fr[c] for c in FRACTIONS], axis=1)
