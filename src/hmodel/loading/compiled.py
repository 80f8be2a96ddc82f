"""Compiled loading segments for the closed-form cell solver and meso surrogates (the fast path).

:func:`hmodel.loading.control.solve_increment` drives any cell solver from Python; each Newton
trial is a batched REV call, and for one material point at nθ = 360 the Python overhead
exceeds the cell computation many times over. When the REV runs the closed-form solver, a whole
segment instead runs in one Numba kernel: per increment and per material point, the same
Newton-Broyden iteration (tangent predictor, secant updates skipped across cell events,
finite-difference refresh on stalls, trust region), with localization (eq. 1.1), the cell
increment (eq. 1.7) and averaging (eq. 1.15) fused in one loop over directions.

A ``meso`` surrogate (``SurrogateSolver`` with a meso model) runs through the same kernel: its
network sees the state only, so each increment starts with one network evaluation of every cell
of every point (:func:`cell_responses`, which also checks the training domain), and every trial
of the increment applies that learned response in :func:`hmodel.cell.meso_kernel.meso_increment`.
Newton's first trial is then the point's previous increment (along a smooth path it is close
to the answer, so fewer trials are needed), and where one stress row is controlled each trial
also gives the exact stress slope along the free strain direction, in place of Broyden's secant;
the closed form keeps its tangent predictor and secant.

The kernel also has the generic driver's event fallback (a stress target inside the jump of a
cell event, see ``solve_increment``). An increment it still cannot converge is handed back to
the generic driver, which then either solves it or raises its error with the strain reached;
the kernel resumes after it. Results equal the generic path's to the Newton tolerance
(``tests/test_compiled.py``, ``tests/test_meso_compiled.py``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..cell.closed_form import P_KN, P_R, cell_increment
from ..cell.mesostress import vsigma_local
from ..cell.meso_kernel import meso_increment
from ..cell.state import CellFlags, CellState
from ..rev import Rev, RevState
from ..rev.kernels import cell_dl, weighted_global
from .control import MAX_TRIAL_STRAIN, STEP_MULTIPLE, Control, Tangent, solve_increment
from .result import FRACTIONS

# Kernel status per material point and increment.
OK, NOT_CONVERGED = 0, 1
#: The generic driver's bounds on a trial strain increment, for the kernels (``control.trial_cap``).
TRIAL_LIMITS = np.array([MAX_TRIAL_STRAIN, STEP_MULTIPLE])


def supports(rev: Rev) -> bool:
    """Whether ``rev`` can run compiled segments: its cell solver has a compiled increment
    (:meth:`hmodel.cell.CellSolver.kernel`)."""
    return rev.kernel is not None


def kernel_inputs(rev: Rev, k: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(geo, p) for :func:`_trial` of a point of parameter set k: the direction factors cos²,
    sin², sin·cos and their weighted versions (6, n_theta), and the solver kernel's packed
    parameters."""
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
    """Per-cell inputs of :func:`_trial` that depend on the cells' states (B, n_theta, n_fields)
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
def _trial(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp):
    """REV step of one material point: cells ``values`` (n, n_fields) -> ``out``, stress -> ``sig``.

    Same operations, in the same order, as ``Rev.localize``, the cell solver and ``Rev.stress``:
    the closed-form cell kernel, or with learned responses ``resp`` (n, R > 0) the meso
    surrogate's trial (``meso_kernel.meso_increment``). Returns False when a cell increment failed.
    """
    return _trial_core(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp, False,
                       deps, sig)


@njit(cache=True, error_model="numpy")
def _trial_tangent(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp, u, dsig):
    """:func:`_trial` of a meso surrogate that also gives ``dsig``, the derivative of the stress
    along the strain direction ``u`` (3,): exact within every cell's regime."""
    return _trial_core(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp, True, u,
                       dsig)


