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
  for absurd increments), lowered to what the cell solver takes (:func:`solver_limits`: a
  learned cell's ``max_cell_strain``);
- after each trial K is updated by Broyden's rank-one secant, except across a cell event (the
  set of broken cells changed: a jump) and along u where the slope is exact;
- a stalled Newton takes a fresh finite-difference tangent at its current trial after a third
  of its iterations; a singular Jacobian takes one at the current trial, then at no strain;
- when Newton has not converged after ``max_iter`` corrections, the trial with the most broken
  cells (then the smallest residual) is the event state (a target inside the jump of a cell
  event, see ``solve_increment``), unless every trial was held at the cap (diverged); where
  an increment of bi-hexagons is given up, either driver solves it once more counting broken
  hexagons (a bi-hexagon's two apart: ``control.solve_increment``, ``compiled.solve_point``).

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

    def packed(self, rtol_floor: float = 0.0, strain_ceiling: float = math.inf) -> np.ndarray:
        """The settings for the kernels (see the ``C_*`` indices), rtol raised to the floor;
        ``strain_ceiling`` lowers the strain cap to what the cell solver takes
        (:func:`solver_limits`)."""
        return np.array([max(self.rtol, rtol_floor), self.max_iter, self.refresh_at, self.trust,
                         self.fd_step, self.max_trial_strain, self.step_multiple, strain_ceiling])

    def packed_for(self, solver) -> np.ndarray:
        """:meth:`packed` with the limits of the cell solver ``solver`` (:func:`solver_limits`)."""
        return self.packed(*solver_limits(solver))


def solver_limits(solver) -> tuple[float, float]:
    """The cell solver's own stress tolerance, and the largest REV strain trial (norm over the
    components, shear once) whose cell strains it can take.

    A learned cell refuses a cell strain increment dl / l0 beyond its ``max_cell_strain`` (many
    times its trained increments: a run-away trial it would only guess at). The REV's dl is L
    n.de.n for a unit direction n (eq. 1.1), L the cell's length or its box's, l + 2r (eq.
    1.19), at most 2 l0 in compression (l0 = 2r (1 + 2 cos alpha0) >= 2r); n.de.n is at most
    the largest eigenvalue of de, which is at most de's Frobenius norm, at most sqrt(2) times
    the norm taken here. So trials within max_cell_strain / (2 sqrt(2)) are increments the
    cells take, and a nearly singular tangent's trial is held there instead of failing the
    increment."""
    ceiling = float(solver.max_cell_strain) / (2.0 * math.sqrt(2.0))
    return float(solver.stress_rtol), ceiling


# Indices of the packed settings.
C_RTOL, C_MAX_ITER, C_REFRESH, C_TRUST, C_FD, C_CAP, C_MULTIPLE, C_CEILING = range(8)

# What the machine asks of its driver, or how it ended.
ASK_TRIAL = 0      # evaluate the trial W[XN:XN+3] (with its slope along u if exact)
ASK_TANGENT = 1    # a finite-difference tangent into K at W[XN:XN+3]
ASK_SLOPE = 2      # evaluate W[XN:XN+3] (= 0) with its slope along u, K zeroed first
CONVERGED = 3      # the solution is the current trial (W[X], W[SIG])
STALLED = 4        # not converged: the best trial is the event state (W[BX], W[BSIG])
SINGULAR = 5       # the Jacobian stayed singular after fresh tangents
DIVERGED = 6       # not converged, and every trial held at the strain cap
CELL_FAILED = 7    # a cell increment could not be solved

# Layout of a point's workspace W (float64, :func:`workspace_size` of n components): eight
# blocks of n values (block k is W[k n:(k + 1) n]), then eight scalars from W[8 n].
X, XN, SIG, R, SCALE, BX, BSIG, V = range(8)
TRUST, CAP, BKEY, IT, HELD, PHASE, PENDING, FRESH = range(8)

# Phases: what the asked-for answer is for.
P_FIRST_TANGENT, P_FIRST_TRIAL, P_TRIAL, P_REFRESH, P_FRESH = range(5)
# After a fresh tangent for a singular Jacobian: retry the predictor or the correction.
AT_PREDICTOR, AT_CORRECTION = 0, 1
# What a driver does after Newton's outcome within one increment (:func:`after_newton`).
COMMIT_SOLUTION, COMMIT_EVENT, GIVE_UP = 0, 1, 2


@njit(cache=True, error_model="numpy")
def workspace_size(n):
    """Length of a point's workspace W for n components."""
    return 8 * n + 8


@njit(cache=True, inline="always", error_model="numpy")
def block(W, k, n):
    """Block ``k`` (X, XN, SIG, ...) of the workspace W of n components: a view."""
    return W[k * n:(k + 1) * n]


@njit(cache=True, inline="always", error_model="numpy")
def _s(n, k):
    """Index of scalar ``k`` (TRUST, CAP, ...) in the workspace of n components."""
    return 8 * n + k


@njit(cache=True, inline="always", error_model="numpy")
def _norm(x):
    s = 0.0
    for j in range(x.shape[0]):
        s += x[j] ** 2
    return math.sqrt(s)


@njit(cache=True, inline="always", error_model="numpy")
def _dot(a, b):
    s = 0.0
    for j in range(a.shape[0]):
        s += a[j] * b[j]
    return s


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
def solve(J, R):
    """J^-1 R for n x n J: cofactors for n = 3 (:func:`solve3`), Gaussian elimination with
    partial pivoting otherwise; None when J is singular (a zero or non-finite pivot)."""
    n = R.shape[0]
    if n == 3:
        return solve3(J, R)
    A = J.copy()
    x = R.copy()
    for k in range(n):
        piv = k
        for i in range(k + 1, n):
            if abs(A[i, k]) > abs(A[piv, k]):
                piv = i
        if A[piv, k] == 0.0 or not math.isfinite(A[piv, k]):
            return None
        if piv != k:
            for j in range(n):
                A[k, j], A[piv, j] = A[piv, j], A[k, j]
            x[k], x[piv] = x[piv], x[k]
        for i in range(k + 1, n):
            f = A[i, k] / A[k, k]
            for j in range(k, n):
                A[i, j] -= f * A[k, j]
            x[i] -= f * x[k]
    for k in range(n - 1, -1, -1):
        s = x[k]
        for j in range(k + 1, n):
            s -= A[k, j] * x[j]
        x[k] = s / A[k, k]
    return x


@njit(cache=True, error_model="numpy")
def free_direction(S, M):
    """The strain direction (n,) the strain rows of M leave free when exactly one row is a
    stress row (for n = 3 the cross product of the two strain rows; otherwise M^-1 e_r, r the
    stress row); empty otherwise."""
    n = S.shape[0]
    stress = -1
    for r in range(n):
        if S[r]:
            if stress >= 0:
                return np.zeros(0)
            stress = r
    if stress < 0:
        return np.zeros(0)
    if n == 3:
        rows = np.empty(2, dtype=np.int64)
        m = 0
        for r in range(3):
            if not S[r]:
                rows[m] = r
                m += 1
        a, b = M[rows[0]], M[rows[1]]
        return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                         a[0] * b[1] - a[1] * b[0]])
    e = np.zeros(n)
    e[stress] = 1.0
    u = solve(M, e)
    return np.zeros(0) if u is None else u


