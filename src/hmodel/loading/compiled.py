"""Compiled loading segments for every cell solver with a compiled increment (the fast path).

:func:`hmodel.loading.control.solve_increment` drives any cell solver from Python; each round
of Newton trials is a batched REV call, and for one material point at nθ = 360 the Python
overhead exceeds the cell computation many times over. When the cell solver has a compiled
increment (:meth:`hmodel.cell.CellSolver.kernel`: the closed form, a ``meso`` or ``compliance``
surrogate), a whole segment instead runs in one Numba kernel: per increment and per material
point, the one Newton of :mod:`hmodel.loading.newton`, its trials evaluated here with
localization (eq. 1.1), the cell increment and averaging (eq. 1.15) fused in one loop over
directions: the REV's own trial (:func:`hmodel.rev.trial.point_trial`), on the REV's kernel
inputs (:meth:`hmodel.rev.batch.RevBatch.kernel_inputs`).

The kernels are written for n components and never ask which REV runs: the REV's kernel inputs
(one row of geometry per cell, each set's packed cell parameters) say which trial applies, the
2D REV's H-cells (:func:`hmodel.rev.kernels.trial`) or the 3D REV's bi-hexagons
(:func:`hmodel.rev.kernels3d.bihex_trial`); Newton, the event loop, the batched per-point kernel
and the hand-back to the generic driver are the same code.

A learned cell response (``meso`` and ``compliance`` surrogates) sees the state only, so each
increment starts with one evaluation of every cell of every point (:func:`cell_responses`,
which may refuse cells outside a training domain), and every trial of the increment applies
that response, in :func:`hmodel.cell.meso_kernel.meso_increment` or
:func:`hmodel.cell.compliance_kernel.compliance_increment` (the law packed in the kernel's
parameters). Where one stress row is controlled, each trial of a meso response also gives the
exact stress slope along the free strain direction (:func:`hmodel.rev.kernels.trial_tangent`), in place of
Broyden's secant there.

The kernel has the generic driver's event fallback (a stress target inside the jump of a cell
event, see ``solve_increment``), with its second count of broken hexagons for bi-hexagons
(:func:`solve_point`). An increment it still cannot converge is handed back to the
generic driver, which then either solves it or raises its error with the strain reached; the
kernel resumes after it. Results equal the generic path's to the Newton tolerance
(``tests/test_compiled.py``, ``tests/test_meso_compiled.py``).
"""

from __future__ import annotations

import types

import numpy as np
from numba import njit, prange

from ..cell.base import LAW_MESO, P_LAW
from ..cell.state import CellFlags, CellState
from ..errors import PointFailure, SolverError
from ..rev import Rev, RevState
from ..rev.kernels import closed_form_tangent, prepare, trial, trial_tangent  # noqa: F401 (their face here)
from ..rev.state import normal_components
from ..rev.trial import point_prepared, point_trial, point_trial_prepared
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
    solve,
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
    """(geo, p) of the compiled trial of a point of parameter set k: its rows of the REV's
    kernel inputs (:meth:`~hmodel.rev.batch.RevBatch.kernel_inputs`), geometry (C, width) and
    packed cell parameters (P,)."""
    geo, p = rev.kernel_inputs()
    return geo[k if len(geo) > 1 else 0], p[k]


def batch_inputs(rev: Rev) -> tuple[np.ndarray, np.ndarray]:
    """The REV's kernel inputs: geometry rows (K or 1, C, width) and parameters (K, P)."""
    return rev.kernel_inputs()


#: The trial of a point of either REV (:func:`hmodel.rev.trial.point_trial`).
any_trial = point_trial


