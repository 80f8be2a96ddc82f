"""Mixed stress/strain control of one loading increment (report §1.1.2).

An increment is three linear constraints on the unknown strain increment ``deps`` (B, 3):
row r is either a *strain row*, ``M[r] . deps = v[r]``, or a *stress row*,
``M[r] . sig(eps + deps) = v[r]`` (a target stress after the increment). Per-component control
uses unit rows; combinations give the isochoric (``deps11 + deps22 = 0``), isotropic
(``deps11 - deps22 = 0``) and constant-p (``(sig11 + sig22)/2 = p0``) paths.

:func:`solve_increment` finds ``deps`` by the one Newton of :mod:`hmodel.loading.newton`
(settings: :class:`~hmodel.loading.newton.NewtonSettings`), every point asking for its own
trials; each round evaluates all the trials asked for in one batched REV call, and the
finite-difference tangents in one call on 4 copies of every point that needs one. The tangent
``K = dsig/ddeps`` (B, 3, 3) is carried from one increment to the next (:class:`Tangent`). An
increment Newton cannot solve is refused with an error that gives the strain reached and why.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import PointFailure, SolverError
from ..rev import Rev, RevState
from .newton import (ASK_TANGENT, ASK_TRIAL, CAP, CONVERGED, DIVERGED, NW, STALLED, XN, NewtonSettings,
                     begin, told_tangent, told_trial)

COMPONENTS = ("11", "22", "12")


@dataclass(frozen=True)
class Control:
    """Constraints of one increment for B material points.

    Attributes
    ----------
    stress_rows : ndarray (3,) bool   which rows constrain the stress after the increment
    matrix : ndarray (3, 3)           row coefficients on (11, 22, 12)
    values : ndarray (B, 3)           strain-increment values or absolute stress targets [Pa]
    """

    stress_rows: np.ndarray
    matrix: np.ndarray
    values: np.ndarray

    @classmethod
    def strain(cls, deps: np.ndarray) -> "Control":
        """Every component strain-controlled: ``deps`` (B, 3)."""
        deps = np.atleast_2d(np.asarray(deps, dtype=float))
        return cls(np.zeros(3, bool), np.eye(3), deps)

    @classmethod
    def of_step(cls, stress_rows, matrix, start: np.ndarray, end: np.ndarray, k: int,
                n_steps: int) -> "Control":
        """Increment ``k`` (1..n_steps) of a segment of ``n_steps`` equal ones: stress rows
        targeted on the straight line from ``start`` to ``end`` (B, 3), strain rows each taking
        ``end / n_steps`` of their total change.

        >>> c = Control.of_step([False, True, False], np.eye(3), np.array([[0.0, 1e5, 0.0]]),
        ...                     np.array([[1e-3, 2e5, 0.0]]), 1, 4)
        >>> c.values.tolist()
        [[0.00025, 125000.0, 0.0]]
        """
        S = np.asarray(stress_rows, bool)
        return cls(S, matrix, np.where(S, start + (end - start) * (k / n_steps), end / n_steps))

    @classmethod
    def components(cls, kinds: str, values: np.ndarray) -> "Control":
        """Per-component control, ``kinds`` like ``"ESE"``: E = strain increment, S = stress target.

        >>> Control.components("ESE", [[1e-4, 2e5, 0.0]]).stress_rows.tolist()
        [False, True, False]
        """
        kinds = kinds.upper()
        if len(kinds) != 3 or set(kinds) - {"E", "S"}:
            raise ValueError(f"control kinds must be 3 letters among E/S, got {kinds!r}")
        return cls(np.array([k == "S" for k in kinds]), np.eye(3),
                   np.atleast_2d(np.asarray(values, dtype=float)))

    @property
    def n_points(self) -> int:
        return self.values.shape[0]


@dataclass
class Tangent:
    """Newton's memory between increments: K = dsig/ddeps (B, 3, 3) and each point's previous
    strain increment (B, 3) (NaN rows: none), or None before the first."""

    K: np.ndarray | None = None
    previous: np.ndarray | None = None


def _fd_tangent(rev: Rev, state: RevState, x: np.ndarray, h: float) -> np.ndarray:
    """Finite-difference tangent at trial increments x (B, 3), one batched call on 4B copies."""
    B = state.n_points
    reps = np.repeat(np.arange(B), 4)
    probe = np.repeat(x, 4, axis=0).reshape(B, 4, 3)
    probe[:, 1:, :] += h * np.eye(3)
    trial = rev.step(state.select(reps), probe.reshape(-1, 3))
    sig = trial.sig.reshape(B, 4, 3)
    return np.transpose((sig[:, 1:, :] - sig[:, :1, :]) / h, (0, 2, 1))  # K[b, i, j] = dsig_i/dx_j


def solve_increment(rev: Rev, state: RevState, control: Control, tangent: Tangent,
                    settings: NewtonSettings = NewtonSettings()) -> RevState:
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
    """
    B = state.n_points
    c = settings.packed(float(rev.solver.stress_rtol))
    if tangent.K is None or tangent.K.shape[0] != B:
        tangent.K = None
    K = np.zeros((B, 3, 3)) if tangent.K is None else np.array(tangent.K, float)
    has_K = np.full(B, tangent.K is not None)
    guess = np.full((B, 3), np.nan)
    if settings.previous_first and tangent.previous is not None and tangent.previous.shape == (B, 3):
        guess[:] = tangent.previous
    start = state
    out = state
    pending = np.arange(B)
    for event in range(settings.max_events + 1):
        part = Control(control.stress_rows, control.matrix, control.values[pending])
        Kp, hp = K[pending], has_K[pending]
        try:
            done, reached = _newton(rev, state.select(pending), part, Kp, hp, c, settings,
                                    guess[pending] if event == 0 else None)
        except PointFailure as e:  # name the failed points in this call's batch
            raise e.renumber(pending)
        K[pending], has_K[pending] = Kp, hp
        out = out.scatter(pending, reached)
        if done.all():
            tangent.K, tangent.previous = K, out.eps - start.eps
            return out
        # Points past a cell event go on from the event state: strain rows are met already.
        pending, state = pending[~done], out
        control = Control(control.stress_rows, control.matrix,
                          np.where(control.stress_rows, control.values, 0.0))
    tangent.K = K
    res = np.abs(out.sig @ control.matrix[control.stress_rows].T
                 - control.values[:, control.stress_rows])
    raise PointFailure(
        f"mixed-control Newton did not converge at strain {np.round(out.eps[pending], 8).tolist()}: "
        f"stress residual {float(res.max()):.3g} Pa after {settings.max_events} cell events", pending)