@njit(cache=True, inline="always", error_model="numpy")
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
    meso = resp.shape[1] > 0
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
            ok &= cell_increment(values[i], dl1, dl2, p, out[i], flags[i])
            vnn, vtt = vsigma_local(out[i], kn, two_r)
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
def _fd_tangent(values, eps, x, geo, p, mode, volume0, h, out, flags, K, resp):
    """K[i, j] = dsig_i / dx_j by forward differences at trial increment x."""
    sig0 = np.empty(3)
    sig1 = np.empty(3)
    xp = x.copy()
    _trial(values, eps, xp, geo, p, mode, volume0, out, flags, sig0, resp)
    for j in range(3):
        xp[:] = x
        xp[j] += h
        _trial(values, eps, xp, geo, p, mode, volume0, out, flags, sig1, resp)
        for i in range(3):
            K[i, j] = (sig1[i] - sig0[i]) / h


@njit(cache=True, error_model="numpy")
def _solve3(J, R):
    """J^-1 R by cofactors (a LAPACK call from Numba costs several times the few products of a
    3x3 system); None when J is singular."""
    c00 = J[1, 1] * J[2, 2] - J[1, 2] * J[2, 1]
    c01 = J[1, 2] * J[2, 0] - J[1, 0] * J[2, 2]
    c02 = J[1, 0] * J[2, 1] - J[1, 1] * J[2, 0]
    det = J[0, 0] * c00 + J[0, 1] * c01 + J[0, 2] * c02
    if det == 0.0 or not math.isfinite(det):
        return None
    x = np.empty(3)
    x[0] = (R[0] * c00 + R[1] * (J[0, 2] * J[2, 1] - J[0, 1] * J[2, 2])
            + R[2] * (J[0, 1] * J[1, 2] - J[0, 2] * J[1, 1])) / det
    x[1] = (R[0] * c01 + R[1] * (J[0, 0] * J[2, 2] - J[0, 2] * J[2, 0])
            + R[2] * (J[0, 2] * J[1, 0] - J[0, 0] * J[1, 2])) / det
    x[2] = (R[0] * c02 + R[1] * (J[0, 1] * J[2, 0] - J[0, 0] * J[2, 1])
            + R[2] * (J[0, 0] * J[1, 1] - J[0, 1] * J[1, 0])) / det
    return x


@njit(cache=True, error_model="numpy")
def _newton_step(x, R, K, S, M):
    """x - J^-1 R with J = M, stress rows replaced by M[r] K; returns (x_new, solvable)."""
    J = M.copy()
    for r in range(3):
        if S[r]:
            for j in range(3):
                J[r, j] = M[r, 0] * K[0, j] + M[r, 1] * K[1, j] + M[r, 2] * K[2, j]
    d = _solve3(J, R)
    if d is None:
        return x.copy(), False
    return x - d, True


@njit(cache=True, error_model="numpy")
def _free_direction(S, M):
    """The strain direction (3,) the strain rows of M leave free when exactly one row is a
    stress row (their cross product); empty otherwise."""
    rows = np.empty(2, dtype=np.int64)
    n = 0
    for r in range(3):
        if not S[r]:
            if n == 2:
                return np.zeros(0)
            rows[n] = r
            n += 1
    if n != 2:
        return np.zeros(0)
    a, b = M[rows[0]], M[rows[1]]
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@njit(cache=True, error_model="numpy")
def _slope_trial(values, eps, x, geo, p, mode, volume0, out, flags, sig, resp, exact, u, K):
    """:func:`_trial`; with ``exact``, also the stress slope du along u, set into K: K u = du,
    K unchanged on directions normal to u (a rank-one update)."""
    if not exact:
        return _trial(values, eps, x, geo, p, mode, volume0, out, flags, sig, resp)
    du = np.empty(3)
    ok = _trial_tangent(values, eps, x, geo, p, mode, volume0, out, flags, sig, resp, u, du)
    uu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2]
    for a in range(3):
        c = (du[a] - (K[a, 0] * u[0] + K[a, 1] * u[1] + K[a, 2] * u[2])) / uu
        for j in range(3):
            K[a, j] += c * u[j]
    return ok


@njit(cache=True, error_model="numpy")
def _same_events(flags_a, flags_b):
    """Whether the same cells are broken (a contact open) in two trials."""
    for i in range(flags_a.shape[0]):
        if (flags_a[i, 1] or flags_a[i, 2]) != (flags_b[i, 1] or flags_b[i, 2]):
            return False
    return True