@njit(cache=True, error_model="numpy")
def _newton_step(x, R, K, S, M):
    """x - J^-1 R with J = M, stress rows replaced by M[r] K; None when J is singular."""
    n = S.shape[0]
    J = M.copy()
    for r in range(n):
        if S[r]:
            for j in range(n):
                s = 0.0
                for a in range(n):
                    s += M[r, a] * K[a, j]
                J[r, j] = s
    d = solve(J, R)
    if d is None:
        return None
    return x - d


@njit(cache=True, error_model="numpy")
def _bound(x, cap):
    """Scales x (n,) in place back onto the ball of radius cap if outside; whether it did."""
    nrm = _norm(x)
    if nrm <= cap:
        return False
    for j in range(x.shape[0]):
        x[j] *= cap / nrm
    return True


@njit(cache=True, error_model="numpy")
def _residual(W, S, M):
    """W[R] = M x - v on strain rows, M sig - v on stress rows, at the current trial."""
    n = S.shape[0]
    for r in range(n):
        a = block(W, SIG, n) if S[r] else block(W, X, n)
        W[R * n + r] = _dot(M[r], a) - W[V * n + r]


@njit(cache=True, error_model="numpy")
def _converged(W, S, rtol):
    n = S.shape[0]
    for r in range(n):
        if S[r] and abs(W[R * n + r]) > rtol * W[SCALE * n + r]:
            return False
    return True