def _newton(rev: Rev, state: RevState, control: Control, K: np.ndarray, has_K: np.ndarray,
            c: np.ndarray, settings: NewtonSettings,
            guess: np.ndarray | None = None) -> tuple[np.ndarray, RevState]:
    """The one Newton for B points, each asking for its trials; every round evaluates the
    trials asked for in one batched REV call (and the tangents in one call on 4 copies each).

    Returns a mask of the converged points (B,) and a state holding, for each point, its
    solution or, where Newton stalled, the trial with the most broken cells (an event state).
    Raises SolverError where Newton diverged or the Jacobian stayed singular.
    """
    M, S, v = control.matrix, control.stress_rows, control.values
    B = state.n_points
    if not S.any():
        try:
            deps = np.linalg.solve(M, v.T).T
        except np.linalg.LinAlgError:
            raise SolverError("strain control rows are linearly dependent") from None
        return np.ones(B, bool), rev.step(state, deps)
    W = np.zeros((B, NW))
    acts = np.empty(B, np.int64)
    no_guess = np.empty(0)
    for b in range(B):
        acts[b] = begin(W[b], K[b], has_K[b:b + 1], S, M, v[b], state.sig[b], c,
                        no_guess if guess is None else guess[b], False)
    current, best = state, state  # each point's current and best trials (the state: none yet)
    tried = np.zeros(B, bool)
    flag = np.zeros(1, bool)
    while True:
        ask = np.flatnonzero(acts == ASK_TANGENT)
        if len(ask):
            K[ask] = _fd_tangent(rev, state.select(ask), W[ask, XN:XN + 3], settings.fd_step)
            for b in ask:
                acts[b] = told_tangent(W[b], K[b], has_K[b:b + 1], S, M, c)
        ask = np.flatnonzero(acts == ASK_TRIAL)
        if not len(ask):
            if np.any(acts == ASK_TANGENT):
                continue
            break
        new = rev.step(state.select(ask), W[ask, XN:XN + 3])
        broken = new.flags.broken
        same = tried[ask] & np.all(broken == current.flags.broken[ask], axis=1)
        n_broken = broken.sum(axis=1)
        better = np.zeros(len(ask), bool)
        for j, b in enumerate(ask):
            acts[b] = told_trial(W[b], K[b], S, M, c, new.sig[j], True, n_broken[j], same[j],
                                 False, flag)
            better[j] = flag[0]
        current, tried[ask] = current.scatter(ask, new), True
        if better.any():
            best = best.scatter(ask[better], new.select(better))
    failed = np.flatnonzero(~np.isin(acts, (CONVERGED, STALLED)))
    if len(failed):
        b = failed[0]
        at = np.round(state.eps[b], 8).tolist()
        if acts[b] == DIVERGED:
            raise PointFailure(
                f"mixed-control Newton diverged at strain {at}: every trial beyond the "
                f"strain-increment limit {W[b, CAP]:.3g} missed the stress targets (singular or "
                f"sign-flipped tangent)", failed)
        raise PointFailure(f"singular tangent under mixed control at strain {at}", failed)
    done = acts == CONVERGED
    return done, current.where(done, best)


