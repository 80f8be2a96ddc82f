"""The one Newton of a mixed-control increment (report §1.1.2), for both loading drivers.

One material point's increment is three linear rows on its strain increment x (see
:mod:`hmodel.loading.control`): strain rows ``M[r] . x = v[r]`` and stress rows
``M[r] . sig(x) = v[r]``. Newton's method solves the stress rows with a tangent K = dsig/dx
carried from one increment to the next:

- the first tangent is a finite-difference one (4 trials), or, where the trial gives the exact
  stress slope along the one strain direction u the strain rows leave free (a learned cell
  response, see :class:`hmodel.cell.CellKernel`), one trial at no strain with that slope;
- the first trial is the tangent predictor, or (``previous_first``) the point's previous
  increment with its strain rows moved to this increment's;
- each correction is a Newton step, shortened to ``trust`` times the predictor (trust region)
  and held inside the strain cap (``max_trial_strain``, or ``step_multiple`` times the strain
  rows where those ask for more: a nearly singular tangent would otherwise ask a cell solver
  for absurd increments);
- after each trial K is updated by Broyden's rank-one secant, except across a cell event (the
  set of broken cells changed: a jump) and along u where the slope is exact;
- a stalled Newton takes a fresh finite-difference tangent at its current trial after a third
  of its iterations; a singular Jacobian takes one at the current trial, then at no strain;
- when Newton has not converged after ``max_iter`` corrections, the trial with the most broken
  cells (then the smallest residual) is the event state (a target inside the jump of a cell
  event, see ``solve_increment``), unless every trial was held at the cap (diverged).

The algorithm is written once, as a state machine per point that asks its driver for trials
(:func:`begin`, :func:`told_trial`, :func:`told_tangent`): the compiled driver
(:mod:`hmodel.loading.compiled`) answers inside its Numba kernel, the generic driver
(:mod:`hmodel.loading.control`) with one batched REV call per round for all points. The two
differ only in how a trial is evaluated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit


@dataclass(frozen=True)
class NewtonSettings:
    """Settings of the mixed-control Newton (one place for both drivers).

    Attributes
    ----------
    rtol : float
        Stress rows are met to rtol times the larger of the target and the current stress
        level (raised to the cell solver's own ``stress_rtol`` where that is larger).
    max_iter : int
        Newton corrections per increment before the event fallback.
    max_events : int
        Cell events committed within one increment before it is refused.
    trust : float
        A correction never exceeds ``trust`` times the predictor increment.
    fd_step : float
        Strain step of the finite-difference tangents.
    max_trial_strain, step_multiple : float
        The strain cap: no trial strain increment (norm over 11, 22, 12) beyond
        max(max_trial_strain, step_multiple x the norm of the increment's strain rows).
    previous_first : bool
        Newton's first trial is the point's previous increment (its strain rows moved to this
        increment's) rather than the tangent predictor: along a smooth path it is closer.
    """

    rtol: float = 1e-10
    max_iter: int = 24
    max_events: int = 6
    trust: float = 4.0
    fd_step: float = 1e-7
    max_trial_strain: float = 0.05
    step_multiple: float = 100.0
    previous_first: bool = True

    @property
    def refresh_at(self) -> int:
        """The correction before which a stalled Newton takes a fresh tangent."""
        return self.max_iter // 3

    def packed(self, rtol_floor: float = 0.0) -> np.ndarray:
        """The settings for the kernels (see the ``C_*`` indices), rtol raised to the floor."""
        return np.array([max(self.rtol, rtol_floor), self.max_iter, self.refresh_at, self.trust,
                         self.fd_step, self.max_trial_strain, self.step_multiple])


# Indices of the packed settings.
C_RTOL, C_MAX_ITER, C_REFRESH, C_TRUST, C_FD, C_CAP, C_MULTIPLE = range(7)

# What the machine asks of its driver, or how it ended.
ASK_TRIAL = 0      # evaluate the trial W[XN:XN+3] (with its slope along u if exact)
ASK_TANGENT = 1    # a finite-difference tangent into K at W[XN:XN+3]
ASK_SLOPE = 2      # evaluate W[XN:XN+3] (= 0) with its slope along u, K zeroed first
CONVERGED = 3      # the solution is the current trial (W[X], W[SIG])
STALLED = 4        # not converged: the best trial is the event state (W[BX], W[BSIG])
SINGULAR = 5       # the Jacobian stayed singular after fresh tangents
DIVERGED = 6       # not converged, and every trial held at the strain cap
CELL_FAILED = 7    # a cell increment could not be solved

# Layout of a point's workspace W (float64, NW).
X, XN, SIG, R, SCALE, BX, BSIG, V = 0, 3, 6, 9, 12, 15, 18, 21
TRUST, CAP, BKEY, IT, HELD, PHASE, PENDING, FRESH = 24, 25, 26, 27, 28, 29, 30, 31
NW = 32

# Phases: what the asked-for answer is for.
P_FIRST_TANGENT, P_FIRST_TRIAL, P_TRIAL, P_REFRESH, P_FRESH = range(5)
# After a fresh tangent for a singular Jacobian: retry the predictor or the correction.
AT_PREDICTOR, AT_CORRECTION = 0, 1


@njit(cache=True, error_model="numpy")
def solve3(J, R):
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
def free_direction(S, M):
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
def _newton_step(x, R, K, S, M):
    """x - J^-1 R with J = M, stress rows replaced by M[r] K; None when J is singular."""
    J = M.copy()
    for r in range(3):
        if S[r]:
            for j in range(3):
                J[r, j] = M[r, 0] * K[0, j] + M[r, 1] * K[1, j] + M[r, 2] * K[2, j]
    d = solve3(J, R)
    if d is None:
        return None
    return x - d


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
def _residual(W, S, M):
    """W[R] = M x - v on strain rows, M sig - v on stress rows, at the current trial."""
    for r in range(3):
        a = W[SIG:SIG + 3] if S[r] else W[X:X + 3]
        W[R + r] = M[r, 0] * a[0] + M[r, 1] * a[1] + M[r, 2] * a[2] - W[V + r]


@njit(cache=True, error_model="numpy")
def _converged(W, S, rtol):
    for r in range(3):
        if S[r] and abs(W[R + r]) > rtol * W[SCALE + r]:
            return False
    return True


@njit(cache=True, error_model="numpy")
def begin(W, K, has_K, S, M, v, sig, c, guess, exact):
    """Starts a point's increment toward targets v (3,) from stress sig (3,); returns the first
    request. ``guess`` (3,) is the previous increment (or empty, or NaN: none); ``exact``:
    trials give the exact slope along the free direction."""
    W[:] = 0.0
    W[V:V + 3] = v
    strain = 0.0
    for r in range(3):
        if not S[r]:
            strain += v[r] ** 2
    W[CAP] = max(c[C_CAP], c[C_MULTIPLE] * math.sqrt(strain))
    smax = max(abs(sig[0]), abs(sig[1]), abs(sig[2]))
    for r in range(3):
        W[SCALE + r] = max(max(abs(v[r]), smax), 1.0)
    W[SIG:SIG + 3] = sig  # the state itself is the trial x = 0
    W[BKEY] = 1e300
    if guess.shape[0] == 3:
        W[BX:BX + 3] = guess  # kept here until the predictor has used it
    else:
        W[BX] = np.nan
    if not has_K[0]:
        W[PHASE] = P_FIRST_TANGENT
        if exact:
            K[:, :] = 0.0
            return ASK_SLOPE
        return ASK_TANGENT
    return _predict(W, K, S, M, c)


@njit(cache=True, error_model="numpy")
def _predict(W, K, S, M, c):
    """The first trial: the tangent predictor from the state, or the previous increment."""
    _residual(W, S, M)
    xt = _newton_step(W[X:X + 3], W[R:R + 3], K, S, M)
    if xt is None:
        return _fresh(W, AT_PREDICTOR)
    W[FRESH] = 0.0
    _bound(xt, W[CAP])
    W[TRUST] = c[C_TRUST] * max(math.sqrt(xt[0] ** 2 + xt[1] ** 2 + xt[2] ** 2), 1e-8)
    g = W[BX:BX + 3].copy()
    if math.isfinite(g[0]):
        # the last increment's strain, its strain rows moved to this increment's
        d = np.zeros(3)
        for r in range(3):
            if not S[r]:
                d[r] = W[V + r] - (M[r, 0] * g[0] + M[r, 1] * g[1] + M[r, 2] * g[2])
        dg = solve3(M, d)
        if dg is not None:
            xt = g + dg
            W[TRUST] = max(W[TRUST], c[C_TRUST] * math.sqrt(xt[0] ** 2 + xt[1] ** 2 + xt[2] ** 2))
    W[HELD] = _bound(xt, W[CAP])
    W[XN:XN + 3] = xt
    W[PHASE] = P_FIRST_TRIAL
    return ASK_TRIAL


@njit(cache=True, error_model="numpy")
def _correct(W, K, S, M, c):
    """The next correction from the current trial."""
    xn = _newton_step(W[X:X + 3], W[R:R + 3], K, S, M)
    if xn is None:
        return _fresh(W, AT_CORRECTION)
    W[FRESH] = 0.0
    dx = xn - W[X:X + 3]
    nrm = math.sqrt(dx[0] ** 2 + dx[1] ** 2 + dx[2] ** 2)
    if nrm > W[TRUST]:  # trust region: a correction never exceeds a few predictor increments
        dx *= W[TRUST] / nrm
    xn = W[X:X + 3] + dx
    W[HELD] = _bound(xn, W[CAP])
    W[XN:XN + 3] = xn
    W[IT] += 1.0
    W[PHASE] = P_TRIAL
    return ASK_TRIAL


@njit(cache=True, error_model="numpy")
def _fresh(W, at):
    """A singular Jacobian: a fresh tangent at the current trial, then at no strain."""
    W[PENDING] = at
    W[PHASE] = P_FRESH
    if W[FRESH] == 0.0:
        W[FRESH] = 1.0
        W[XN:XN + 3] = W[X:X + 3]
        return ASK_TANGENT
    if W[FRESH] == 1.0 and (W[X] != 0.0 or W[X + 1] != 0.0 or W[X + 2] != 0.0):
        W[FRESH] = 2.0
        W[XN:XN + 3] = 0.0
        return ASK_TANGENT
    return SINGULAR


@njit(cache=True, error_model="numpy")
def told_tangent(W, K, has_K, S, M, c):
    """The driver has put the asked-for tangent (or slope) into K; the next request."""
    phase = W[PHASE]
    if phase == P_FIRST_TANGENT:
        has_K[0] = True
        return _predict(W, K, S, M, c)
    if phase == P_REFRESH:
        return _correct(W, K, S, M, c)
    # P_FRESH
    if W[PENDING] == AT_PREDICTOR:
        return _predict(W, K, S, M, c)
    return _correct(W, K, S, M, c)


@njit(cache=True, error_model="numpy")
def told_trial(W, K, S, M, c, sig_n, ok, broken, same_events, exact, best):
    """The driver evaluated the asked-for trial: its stress sig_n (3,), whether every cell
    increment was solved, its number of broken cells and whether the same cells are broken as
    in the current trial. Sets ``best[0]`` when this trial is the new event candidate (the
    driver keeps its state); returns the next request or the outcome."""
    best[0] = False
    if not ok:
        return CELL_FAILED
    xn = W[XN:XN + 3].copy()
    if W[PHASE] == P_TRIAL and not exact and same_events:
        # Broyden's rank-one secant update (skipped across a cell event, a jump, and where the
        # slope along u is exact)
        dx = xn - W[X:X + 3]
        dd = dx[0] ** 2 + dx[1] ** 2 + dx[2] ** 2
        if dd > 0.0:
            for a in range(3):
                upd = sig_n[a] - W[SIG + a] - (K[a, 0] * dx[0] + K[a, 1] * dx[1] + K[a, 2] * dx[2])
                for j in range(3):
                    K[a, j] += upd * dx[j] / dd
    W[X:X + 3] = xn
    W[SIG:SIG + 3] = sig_n
    _residual(W, S, M)
    res = 0.0
    for r in range(3):
        if S[r]:
            res = max(res, abs(W[R + r]))
    key = -broken + res / (1.0 + res)
    # the event fallback's candidate: most broken cells, then residual (a trial held at the cap
    # is none: a jump lies near the solution, not out there)
    if W[HELD] == 0.0 and key < W[BKEY]:
        W[BKEY] = key
        W[BX:BX + 3] = xn
        W[BSIG:BSIG + 3] = sig_n
        best[0] = True
    if _converged(W, S, c[C_RTOL]):
        return CONVERGED
    if W[IT] >= c[C_MAX_ITER]:
        return STALLED if W[BKEY] < 1e300 else DIVERGED
    if W[IT] == c[C_REFRESH]:  # stalled: fresh finite-difference tangent at the current trial
        W[XN:XN + 3] = xn
        W[PHASE] = P_REFRESH
        return ASK_TANGENT
    return _correct(W, K, S, M, c)