@njit(cache=True, error_model="numpy")
def _residual(x, sig, S, M, v, R):
    for r in range(3):
        a = sig if S[r] else x
        R[r] = M[r, 0] * a[0] + M[r, 1] * a[1] + M[r, 2] * a[2] - v[r]


@njit(cache=True, error_model="numpy")
def _converged(R, S, scale, rtol):
    for r in range(3):
        if S[r] and abs(R[r]) > rtol * scale[r]:
            return False
    return True


@njit(cache=True, error_model="numpy")
def _broken(flags):
    n = 0
    for i in range(flags.shape[0]):
        n += flags[i, 1] or flags[i, 2]
    return n


@njit(cache=True, error_model="numpy")
def _bound(x, cap):
    """Scales x (3,) in place back onto the ball of radius cap if outside; whether it did."""
    nrm = math.sqrt(x[0] ** 2 + x[1] ** 2 + x[2] ** 2)
    if nrm <= cap:
        return False
    for j in range(3):
        x[j] *= cap / nrm
    return True


@njit(cache=True, error_model="numpy")
def _newton_point(values, eps, sig, K, has_K, S, M, v, geo, p, mode, volume0, rtol, max_iter,
                  h, buf, bufflags, x, sig_out, resp, guess, trials, limits):
    """Newton-Broyden on the stress rows of one point (mirrors ``control._newton``).

    Returns (converged, slot): ``buf[slot]``/``bufflags[slot]`` hold the solution, or, when
    Newton stalls, the trial with the most broken cells (the event state); ``x`` and
    ``sig_out`` receive its strain increment and stress. Slots 0-2 hold the current, the best
    and the next trial (indices, not copies). Returns slot -1 when a cell increment or the
    Jacobian fails, or when Newton stalled with every trial held at the strain cap
    (``limits`` = (MAX_TRIAL_STRAIN, STEP_MULTIPLE), see ``control.trial_cap``).
    """
    strain = 0.0
    for r in range(3):
        if not S[r]:
            strain += v[r] ** 2
    cap = max(limits[0], limits[1] * math.sqrt(strain))
    R = np.empty(3)
    sig_t = np.empty(3)
    sig_n = np.empty(3)
    smax = max(abs(sig[0]), abs(sig[1]), abs(sig[2]))
    scale = np.empty(3)
    for r in range(3):
        scale[r] = max(max(abs(v[r]), smax), 1.0)
    x[:] = 0.0
    # A meso surrogate with one stress row: each trial also gives the stress derivative along
    # the strain direction u left free by the strain rows, which replaces Broyden's secant along
    # u (the exact slope of the current regimes needs no secant updates to learn it: fewer trials
    # per drained increment, and the first tangent costs one trial)
    u = _free_direction(S, M) if resp.shape[1] > 0 else np.zeros(0)
    exact = u.shape[0] > 0
    if not has_K[0]:
        if exact:  # one trial at no strain, its slope along u
            K[:, :] = 0.0
            _slope_trial(values, eps, x, geo, p, mode, volume0, buf[1], bufflags[1], sig_t, resp,
                         True, u, K)
            trials[0] += 1
        else:
            _fd_tangent(values, eps, x, geo, p, mode, volume0, h, buf[1], bufflags[1], K, resp)
            trials[0] += 4
        has_K[0] = True
    _residual(x, sig, S, M, v, R)
    xt, ok = _newton_step(x, R, K, S, M)
    if not ok:
        return False, -1
    _bound(xt, cap)
    trust = 4.0 * max(math.sqrt(xt[0] ** 2 + xt[1] ** 2 + xt[2] ** 2), 1e-8)
    if guess.shape[0] and math.isfinite(guess[0]):
        # first trial: the last increment's strain, its strain rows moved to this increment's
        d = np.zeros(3)
        for r in range(3):
            if not S[r]:
                d[r] = v[r] - (M[r, 0] * guess[0] + M[r, 1] * guess[1] + M[r, 2] * guess[2])
        dg = _solve3(M, d)
        if dg is not None:
            xt = guess + dg
            trust = max(trust, 4.0 * math.sqrt(xt[0] ** 2 + xt[1] ** 2 + xt[2] ** 2))
    held = _bound(xt, cap)
    cur = 0
    trials[0] += 1
    if not _slope_trial(values, eps, xt, geo, p, mode, volume0, buf[cur], bufflags[cur], sig_t,
                        resp, exact, u, K):
        return False, -1
    _residual(xt, sig_t, S, M, v, R)
    best_key = 1e300
    best = cur
    for it in range(max_iter + 1):
        res = 0.0
        for r in range(3):
            if S[r]:
                res = max(res, abs(R[r]))
        key = -_broken(bufflags[cur]) + res / (1.0 + res)
        # the event fallback's candidate: most broken cells, then residual (a trial held at the
        # cap is none: a jump lies near the solution, not out there)
        if not held and key < best_key:
            best_key = key
            best = cur
            x[:] = xt
            sig_out[:] = sig_t
        if _converged(R, S, scale, rtol):
            x[:] = xt
            sig_out[:] = sig_t
            return True, cur
        if it == max_iter:
            break
        nxt = 0  # the next trial's slot: neither the current nor the best one
        while nxt == cur or nxt == best:
            nxt += 1
        if it == max_iter // 3:  # stalled: fresh finite-difference tangent at the current trial
            _fd_tangent(values, eps, xt, geo, p, mode, volume0, h, buf[nxt], bufflags[nxt], K,
                        resp)
            trials[0] += 4
        x_new, ok = _newton_step(xt, R, K, S, M)
        if not ok:
            return False, -1
        dx = x_new - xt
        nrm = math.sqrt(dx[0] ** 2 + dx[1] ** 2 + dx[2] ** 2)
        if nrm > trust:  # trust region: a correction never exceeds a few predictor increments
            dx *= trust / nrm
        x_new = xt + dx
        held = _bound(x_new, cap)
        dx = x_new - xt
        trials[0] += 1
        if not _slope_trial(values, eps, xt + dx, geo, p, mode, volume0, buf[nxt], bufflags[nxt],
                            sig_n, resp, exact, u, K):
            return False, -1
        # Broyden's rank-one secant update, skipped where the slope is exact and across a cell
        # event (a jump).
        dd = dx[0] ** 2 + dx[1] ** 2 + dx[2] ** 2
        if not exact and dd > 0.0 and _same_events(bufflags[nxt], bufflags[cur]):
            for a in range(3):
                upd = sig_n[a] - sig_t[a] - (K[a, 0] * dx[0] + K[a, 1] * dx[1] + K[a, 2] * dx[2])
                for j in range(3):
                    K[a, j] += upd * dx[j] / dd
        xt = xt + dx
        sig_t[:] = sig_n
        cur = nxt
        _residual(xt, sig_t, S, M, v, R)
    return False, best if best_key < 1e300 else -1