@njit(cache=True, error_model="numpy")
def begin(W, K, has_K, S, M, v, sig, c, guess, exact):
    """Starts a point's increment toward targets v (n,) from stress sig (n,); returns the first
    request. ``guess`` (n,) is the previous increment (or empty, or NaN: none); ``exact``:
    trials give the exact slope along the free direction. Without stress rows the one trial is
    M^-1 v (SINGULAR when the strain rows are dependent)."""
    n = S.shape[0]
    W[:] = 0.0
    block(W, V, n)[:] = v
    strain = 0.0
    n_stress = 0
    for r in range(n):
        if not S[r]:
            strain += v[r] ** 2
        else:
            n_stress += 1
    # the cap, lowered to the cell solver's ceiling, but never below the strain rows' own norm
    W[_s(n, CAP)] = max(min(max(c[C_CAP], c[C_MULTIPLE] * math.sqrt(strain)), c[C_CEILING]), math.sqrt(strain))
    smax = 0.0
    for j in range(n):
        smax = max(smax, abs(sig[j]))
    for r in range(n):
        W[SCALE * n + r] = max(max(abs(v[r]), smax), 1.0)
    block(W, SIG, n)[:] = sig  # the state itself is the trial x = 0
    W[_s(n, BKEY)] = 1e300
    if n_stress == 0:  # pure strain control: the increment is known, one trial evaluates it
        x = solve(M, v)
        if x is None:
            return SINGULAR
        block(W, XN, n)[:] = x
        W[_s(n, PHASE)] = P_FIRST_TRIAL
        return ASK_TRIAL
    if guess.shape[0] == n:
        block(W, BX, n)[:] = guess  # kept here until the predictor has used it
    else:
        W[BX * n] = np.nan
    if not has_K[0]:
        W[_s(n, PHASE)] = P_FIRST_TANGENT
        if exact:
            K[:, :] = 0.0
            return ASK_SLOPE
        return ASK_TANGENT
    return _predict(W, K, S, M, c)


@njit(cache=True, error_model="numpy")
def _predict(W, K, S, M, c):
    """The first trial: the tangent predictor from the state, or the previous increment."""
    n = S.shape[0]
    _residual(W, S, M)
    xt = _newton_step(block(W, X, n), block(W, R, n), K, S, M)
    if xt is None:
        return _fresh(W, AT_PREDICTOR, n)
    W[_s(n, FRESH)] = 0.0
    _bound(xt, W[_s(n, CAP)])
    W[_s(n, TRUST)] = c[C_TRUST] * max(_norm(xt), 1e-8)
    g = block(W, BX, n).copy()
    if math.isfinite(g[0]):
        # the last increment's strain, its strain rows moved to this increment's
        d = np.zeros(n)
        for r in range(n):
            if not S[r]:
                d[r] = W[V * n + r] - _dot(M[r], g)
        dg = solve(M, d)
        if dg is not None:
            xt = g + dg
            W[_s(n, TRUST)] = max(W[_s(n, TRUST)], c[C_TRUST] * _norm(xt))
    W[_s(n, HELD)] = _bound(xt, W[_s(n, CAP)])
    block(W, XN, n)[:] = xt
    W[_s(n, PHASE)] = P_FIRST_TRIAL
    return ASK_TRIAL


@njit(cache=True, error_model="numpy")
def _correct(W, K, S, M, c):
    """The next correction from the current trial."""
    n = S.shape[0]
    xn = _newton_step(block(W, X, n), block(W, R, n), K, S, M)
    if xn is None:
        return _fresh(W, AT_CORRECTION, n)
    W[_s(n, FRESH)] = 0.0
    dx = xn - block(W, X, n)
    nrm = _norm(dx)
    if nrm > W[_s(n, TRUST)]:  # trust region: a correction never exceeds a few predictor increments
        dx *= W[_s(n, TRUST)] / nrm
    xn = block(W, X, n) + dx
    W[_s(n, HELD)] = _bound(xn, W[_s(n, CAP)])
    block(W, XN, n)[:] = xn
    W[_s(n, IT)] += 1.0
    W[_s(n, PHASE)] = P_TRIAL
    return ASK_TRIAL


@njit(cache=True, error_model="numpy")
def _fresh(W, at, n):
    """A singular Jacobian: a fresh tangent at the current trial, then at no strain."""
    W[_s(n, PENDING)] = at
    W[_s(n, PHASE)] = P_FRESH
    if W[_s(n, FRESH)] == 0.0:
        W[_s(n, FRESH)] = 1.0
        block(W, XN, n)[:] = block(W, X, n)
        return ASK_TANGENT
    if W[_s(n, FRESH)] == 1.0 and _norm(block(W, X, n)) != 0.0:
        W[_s(n, FRESH)] = 2.0
        block(W, XN, n)[:] = 0.0
        return ASK_TANGENT
    return SINGULAR


