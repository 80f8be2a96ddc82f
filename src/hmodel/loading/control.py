"""Mixed stress/strain control of one loading increment (report §1.1.2), on n components.

An increment is n linear constraints on the unknown strain increment ``deps`` (B, n), n the
REV's number of strain and stress components (3 in 2D: 11, 22, 12): row r is either a *strain
row*, ``M[r] . deps = v[r]``, or a *stress row*, ``M[r] . sig(eps + deps) = v[r]`` (a target
stress after the increment). Per-component control uses unit rows; combinations give the
isochoric (``deps11 + deps22 = 0``), isotropic (``deps11 - deps22 = 0``) and constant-p
(``(sig11 + sig22)/2 = p0``) paths.

:func:`solve_increment` finds ``deps`` by the one Newton of :mod:`hmodel.loading.newton`
(settings: :class:`~hmodel.loading.newton.NewtonSettings`), every point asking for its own
trials; each round evaluates all the trials asked for in one batched REV call, and the
finite-difference tangents in one call on n + 1 copies of every point that needs one. The
tangent ``K = dsig/ddeps`` (B, n, n) is carried from one increment to the next
(:class:`Tangent`). An increment Newton cannot solve is refused with an error that gives the
strain reached and why.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import PointFailure
from ..rev import Rev, RevState
from .newton import (ASK_TANGENT, ASK_TRIAL, CAP, COMMIT_EVENT, COMMIT_SOLUTION, CONVERGED, DIVERGED,
                     GIVE_UP, SINGULAR, STALLED, XN, NewtonSettings, after_newton, begin, event_targets,
                     segment_targets, told_tangent, told_trial, workspace_size)


@dataclass(frozen=True)
class Control:
    """Constraints of one increment for B material points.

    Attributes
    ----------
    stress_rows : ndarray (n,) bool   which rows constrain the stress after the increment
    matrix : ndarray (n, n)           row coefficients on the components (2D: 11, 22, 12)
    values : ndarray (B, n)           strain-increment values or absolute stress targets [Pa]
    """

    stress_rows: np.ndarray
    matrix: np.ndarray
    values: np.ndarray

    @classmethod
    def strain(cls, deps: np.ndarray) -> "Control":
        """Every component strain-controlled: ``deps`` (B, n)."""
        deps = np.atleast_2d(np.asarray(deps, dtype=float))
        return cls(np.zeros(deps.shape[1], bool), np.eye(deps.shape[1]), deps)

    @classmethod
    def of_step(cls, stress_rows, matrix, start: np.ndarray, end: np.ndarray, k: int,
                n_steps: int) -> "Control":
        """Increment ``k`` (1..n_steps) of a segment of ``n_steps`` equal ones: stress rows
        targeted on the straight line from ``start`` to ``end`` (B, n), strain rows each taking
        ``end / n_steps`` of their total change (:func:`~hmodel.loading.newton.segment_targets`,
        which the compiled driver calls too).

        >>> c = Control.of_step([False, True, False], np.eye(3), np.array([[0.0, 1e5, 0.0]]),
        ...                     np.array([[1e-3, 2e5, 0.0]]), 1, 4)
        >>> c.values.tolist()
        [[0.00025, 125000.0, 0.0]]
        """
        S = np.asarray(stress_rows, np.bool_)
        start, end = np.broadcast_arrays(np.atleast_2d(np.asarray(start, float)),
                                         np.atleast_2d(np.asarray(end, float)))
        start, end = np.ascontiguousarray(start), np.ascontiguousarray(end)
        v = np.empty(start.shape)
        for b in range(len(v)):
            segment_targets(S, start[b], end[b], k, n_steps, v[b])
        return cls(S, matrix, v)

    @classmethod
    def components(cls, kinds: str, values: np.ndarray) -> "Control":
        """Per-component control, ``kinds`` like ``"ESE"``: E = strain increment, S = stress
        target, one letter per component.

        >>> Control.components("ESE", [[1e-4, 2e5, 0.0]]).stress_rows.tolist()
        [False, True, False]
        """
        kinds = kinds.upper()
        values = np.atleast_2d(np.asarray(values, dtype=float))
        if len(kinds) != values.shape[1] or set(kinds) - {"E", "S"}:
            raise ValueError(f"control kinds must be {values.shape[1]} letters among E/S, got {kinds!r}")
        return cls(np.array([k == "S" for k in kinds]), np.eye(len(kinds)), values)

    @property
    def n_components(self) -> int:
        return self.values.shape[1]

    def of_points(self, index) -> "Control":
        """The same rows for the points ``index`` of the batch."""
        return Control(self.stress_rows, self.matrix, self.values[index])

    @property
    def n_points(self) -> int:
        return self.values.shape[0]


@dataclass
class Tangent:
    """Newton's memory between increments: K = dsig/ddeps (B, n, n) and each point's previous
    strain increment (B, n) (NaN rows: none), or None before the first."""

    K: np.ndarray | None = None
    previous: np.ndarray | None = None


def _fd_tangent(rev: Rev, state: RevState, x: np.ndarray, h: float) -> np.ndarray:
    """Finite-difference tangent at trial increments x (B, n), one batched call on (n + 1) B
    copies."""
    B, n = x.shape
    reps = np.repeat(np.arange(B), n + 1)
    probe = np.repeat(x, n + 1, axis=0).reshape(B, n + 1, n)
    probe[:, 1:, :] += h * np.eye(n)
    trial = rev.step(state.select(reps), probe.reshape(-1, n))
    sig = trial.sig.reshape(B, n + 1, n)
    return np.transpose((sig[:, 1:, :] - sig[:, :1, :]) / h, (0, 2, 1))  # K[b, i, j] = dsig_i/dx_j


def solve_increment(rev: Rev, state: RevState, control: Control, tangent: Tangent,
                    settings: NewtonSettings = NewtonSettings(), by_hexagon: bool = False) -> RevState:
    """Advance ``state`` by one increment satisfying ``control``; updates ``tangent`` in place.

    Stress rows are met to ``settings.rtol`` (or the cell solver's ``stress_rtol`` where larger)
    times the larger of the target and the current stress level, by the one Newton of
    :mod:`hmodel.loading.newton`, its trials evaluated as batched REV calls.

    The stress response is continuous in the strain increment except where a cell event makes
    it jump: with ``sliding_rhs="report"`` a cell that starts sliding with T1 < 0 loses its
    contact at once (see :class:`hmodel.params.Params`). When the target lies inside such a
    jump, no increment meets it; Newton then stalls, and the fallback commits the trial where
    the most cells broke (the event happens), and solves the rest of the increment from there
    (strain rows already met, stress rows unchanged), at most ``settings.max_events`` times.

    A bi-hexagon's hexagon that opens beside its open twin makes the stress jump with the same
    broken cells, which that count does not see: a point whose increment is given up with cells
    of two hexagons is solved again from the increment's start with broken hexagons counted
    instead (``by_hexagon``; docs/loading.md, "Cell events"). Only increments that failed take
    this second attempt, so every increment solved before is solved as it was.
    """
    B, n = state.n_points, control.n_components
    S, M = control.stress_rows, control.matrix
    c = settings.packed_for(rev.solver)
    if tangent.K is None or tangent.K.shape[0] != B:
        tangent.K = None
    K = np.zeros((B, n, n)) if tangent.K is None else np.array(tangent.K, float)
    has_K = np.full(B, tangent.K is not None)
    # the increment's own tangent, for a retry: K is a copy, and tangent.K is only rebound below
    entry = Tangent(tangent.K, tangent.previous)
    guess = np.full((B, n), np.nan)
    if settings.previous_first and tangent.previous is not None and tangent.previous.shape == (B, n):
        guess[:] = tangent.previous
    start = out = state
    targets = np.array(control.values, float)  # the event loop moves the strain rows
    pending = np.arange(B)
    retry = np.zeros(0, np.int64)
    event = 0
    while len(pending):
        Kp, hp = K[pending], has_K[pending]
        acts, W, reached = _newton(rev, state.select(pending), Control(S, M, targets[pending]), Kp,
                                   hp, c, settings, guess[pending] if event == 0 else None, by_hexagon)
        K[pending], has_K[pending] = Kp, hp
        out = out.scatter(pending, reached)
        then = np.array([after_newton(a, event, settings.max_events) for a in acts])
        if np.any(then == GIVE_UP):
            if by_hexagon or out.flags.hexagons.shape[-2] < 2:
                tangent.K = K
                raise _failure(acts, then, W, state.select(pending), out.select(pending), S, M,
                               targets[pending], settings).renumber(pending)
            retry = np.r_[retry, pending[then == GIVE_UP]]
        # Points past a cell event go on from the event state (newton.event_targets).
        pending, state = pending[then == COMMIT_EVENT], out
        event_targets(S, targets)
        event += 1
    if len(retry):
        sub = Tangent(None if entry.K is None else entry.K[retry],
                      None if entry.previous is None else entry.previous[retry])
        try:
            solved = solve_increment(rev, start.select(retry), control.of_points(retry), sub, settings,
                                     by_hexagon=True)
        except PointFailure as e:
            tangent.K = K
            raise e.renumber(retry)
        out = out.scatter(retry, solved)
        K[retry], has_K[retry] = sub.K, True
    tangent.K = K
    if S.any():  # a pure strain increment had no Newton: nothing to start the next one
        tangent.previous = out.eps - start.eps
    return out


def _failure(acts, then, W, state: RevState, reached: RevState, S, M, targets,
             settings: NewtonSettings) -> PointFailure:
    """The error of the points (of this batch) whose increment is given up, named by the
    first of them."""
    failed = np.flatnonzero(then == GIVE_UP)
    b = failed[0]
    at = np.round(state.eps[b], 8).tolist()
    n = len(S)
    if acts[b] == STALLED:
        res = np.abs(reached.sig[failed] @ M[S].T - targets[failed][:, S])
        return PointFailure(
            f"mixed-control Newton did not converge at strain "
            f"{np.round(reached.eps[failed], 8).tolist()}: stress residual {float(res.max()):.3g} Pa "
            f"after {settings.max_events} cell events", failed)
    if acts[b] == DIVERGED:
        return PointFailure(
            f"mixed-control Newton diverged at strain {at}: every trial beyond the "
            f"strain-increment limit {W[b, 8 * n + CAP]:.3g} missed the stress targets (singular "
            f"or sign-flipped tangent)", failed)
    if acts[b] == SINGULAR and not S.any():
        return PointFailure("strain control rows are linearly dependent", failed)
    return PointFailure(f"singular tangent under mixed control at strain {at}", failed)


def _newton(rev: Rev, state: RevState, control: Control, K: np.ndarray, has_K: np.ndarray,
            c: np.ndarray, settings: NewtonSettings, guess: np.ndarray | None = None,
            by_hexagon: bool = False) -> tuple[np.ndarray, np.ndarray, RevState]:
    """The one Newton for B points, each asking for its trials; every round evaluates the
    trials asked for in one batched REV call (and the tangents in one call on n + 1 copies
    each).

    Returns each point's outcome (B,) (``CONVERGED``, ``STALLED`` or a failure), their
    workspaces and a state holding, for each point, its solution or, where Newton stalled,
    the trial with the most broken cells, or with ``by_hexagon`` hexagons (an event state).
    """
    M, S, v = control.matrix, control.stress_rows, control.values
    B, n = v.shape
    W = np.zeros((B, workspace_size(n)))
    acts = np.empty(B, np.int64)
    no_guess = np.empty(0)
    for b in range(B):
        acts[b] = begin(W[b], K[b], has_K[b:b + 1], S, M, v[b], state.sig[b], c,
                        no_guess if guess is None else guess[b], False)
    current, best = state, state  # each point's current and best trials (the state: none yet)
    tried = np.zeros(B, bool)
    flag = np.zeros(1, bool)
    trial_x = W[:, XN * n:(XN + 1) * n]
    while True:
        ask = np.flatnonzero(acts == ASK_TANGENT)
        if len(ask):
            K[ask] = _fd_tangent(rev, state.select(ask), trial_x[ask], settings.fd_step)
            for b in ask:
                acts[b] = told_tangent(W[b], K[b], has_K[b:b + 1], S, M, c)
        ask = np.flatnonzero(acts == ASK_TRIAL)
        if not len(ask):
            if np.any(acts == ASK_TANGENT):
                continue
            break
        new = rev.step(state.select(ask), trial_x[ask])
        broken = new.flags.broken
        same = tried[ask] & np.all(broken == current.flags.broken[ask], axis=1)
        n_broken = (new.flags.open_hexagons if by_hexagon else broken).sum(axis=1)
        better = np.zeros(len(ask), bool)
        for j, b in enumerate(ask):
            acts[b] = told_trial(W[b], K[b], S, M, c, new.sig[j], True, n_broken[j], same[j],
                                 False, flag)
            better[j] = flag[0]
        current, tried[ask] = current.scatter(ask, new), True
        if better.any():
            best = best.scatter(ask[better], new.select(better))
    return acts, W, current.where(acts == CONVERGED, best)
