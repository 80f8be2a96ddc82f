"""Mixed stress/strain control of one loading increment (report §1.1.2).

An increment is three linear constraints on the unknown strain increment ``deps`` (B, 3):
row r is either a *strain row*, ``M[r] . deps = v[r]``, or a *stress row*,
``M[r] . sig(eps + deps) = v[r]`` (a target stress after the increment). Per-component control
uses unit rows; combinations give the isochoric (``deps11 + deps22 = 0``), isotropic
(``deps11 - deps22 = 0``) and constant-p (``(sig11 + sig22)/2 = p0``) paths.

:func:`solve_increment` finds ``deps`` by Newton's method on the stress rows. The tangent
``K = dsig/ddeps`` (B, 3, 3) is carried from one increment to the next and refreshed by Broyden's
rank-one update at every trial; it is recomputed by finite differences (one batched REV call on
3 perturbed copies of every material point) at the start and whenever Newton stalls. This is
the documented fallback; if it still does not converge, the increment is refused with an error
that gives the strain reached and the residual.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import SolverError
from ..rev import Rev, RevState

COMPONENTS = ("11", "22", "12")

#: Newton's trials are bounded: no trial strain increment (Euclidean norm over 11, 22, 12) is
#: larger than MAX_TRIAL_STRAIN, or than STEP_MULTIPLE times the increment's strain rows where
#: those ask for more. A singular or sign-flipped tangent (a sample that has lost its stiffness
#: along a stress-controlled direction) otherwise proposes increments many orders of magnitude
#: beyond the path, which a cell solver would have to take.
MAX_TRIAL_STRAIN = 0.05
STEP_MULTIPLE = 100.0


def trial_cap(control: "Control") -> np.ndarray:
    """Largest trial strain increment (B,) of each point's increment under ``control``."""
    strain = np.linalg.norm(control.values[:, ~control.stress_rows], axis=1)
    return np.maximum(MAX_TRIAL_STRAIN, STEP_MULTIPLE * strain)


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
    """Newton's memory between increments: K = dsig/ddeps (B, 3, 3), or None before the first."""

    K: np.ndarray | None = None
    fd_step: float = 1e-7


def _fd_tangent(rev: Rev, state: RevState, x: np.ndarray, h: float) -> np.ndarray:
    """Finite-difference tangent at trial increment x, one batched call on 4B copies."""
    B = state.n_points
    reps = np.repeat(np.arange(B), 4)
    probe = np.repeat(x, 4, axis=0).reshape(B, 4, 3)
    probe[:, 1:, :] += h * np.eye(3)
    trial = rev.step(state.select(reps), probe.reshape(-1, 3))
    sig = trial.sig.reshape(B, 4, 3)
    return np.transpose((sig[:, 1:, :] - sig[:, :1, :]) / h, (0, 2, 1))  # K[b, i, j] = dsig_i/dx_j


def solve_increment(rev: Rev, state: RevState, control: Control, tangent: Tangent,
                    rtol: float = 1e-10, max_iter: int = 24, max_events: int = 6) -> RevState:
    """Advance ``state`` by one increment satisfying ``control``; updates ``tangent`` in place.

    Stress rows are met to ``rtol`` times the larger of the target and the current stress level.

    The stress response is continuous in the strain increment except where a cell event makes
    it jump: with ``sliding_rhs="report"`` a cell that starts sliding with T1 < 0 loses its
    contact at once (see :class:`hmodel.params.Params`). When the target lies inside such a
    jump, no increment meets it; Newton then stalls, and the fallback commits the trial where
    the most cells broke (the event happens), and solves the rest of the increment from there
    (strain rows already met, stress rows unchanged), at most ``max_events`` times.
    """
    B = state.n_points
    # A solver whose cells are converged to less than round-off (DEM) sets its own floor.
    rtol = max(rtol, float(rev.solver.stress_rtol))
    if tangent.K is None or tangent.K.shape[0] != B:
        tangent.K = None
    out = state
    pending = np.arange(B)
    for _ in range(max_events + 1):
        sub = Tangent(None if tangent.K is None else tangent.K[pending], tangent.fd_step)
        part = Control(control.stress_rows, control.matrix, control.values[pending])
        done, reached, diverged = _newton(rev, state.select(pending), part, sub, rtol, max_iter)
        if diverged.any():
            b = pending[np.flatnonzero(diverged)[0]]
            raise SolverError(
                f"mixed-control Newton diverged at strain {np.round(state.eps[b], 8).tolist()}: every "
                f"trial beyond the strain-increment limit {trial_cap(part)[diverged][0]:.3g} missed "
                f"the stress targets (singular or sign-flipped tangent)")
        if tangent.K is None:
            tangent.K = np.zeros((B, 3, 3))
        if sub.K is not None:
            tangent.K[pending] = sub.K
        out = out.scatter(pending, reached)
        if done.all():
            return out
        # Points past a cell event go on from the event state: strain rows are met already.
        pending, state = pending[~done], out
        control = Control(control.stress_rows, control.matrix,
                          np.where(control.stress_rows, control.values, 0.0))
    res = np.abs(out.sig @ control.matrix[control.stress_rows].T
                 - control.values[:, control.stress_rows])
    raise SolverError(
        f"mixed-control Newton did not converge at strain {np.round(out.eps[pending], 8).tolist()}: "
        f"stress residual {float(res.max()):.3g} Pa after {max_events} cell events")