@njit(cache=True, error_model="numpy")
def told_tangent(W, K, has_K, S, M, c):
    """The driver has put the asked-for tangent (or slope) into K; the next request."""
    n = S.shape[0]
    phase = W[_s(n, PHASE)]
    if phase == P_FIRST_TANGENT:
        has_K[0] = True
        return _predict(W, K, S, M, c)
    if phase == P_REFRESH:
        return _correct(W, K, S, M, c)
    # P_FRESH
    if W[_s(n, PENDING)] == AT_PREDICTOR:
        return _predict(W, K, S, M, c)
    return _correct(W, K, S, M, c)


@njit(cache=True, error_model="numpy")
def told_trial(W, K, S, M, c, sig_n, ok, broken, same_events, exact, best):
    """The driver evaluated the asked-for trial: its stress sig_n (n,), whether every cell
    increment was solved, its number of broken cells (or hexagons) and whether the same cells
    are broken as in the current trial. Sets ``best[0]`` when this trial is the new event candidate (the
    driver keeps its state); returns the next request or the outcome."""
    n = S.shape[0]
    best[0] = False
    if not ok:
        return CELL_FAILED
    xn = block(W, XN, n).copy()
    if W[_s(n, PHASE)] == P_TRIAL and not exact and same_events:
        # Broyden's rank-one secant update (skipped across a cell event, a jump, and where the
        # slope along u is exact)
        dx = xn - block(W, X, n)
        dd = _dot(dx, dx)
        if dd > 0.0:
            for a in range(n):
                upd = sig_n[a] - W[SIG * n + a] - _dot(K[a], dx)
                for j in range(n):
                    K[a, j] += upd * dx[j] / dd
    block(W, X, n)[:] = xn
    block(W, SIG, n)[:] = sig_n
    _residual(W, S, M)
    res = 0.0
    for r in range(n):
        if S[r]:
            res = max(res, abs(W[R * n + r]))
    key = -broken + res / (1.0 + res)
    # the event fallback's candidate: most broken cells, then residual (a trial held at the cap
    # is none: a jump lies near the solution, not out there)
    if W[_s(n, HELD)] == 0.0 and key < W[_s(n, BKEY)]:
        W[_s(n, BKEY)] = key
        block(W, BX, n)[:] = xn
        block(W, BSIG, n)[:] = sig_n
        best[0] = True
    if _converged(W, S, c[C_RTOL]):
        return CONVERGED
    if W[_s(n, IT)] >= c[C_MAX_ITER]:
        return STALLED if W[_s(n, BKEY)] < 1e300 else DIVERGED
    if W[_s(n, IT)] == c[C_REFRESH]:  # stalled: fresh finite-difference tangent at the current trial
        block(W, XN, n)[:] = xn
        W[_s(n, PHASE)] = P_REFRESH
        return ASK_TANGENT
    return _correct(W, K, S, M, c)


@njit(cache=True, error_model="numpy")
def after_newton(act, event, max_events):
    """The event loop of one increment (both drivers): after Newton's outcome ``act`` in the
    ``event``-th attempt, COMMIT_SOLUTION (converged: the increment is done), COMMIT_EVENT
    (stalled inside the jump of a cell event: commit the event state and solve the rest of the
    increment from there, :func:`event_targets`) or GIVE_UP (failed, or ``max_events`` events
    committed already)."""
    if act == CONVERGED:
        return COMMIT_SOLUTION
    if act == STALLED and event < max_events:
        return COMMIT_EVENT
    return GIVE_UP


@njit(cache=True, error_model="numpy")
def event_targets(S, v):
    """The rows of the rest of an increment past a committed cell event: its strain rows are
    met already (0), its stress targets unchanged. Works on v (n,) or (B, n) in place."""
    flat = v.reshape(-1, S.shape[0])
    for b in range(flat.shape[0]):
        for r in range(S.shape[0]):
            if not S[r]:
                flat[b, r] = 0.0


@njit(cache=True, error_model="numpy")
def segment_targets(S, start, end, k, n_steps, v):
    """Rows ``v`` (n,) of increment ``k`` (1..n_steps) of a segment of equal increments: stress
    rows targeted on the straight line from ``start`` to ``end`` (n,), strain rows each taking
    ``end / n_steps`` of their total change."""
    for r in range(S.shape[0]):
        if S[r]:
            v[r] = start[r] + (end[r] - start[r]) * (k / n_steps)
        else:
            v[r] = end[r] / n_steps