@njit(cache=True, error_model="numpy")
def _solve_point(values, flags, eps, sig, K, has_K, S, M, v, geo, p, mode, volume0, rtol,
                 max_iter, max_events, h, buf, bufflags, resp, guess, trials, limits):
    """One mixed-control increment of one material point, its state updated in place.

    Mirrors ``control.solve_increment``: when Newton stalls inside the jump of a cell event,
    the event state is committed and the rest of the increment solved from there (strain rows
    met already), at most ``max_events`` times. Returns OK, or NOT_CONVERGED with the state
    restored to its start (slot 3 of ``buf`` keeps it).
    """
    x = np.empty(3)
    sig_new = np.empty(3)
    n_stress = 0
    for r in range(3):
        n_stress += S[r]
    if n_stress == 0:
        xs = _solve3(M, v)
        if xs is None:
            return NOT_CONVERGED
        x = xs
        trials[0] += 1
        if not _trial(values, eps, x, geo, p, mode, volume0, buf[0], bufflags[0], sig_new, resp):
            return NOT_CONVERGED
        values[:] = buf[0]
        flags[:] = bufflags[0]
        for j in range(3):
            eps[j] += x[j]
            sig[j] = sig_new[j]
        return OK
    target = v.copy()
    eps0 = eps.copy()
    sig0 = sig.copy()
    for event in range(max_events + 1):
        done, slot = _newton_point(values, eps, sig, K, has_K, S, M, target, geo, p, mode,
                                   volume0, rtol, max_iter, h, buf, bufflags, x, sig_new, resp,
                                   guess if event == 0 else guess[:0], trials, limits)
        if slot < 0 or (not done and event == max_events):
            break
        if event == 0 and not done:  # keep the start state, to restore it on failure
            buf[3] = values
            bufflags[3] = flags
        values[:] = buf[slot]
        flags[:] = bufflags[slot]
        for j in range(3):
            eps[j] += x[j]
            sig[j] = sig_new[j]
        if done:
            for j in range(guess.shape[0]):
                guess[j] = eps[j] - eps0[j]
            return OK
        for r in range(3):  # past the event: strain rows are met, stress targets unchanged
            if not S[r]:
                target[r] = 0.0
    if event > 0:
        values[:] = buf[3]
        flags[:] = bufflags[3]
    eps[:] = eps0
    sig[:] = sig0
    return NOT_CONVERGED