def _newton(rev: Rev, state: RevState, control: Control, tangent: Tangent, rtol: float,
            max_iter: int) -> tuple[np.ndarray, RevState, np.ndarray]:
    """Newton-Broyden on the stress rows.

    Returns a mask of the converged points (B,), a state holding, for each point, its
    solution or, where Newton stalled, the trial with the most broken cells (an event state),
    and a mask of the diverged points: not converged, and every trial held at the strain cap
    (:func:`trial_cap`), so that no event state is worth committing.
    """
    M, S, v = control.matrix, control.stress_rows, control.values
    if not S.any():
        try:
            deps = np.linalg.solve(M, v.T).T
        except np.linalg.LinAlgError:
            raise SolverError("strain control rows are linearly dependent") from None
        return np.ones(state.n_points, bool), rev.step(state, deps), np.zeros(state.n_points, bool)

    B = state.n_points
    scale = np.maximum(np.abs(v[:, S]), np.abs(state.sig).max(axis=1, keepdims=True))
    scale = np.maximum(scale, 1.0)
    if tangent.K is None:
        tangent.K = _fd_tangent(rev, state, np.zeros((B, 3)), tangent.fd_step)

    def newton(x, R):
        # A degenerate secant update: start afresh at the trial; a trial so far out that the
        # sample carries nothing (every cell open, K = 0): start afresh at the state itself.
        for fresh in (x, np.zeros_like(x), None):
            J = np.broadcast_to(M, (B, 3, 3)).copy()
            J[:, S, :] = np.einsum("rk,bkj->brj", M[S], tangent.K)
            try:
                return x - np.linalg.solve(J, R[..., None])[..., 0]
            except np.linalg.LinAlgError:
                if fresh is not None:
                    tangent.K = _fd_tangent(rev, state, fresh, tangent.fd_step)
        raise SolverError(f"singular tangent under mixed control at strain "
                          f"{np.round(state.eps, 8).tolist()}")

    def residual(x, sig):
        R = np.einsum("rk,bk->br", M, x) - v
        R[:, S] = sig @ M[S].T - v[:, S]
        return R

    cap = trial_cap(control)

    def bounded(x):
        """x held inside the ball of radius cap, and the mask of the points it was cut back."""
        nrm = np.linalg.norm(x, axis=1)
        over = nrm > cap
        return np.where(over[:, None], x * (cap / np.maximum(nrm, 1e-300))[:, None], x), over

    # Tangent predictor from the current state, then Newton with Broyden updates.
    x, held = bounded(newton(np.zeros((B, 3)), residual(np.zeros((B, 3)), state.sig)))
    trust = 4.0 * np.maximum(np.linalg.norm(x, axis=1), 1e-8)[:, None][:, 0]
    trial = rev.step(state, x)
    R = residual(x, trial.sig)
    # a trial held at the cap is no event state (a jump lies near the solution, not out there)
    best, best_key = trial, np.where(held, np.inf, _event_key(trial, R, S))
    for it in range(max_iter):
        done = np.all(np.abs(R[:, S]) <= rtol * scale, axis=1)
        if done.all():
            return done, trial, np.zeros(B, bool)
        if it == max_iter // 3:  # stalled: fresh finite-difference tangent at the current trial
            # (converged points keep theirs, so that a point's path never depends on its batch)
            todo = np.flatnonzero(~done)
            tangent.K[todo] = _fd_tangent(rev, state.select(todo), x[todo], tangent.fd_step)
        dx = newton(x, R) - x
        # Trust region: a Newton correction never exceeds a few predictor increments.
        step = trust / np.maximum(np.linalg.norm(dx, axis=1), 1e-300)
        x_new, held = bounded(np.where(done[:, None], x, x + dx * np.minimum(step, 1.0)[:, None]))
        new = rev.step(state, x_new)
        # A secant across a cell event (a jump) would wreck the tangent: skip those points.
        smooth = np.all(new.flags.broken == trial.flags.broken, axis=1)
        _broyden(tangent, (x_new - x) * smooth[:, None], new.sig - trial.sig)
        x, trial = x_new, new
        R = residual(x, trial.sig)
        key = np.where(held, np.inf, _event_key(trial, R, S))
        better = key < best_key
        best, best_key = trial.where(better, best), np.where(better, key, best_key)
    done = np.all(np.abs(R[:, S]) <= rtol * scale, axis=1)
    return done, trial.where(done, best), ~done & np.isinf(best_key)


def _event_key(trial: RevState, R: np.ndarray, S: np.ndarray) -> np.ndarray:
    """Ordering of trials for the event fallback: most broken cells first, then residual."""
    broken = trial.flags.broken.sum(axis=1)
    res = np.abs(R[:, S]).max(axis=1)
    return -broken + res / (1.0 + res)  # res/(1+res) < 1 breaks ties only


def _broyden(tangent: Tangent, dx: np.ndarray, dsig: np.ndarray) -> None:
    """Rank-one secant update K += (dsig - K dx) dx^T / |dx|^2, point by point."""
    nrm = np.einsum("bi,bi->b", dx, dx)
    ok = nrm > 0
    upd = dsig - np.einsum("bij,bj->bi", tangent.K, dx)
    tangent.K = tangent.K + (upd[:, :, None] * dx[:, None, :]
                             / np.where(ok, nrm, 1.0)[:, None, None]) * ok[:, None, None]