def cell_responses(rev: Rev, values: np.ndarray, sets: np.ndarray | None = None) -> np.ndarray:
    """Per-cell inputs of the trial that depend on the cells' states (B, n_theta, n_fields)
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
def fd_tangent(values, eps, x, geo, p, mode, volume0, h, out, flags, K, resp, pre):
    """K[i, j] = dsig_i / dx_j (n x n) by forward differences at trial increment x (n,): n + 1
    trials (``pre``: :func:`~hmodel.rev.trial.point_prepared` of ``values``)."""
    n = x.shape[0]
    sig0 = np.empty(n)
    sig1 = np.empty(n)
    xp = x.copy()
    point_trial_prepared(values, eps, xp, geo, p, mode, volume0, out, flags, sig0, resp, pre)
    for j in range(n):
        xp[:] = x
        xp[j] += h
        point_trial_prepared(values, eps, xp, geo, p, mode, volume0, out, flags, sig1, resp, pre)
        for i in range(n):
            K[i, j] = (sig1[i] - sig0[i]) / h


@njit(cache=True, error_model="numpy")
def _slope_trial(values, eps, x, geo, p, mode, volume0, out, flags, sig, resp, pre, exact, u, K):
    """:func:`~hmodel.rev.trial.point_trial_prepared`; with ``exact`` (a 2D meso surrogate),
    also the stress slope du along u, set into K: K u = du, K unchanged on directions normal to
    u (a rank-one update)."""
    if not exact:
        return point_trial_prepared(values, eps, x, geo, p, mode, volume0, out, flags, sig, resp, pre)
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
def _broken(flags, by_hexagon):
    """The broken cells of a trial (``CellFlags.broken``), or with ``by_hexagon`` its hexagons
    with a contact open (``CellFlags.open_hexagons``): the event fallback's count."""
    n = 0
    if not by_hexagon:
        for i in range(flags.shape[0]):
            n += _cell_broken(flags, i)
        return n
    for i in range(flags.shape[0]):
        for h in range(flags.shape[1] // 5):
            n += flags[i, 5 * h + 1] or flags[i, 5 * h + 2]
    return n


@njit(cache=True, error_model="numpy")
def _newton_point(values, eps, sig, K, has_K, S, M, v, geo, p, mode, volume0, c, buf, bufflags,
                  W, resp, pre, guess, trials, by_hexagon):
    """The one Newton (:mod:`hmodel.loading.newton`) of one point, its trials evaluated here;
    its event fallback counts broken cells, or with ``by_hexagon`` open hexagons (:func:`_broken`).

    Returns (outcome, cur, best): ``CONVERGED`` with the solution in ``buf[cur]`` (strain
    increment and stress in ``W[X]``, ``W[SIG]``); ``STALLED`` with the event state in
    ``buf[best]`` (``W[BX]``, ``W[BSIG]``); or a failure. Slots 0-2 of ``buf`` hold the current,
    the best and the next trial (indices, not copies).
    """
    # Meso cells with one stress row: each trial also gives the stress derivative along the
    # strain direction u left free by the strain rows (exact within the cells' regimes)
    u = free_direction(S, M) if resp.shape[1] > 0 and p[P_LAW] == LAW_MESO else np.zeros(0)
    # every trial of this Newton starts from ``values``: what they fix, once for all of them
    prepare(values, p, pre)
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
                       bufflags[nxt], K, resp, pre)
            trials[0] += n + 1
            act = told_tangent(W, K, has_K, S, M, c)
        elif act == ASK_SLOPE:
            _slope_trial(values, eps, block(W, XN, n).copy(), geo, p, mode, volume0, buf[nxt],
                         bufflags[nxt], sig_n, resp, pre, True, u, K)
            trials[0] += 1
            act = told_tangent(W, K, has_K, S, M, c)
        elif act == ASK_TRIAL:
            trials[0] += 1
            ok = _slope_trial(values, eps, block(W, XN, n).copy(), geo, p, mode, volume0, buf[nxt],
                              bufflags[nxt], sig_n, resp, pre, exact, u, K)
            same = cur >= 0 and _same_events(bufflags[nxt], bufflags[cur])
            act = told_trial(W, K, S, M, c, sig_n, ok, _broken(bufflags[nxt], by_hexagon), same, exact,
                             flag)
            cur = nxt
            if flag[0]:
                best = nxt
        else:
            return act, cur, best