@njit(cache=True, error_model="numpy")
def _run_steps(values, flags, eps, sig, K, has_K, S, M, start, end, n_steps, k_begin, k_end,
               geo, p, mode, volume0, rtol, max_iter, max_events, h, rec, status, resp, guess, trials,
               limits, sets):
    """Increments k_begin..k_end-1 (1-based k of n_steps) of a segment for B material points.

    Stops after the first increment where a point fails (``status[b] != OK``) and returns its
    k; returns k_end when all went through. ``rec[k - k_begin, b]`` receives eps (3), sig (3)
    and the cell fractions sliding, broken, contact14, contact26. Point b runs with parameter
    set ``sets[b]``: its rows of ``geo`` (K, 6, n_theta), ``p`` (K, P) and ``volume0`` (K,).
    """
    B, n = values.shape[0], values.shape[1]
    buf = np.empty((4, n, values.shape[2]))
    bufflags = np.empty((4, n, 5), dtype=np.bool_)
    v = np.empty(3)
    for k in range(k_begin, k_end):
        failed = False
        for b in range(B):
            for r in range(3):
                if S[r]:
                    v[r] = start[b, r] + (end[b, r] - start[b, r]) * (k / n_steps)
                else:
                    v[r] = end[b, r] / n_steps
            status[b] = _solve_point(values[b], flags[b], eps[b], sig[b], K[b], has_K[b:b + 1],
                                     S, M, v, geo[sets[b]], p[sets[b]], mode, volume0[sets[b]],
                                     rtol, max_iter, max_events,
                                     h, buf, bufflags, resp[b], guess[b], trials[b:b + 1], limits)
            failed |= status[b] != OK
            row = rec[k - k_begin, b]
            row[:3] = eps[b]
            row[3:6] = sig[b]
            slid = 0.0
            brk = 0.0
            c14 = 0.0
            c26 = 0.0
            for i in range(n):
                f = flags[b, i]
                slid += f[0]
                brk += f[1] or f[2]
                c14 += f[3]
                c26 += f[4]
            row[6] = slid / n
            row[7] = brk / n
            row[8] = c14 / n
            row[9] = c26 / n
        if failed:
            return k
    return k_end


class CompiledSegment:
    """Runs the increments of one segment through :func:`_run_steps`, chunk by chunk.

    The state lives in arrays owned by this object; :meth:`state` returns it as a new
    :class:`RevState`. ``tangent`` is shared with the generic driver for handed-back increments.
    """

    def __init__(self, rev: Rev, state: RevState, stress_rows, matrix, start, end, n_steps: int,
                 tangent: Tangent, rtol: float = 1e-10, max_iter: int = 24,
                 max_events: int = 6):
        self.rev, self.n_steps, self.tangent = rev, n_steps, tangent
        self.S = np.asarray(stress_rows, dtype=np.bool_)
        self.M = np.ascontiguousarray(matrix, dtype=float)
        self.start = np.ascontiguousarray(start, dtype=float)
        self.end = np.ascontiguousarray(end, dtype=float)
        self.values = np.array(state.cells.values, dtype=float, order="C")
        self.flags = np.array(state.flags.flags, dtype=np.bool_, order="C")
        self.eps = np.array(state.eps, dtype=float, order="C")
        self.sig = np.array(state.sig, dtype=float, order="C")
        B = state.n_points
        self.has_K = np.full(B, tangent.K is not None and tangent.K.shape[0] == B)
        self.K = tangent.K.copy() if self.has_K.all() else np.zeros((B, 3, 3))
        self.geo, self.p = batch_inputs(rev)
        self.sets = state.set_index.astype(np.int64)
        self._sets = state.sets  # as the state had them (None: all the first set)
        self.meso = rev.kernel.learned
        # per point: the last increment's strain, Newton's first trial of the next one (meso
        # surrogates: close to the answer along a smooth path; the closed form keeps its
        # tangent predictor, whose results the generic driver reproduces to 1e-7 where cell
        # events jump), and the trials made (calls of the cell solver on its n_theta cells)
        self.guess = np.full((B, 3 if self.meso else 0), np.nan)
        self.trials = np.zeros(B, dtype=np.int64)
        # the solver's own floor, as the generic driver takes it (``solve_increment``): a meso
        # surrogate converged to 1e-10 here, not 1e-7, with 4.84 against ~4.0 trials per
        # drained increment
        rtol = max(rtol, float(rev.solver.stress_rtol))
        self.rtol, self.max_iter, self.max_events = rtol, max_iter, max_events

    def state(self) -> RevState:
        return RevState(CellState(self.values.copy()), CellFlags(self.flags.copy()),
                        self.eps.copy(), self.sig.copy(), self._sets)

    def run(self, k_begin: int, k_end: int) -> np.ndarray:
        """Increments k_begin..k_end-1; returns their records (k_end - k_begin, B, 10)."""
        B = self.eps.shape[0]
        rec = np.empty((k_end - k_begin, B, 10))
        status = np.zeros(B, dtype=np.int64)
        # A meso surrogate's responses belong to the states an increment starts from: one
        # increment per kernel call, the network evaluated between them for every cell at once.
        stride = 1 if self.meso else k_end - k_begin
        k = k_begin
        while k < k_end:
            resp = cell_responses(self.rev, self.values, self._sets)
            end = min(k + stride, k_end)
            k = _run_steps(self.values, self.flags, self.eps, self.sig, self.K, self.has_K,
                           self.S, self.M, self.start, self.end, self.n_steps, k, end, self.geo,
                           self.p, self.rev.mode, self.rev.volumes0, self.rtol, self.max_iter,
                           self.max_events, self.tangent.fd_step, rec[k - k_begin:], status, resp,
                           self.guess, self.trials, TRIAL_LIMITS, self.sets)
            if k < end:  # increment k failed for some points
                self._hand_back(k, status != OK, rec[k - k_begin])
                status[:] = OK
                k += 1
        self.tangent.K = self.K.copy()
        return rec

    def _hand_back(self, k: int, failed: np.ndarray, rec_row: np.ndarray) -> None:
        """Solve increment k of the failed points with the generic driver (event fallback)."""
        idx = np.flatnonzero(failed)
        sub = RevState(CellState(self.values[idx]), CellFlags(self.flags[idx]), self.eps[idx],
                       self.sig[idx], None if self._sets is None else self._sets[idx])
        values = np.where(self.S, self.start[idx] + (self.end[idx] - self.start[idx])
                          * (k / self.n_steps), self.end[idx] / self.n_steps)
        tangent = Tangent(self.K[idx].copy() if self.has_K[idx].all() else None, self.tangent.fd_step)
        out = solve_increment(self.rev, sub, Control(self.S, self.M, values), tangent,
                              rtol=self.rtol, max_iter=self.max_iter, max_events=self.max_events)
        self.values[idx], self.flags[idx] = out.cells.values, out.flags.flags
        self.eps[idx], self.sig[idx] = out.eps, out.sig
        self.K[idx], self.has_K[idx] = tangent.K, True
        rec_row[idx, :3], rec_row[idx, 3:6] = out.eps, out.sig
        fr = out.fractions()
        rec_row[idx, 6:] = np.stack([fr[c] for c in FRACTIONS], axis=1)