@njit(cache=True, error_model="numpy")
def solve_point(values, flags, eps, sig, K, has_K, S, M, v, geo, p, mode, volume0, c, max_events,
                 buf, bufflags, resp, pre, guess, trials):
    """One mixed-control increment of one material point, its state updated in place.

    The event loop of :func:`hmodel.loading.newton.after_newton`, as in
    ``control.solve_increment``: when Newton stalls inside the jump of a cell event, the event
    state is committed and the rest of the increment solved from there
    (:func:`~hmodel.loading.newton.event_targets`). An increment of bi-hexagons given up so is
    solved once more from its start, its tangent too, with the fallback counting broken
    hexagons, as the generic driver does (``solve_increment(..., by_hexagon=True)``;
    docs/loading.md, "Cell events"). Returns OK, or NOT_CONVERGED with the state restored to its
    start (slot 3 of ``buf`` keeps the cells), and for bi-hexagons the tangent too: the driver
    then hands the increment to ``control.solve_increment``, which tries both counts again (H-cells
    keep the tangent the failed attempt left, with which the hand-back has solved increments
    before).
    """
    eps0 = eps.copy()
    sig0 = sig.copy()
    bihex = flags.shape[1] > 5
    K0 = K.copy()
    has_K0 = has_K.copy()
    # the second count only picks another event state to commit: none where none may be
    attempts = 2 if bihex and max_events > 0 else 1
    for attempt in range(attempts):
        outcome = _event_loop(values, flags, eps, sig, K, has_K, S, M, v, geo, p, mode, volume0, c,
                              max_events, buf, bufflags, resp, pre, guess, trials, attempt == 1)
        if outcome == OK:
            return OK
        if outcome == _GIVEN_UP_AFTER_EVENTS:  # cells committed: back to the start
            values[:] = buf[3]
            flags[:] = bufflags[3]
        eps[:] = eps0
        sig[:] = sig0
        if bihex:
            K[:] = K0
            has_K[:] = has_K0
    return NOT_CONVERGED


#: :func:`_event_loop` gave its increment up after committing a cell event (the cells moved).
_GIVEN_UP_AFTER_EVENTS = 2


@njit(cache=True, error_model="numpy")
def _event_loop(values, flags, eps, sig, K, has_K, S, M, v, geo, p, mode, volume0, c, max_events,
                buf, bufflags, resp, pre, guess, trials, by_hexagon):
    """:func:`solve_point`'s event loop with one count of the fallback: OK (the state updated in
    place), NOT_CONVERGED (given up before any event: the cells as they were) or
    :data:`_GIVEN_UP_AFTER_EVENTS` (slot 3 of ``buf`` keeps the cells of the start)."""
    n = S.shape[0]
    W = np.empty(workspace_size(n))
    target = v.copy()
    eps0 = eps.copy()
    event = 0
    while True:
        act, cur, best = _newton_point(values, eps, sig, K, has_K, S, M, target, geo, p, mode,
                                       volume0, c, buf, bufflags, W, resp, pre,
                                       guess if event == 0 else guess[:0], trials, by_hexagon)
        then = after_newton(act, event, max_events)
        if then != COMMIT_SOLUTION and then != COMMIT_EVENT:
            return _GIVEN_UP_AFTER_EVENTS if event > 0 else NOT_CONVERGED
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


@njit(cache=True, inline="always")
def _mean_normal(s, n_normal):
    """The mean of the first ``n_normal`` components of a stress ``s``: its mean stress p, as
    :func:`hmodel.rev.state.mean_stress` computes it."""
    t = 0.0
    for r in range(n_normal):
        t += s[r]
    return t / n_normal


@njit(cache=True, error_model="numpy")
def _known_increment(S, M, start, end, k, n_steps, v, x):
    """The strain increment ``x`` of increment k of a segment of strain rows only, M^-1 v, as
    Newton's one trial takes it (:func:`~hmodel.loading.newton.begin`); False where the rows
    are dependent (Newton then says so)."""
    segment_targets(S, start, end, k, n_steps, v)
    r = solve(M, v)
    if r is None:
        return False
    x[:] = r
    return True


def _steps(values, flags, eps, sig, K, has_K, S, M, start, end, n_steps, k_from, k_end,
           geo, p, mode, volume0, c, max_events, rec, k_rec, until, before, n_normal, met_at,
           stop, resp, guess, trials, sets, dropped):
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
    on without, or one a criterion ended) is left as it is, its records NaN.

    ``until`` (B,) (empty: none): a point also ends at the first increment k after which its
    mean stress (of its ``n_normal`` normal components) reaches ``until[b]``: ``met_at[b] = k``,
    the point's state that one (or, ``before``, the one before it, the increment undone), its
    later records NaN.
    """
    B, n = values.shape[0], values.shape[1]
    m = eps.shape[1]
    watch = until.shape[0] > 0
    strain_only = not S.any()
    save = watch and before and not strain_only
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
        # the state before each increment, where an increment that meets ``until`` is undone
        kept = np.empty((n if save else 0, values.shape[2]))
        kept_flags = np.empty((n if save else 0, flags.shape[2]), dtype=np.bool_)
        kept_eps, kept_sig, kept_K = np.empty(m), np.empty(m), np.empty((m, m))
        kept_guess = np.empty(guess.shape[1])
        kept_has = False
        # Strain rows only: every increment is the same known one, M^-1 v, and Newton's one
        # trial evaluates it; made here, it is checked against ``until`` before it is taken.
        x = np.empty(m)
        known = strain_only and _known_increment(S, M, start[b], end[b], k_from[b], n_steps, v, x)
        # the inputs of the trials that the committed cells fix (solve_point fills it again)
        pre = point_prepared(vals, gb, pb, rb)
        sig_n = np.empty(m)
        for k in range(k_from[b], k_end):
            if known:
                trials[b] += 1
                prepare(vals, pb, pre)
                if not point_trial_prepared(vals, eps[b], x, gb, pb, mode, volume0[sets[b]], buf[0],
                                            bufflags[0], sig_n, rb, pre):
                    stop[b] = k  # the state is the one before increment k
                    break
                met = watch and _mean_normal(sig_n, n_normal) >= until[b]
                if not (met and before):
                    vals[:] = buf[0]
                    flg[:] = bufflags[0]
                    eps[b] += x
                    sig[b, :] = sig_n
                    _record(rec[k - k_rec, b], eps[b], sig[b], flg)
                if met:
                    met_at[b] = k
                    for j in range(k if before else k + 1, k_end):
                        rec[j - k_rec, b, :] = np.nan
                    break
                continue
            segment_targets(S, start[b], end[b], k, n_steps, v)
            if save:
                kept[:] = vals
                kept_flags[:] = flg
                kept_eps[:] = eps[b]
                kept_sig[:] = sig[b]
                kept_K[:] = K[b]
                kept_guess[:] = guess[b]
                kept_has = has_K[b]
            if solve_point(vals, flg, eps[b], sig[b], K[b], has_K[b:b + 1], S, M, v, gb, pb, mode,
                           volume0[sets[b]], c, max_events, buf, bufflags, rb, pre, guess[b],
                           trials[b:b + 1]) != OK:
                stop[b] = k  # solve_point restored the state before increment k
                break
            if watch and _mean_normal(sig[b], n_normal) >= until[b]:
                met_at[b] = k
                if before:
                    vals[:] = kept
                    flg[:] = kept_flags
                    eps[b, :] = kept_eps
                    sig[b, :] = kept_sig
                    K[b, :, :] = kept_K
                    guess[b, :] = kept_guess
                    has_K[b] = kept_has
                else:
                    _record(rec[k - k_rec, b], eps[b], sig[b], flg)
                for j in range(k if before else k + 1, k_end):
                    rec[j - k_rec, b, :] = np.nan
                break
            _record(rec[k - k_rec, b], eps[b], sig[b], flg)
        values[b] = vals
        flags[b] = flg


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


class CompiledSegment:
    """Runs the increments of one segment through :func:`_run_steps`, chunk by chunk.

    The state lives in arrays owned by this object; :meth:`state` returns it as a new
    :class:`RevState`. ``tangent`` is shared with the generic driver for handed-back increments.
    Written for n components, on the REV's kernel inputs (2D or 3D alike).
    """

    def __init__(self, rev: Rev, state: RevState, stress_rows, matrix, start, end, n_steps: int,
                 tangent: Tangent, settings: NewtonSettings = NewtonSettings(),
                 failures: dict | None = None, until: np.ndarray | None = None,
                 before: bool = False):
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
        self.geo, self.p = rev.kernel_inputs()  # (geometry rows per set or shared, parameters)
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
        #: each point's mean stress at which the kernel ends it (empty: no such criterion;
        #: ``before``: on the state before the increment that reaches it), the increment that
        #: did (0: none yet) and the points a criterion ended, which take no more increments
        self.until = (np.empty(0) if until is None else
                      np.ascontiguousarray(np.broadcast_to(np.asarray(until, float), B)))
        self.before = bool(before)
        self.n_normal = normal_components(n)
        self.met_at = np.zeros(B, dtype=np.int64)
        self.frozen = np.zeros(B, dtype=np.bool_)

    @property
    def evaluates_stop(self) -> bool:
        """Whether the kernel itself ends points at a mean stress (``until``)."""
        return self.until.shape[0] > 0

    def freeze(self, points: np.ndarray) -> None:
        """The points of the mask (B,) take no more increments (a criterion ended them)."""
        self.frozen |= points

    def state(self) -> RevState:
        return RevState(CellState(self.values.copy()), CellFlags(self.flags.copy()),
                        self.eps.copy(), self.sig.copy(), self._sets)

    # Copies of everything :meth:`run` changes, so that a caller can go back to a state between
    # chunks and run the same increments again (a loading program stopping on a criterion
    # re-runs the chunk that crossed it up to the crossing: same increments, same results).
    _MUTABLE = ("values", "flags", "eps", "sig", "K", "has_K", "guess", "trials", "met_at", "frozen")

    def snapshot(self) -> dict:
        """Copies of the arrays that :meth:`run` changes (see :meth:`restore`)."""
        return {**{a: getattr(self, a).copy() for a in self._MUTABLE}, "dropped": self.dropped.copy()}

    def restore(self, snap: dict, points: np.ndarray | None = None) -> None:
        """Go back to the state of a :meth:`snapshot` (the arrays are copied in place): of
        every point, or of the ``points`` (B,) mask's, which are also no longer dropped where
        they were not then (the caller forgets their failures)."""
        for a in self._MUTABLE:
            if points is None:
                getattr(self, a)[...] = snap[a]
            else:
                getattr(self, a)[points] = snap[a][points]
        if points is not None:
            self.dropped[points] = snap["dropped"][points]

    def run(self, k_begin: int, k_end: int, caps: np.ndarray | None = None) -> np.ndarray:
        """Increments k_begin..k_end-1 (each point below its ``caps`` (B,), where given);
        returns their records (k_end - k_begin, B, 2n + 4), NaN where a point took none."""
        B, n = self.eps.shape
        shape = (k_end - k_begin, B, 2 * n + 4)
        rec = np.empty(shape) if caps is None else np.full(shape, np.nan)
        # A meso surrogate's responses belong to the states an increment starts from: one
        # increment per kernel call, the network evaluated between them for every cell at once.
        stride = 1 if self.meso else k_end - k_begin
        steps = _run_steps_parallel if B > 1 else _run_steps
        for k0 in range(k_begin, k_end, stride):
            for a, k1 in _windows(k0, min(k0 + stride, k_end), caps):
                k_from = np.full(B, a, dtype=np.int64)
                if caps is not None:  # the points whose cap comes first run no further
                    k_from[caps < k1] = k1
                    if not (k_from < k1).any():
                        continue
                resp = cell_responses(self.rev, self.values, self._sets)
                while (k_from < k1).any():
                    stop = np.empty(B, dtype=np.int64)
                    steps(self.values, self.flags, self.eps, self.sig, self.K, self.has_K, self.S,
                          self.M, self.start, self.end, self.n_steps, k_from, k1, self.geo, self.p,
                          self.rev.mode, self.rev.volumes0, self.c, self.settings.max_events, rec,
                          k_begin, self.until, self.before, self.n_normal, self.met_at, stop, resp,
                          self.guess, self.trials, self.sets, self.dropped | self.frozen)
                    self.frozen |= self.met_at > 0
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
            except SolverError as e:  # a cell increment that cannot be solved, of some point
                if self.failures is None:
                    raise
                if len(idx) > 1:  # whose: each point alone
                    for b in idx:
                        self._hand_back(k, np.arange(len(failed)) == b, rec_row)
                    return None
                points = PointFailure(str(e), idx).drop_into(self.failures)
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
        take = np.ones(len(idx), bool)
        if self.evaluates_stop:  # the kernel's criterion, on the increments it handed back
            p = out.sig[:, 0].copy()
            for r in range(1, self.n_normal):
                p += out.sig[:, r]
            hit = p / self.n_normal >= self.until[idx]
            self.met_at[idx[hit]] = k
            self.frozen[idx[hit]] = True
            if self.before:  # those keep the state before the increment
                take = ~hit
                rec_row[idx[hit]] = np.nan
        out, idx = out.select(take), idx[take]
        if self.guess.shape[1]:
            self.guess[idx] = tangent.previous[take]
        self.values[idx], self.flags[idx] = out.cells.values, out.flags.flags
        self.eps[idx], self.sig[idx] = out.eps, out.sig
        self.K[idx], self.has_K[idx] = tangent.K[take], True
        n = out.n_components
        rec_row[idx, :n], rec_row[idx, n:2 * n] = out.eps, out.sig
        fr = out.fractions()
        rec_row[idx, 2 * n:] = np.stack([fr[c] for c in FRACTIONS], axis=1)


def _windows(a: int, b: int, caps: np.ndarray | None) -> list[tuple[int, int]]:
    """Increments a..b-1 cut where a point's cap (exclusive) falls inside them (one window
    without caps)."""
    if caps is None:
        return [(a, b)]
    cuts = sorted({a, b, *(int(c) for c in np.unique(caps) if a < c < b)})
    return list(zip(cuts[:-1], cuts[1:]))
