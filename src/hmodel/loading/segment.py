"""One loading segment for a batch of material points: the one runner (report §1.1.2).

A :class:`Segment` is ``n_steps`` equal increments under n fixed constraint rows (see
:class:`~hmodel.loading.control.Control`; n = 3 in 2D, 6 in 3D): strain rows spread their total
change evenly, stress rows move their target linearly from the value at the start of the
segment. :func:`run_segment` runs it on one of two backends with one interface (``run``,
``state``, ``snapshot``, ``restore``): the compiled kernel of :mod:`hmodel.loading.compiled`
(:mod:`hmodel.loading.compiled3d` for the 3D REV) where the REV's cell solver has a compiled
increment, the generic driver
(:func:`~hmodel.loading.control.solve_increment`) otherwise.

The compiled backend runs chunks of :data:`CHUNK` increments; before each chunk the runner's
arrays are copied. When a stopping criterion is met at row j of a chunk, the runner goes back to
the copy and runs exactly the increments up to j: the same increments from the same state give
the same states, so the segment ends on the first state that meets the criterion, and the cost
is at most one chunk run twice. The generic backend runs one increment per chunk, so nothing is
re-run. An increment that cannot be solved ends the segment with :class:`StageFailed` (which
names the increment and the points), after every increment before it has been recorded; with a
``failures`` dict, the points that fail are dropped instead and the others go on.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import InputError, PointFailure, SolverError
from ..rev import Rev, RevState
from .compiled import CompiledSegment, supports
from .compiled3d import CompiledSegment3D
from .control import Control, Tangent, solve_increment
from .newton import NewtonSettings
from .result import FRACTIONS, Recorder, stress_columns

#: Increments per chunk of the compiled kernel (a criterion re-runs at most one chunk).
CHUNK = 100

Progress = Callable[[float], None] | None


@dataclass(frozen=True)
class Segment:
    """``n_steps`` equal increments under fixed constraint rows (see :class:`Control`).

    Strain rows spread ``values[r]`` (a total strain change) evenly over the steps; stress
    rows move their target linearly from the value at the start of the segment to
    ``values[r]``. ``values`` is (n,) or (B, n).
    """

    stress_rows: tuple[bool, ...]
    matrix: np.ndarray
    values: np.ndarray
    n_steps: int
    stage: str

    @classmethod
    def components(cls, kinds: str, values, n_steps: int, stage: str) -> Segment:
        """Per-component segment, ``kinds`` like ``"ESE"`` (E: strain change, S: final stress),
        one letter per component."""
        c = Control.components(kinds, np.atleast_2d(values))
        return cls(tuple(c.stress_rows), c.matrix, np.asarray(values, float), n_steps, stage)

    @property
    def n_components(self) -> int:
        return len(self.stress_rows)


class StageFailed(PointFailure):
    """An increment of a segment could not be solved: ``increment`` (1-based) of the segment,
    the failing ``points``, the solver's reason in the message; the states before it are
    recorded."""

    def __init__(self, message: str, increment: int, points=()):
        super().__init__(message, points)
        self.increment = increment


@dataclass
class SegmentOutcome:
    """How a segment ended: its final state, the increments run, and where a criterion ended
    it early, the columns (:func:`row_values`, arrays of one row) of the state that met it."""

    state: RevState
    increments: int
    met: dict[str, np.ndarray] | None = None


def row_values(rec: np.ndarray) -> dict[str, np.ndarray]:
    """Columns of the result table (:func:`~hmodel.loading.result.columns_for`) from records
    (K, 2n + 4) of one point: eps (n), sig (n), the cell fractions (4)."""
    n = (rec.shape[1] - len(FRACTIONS)) // 2
    cols = stress_columns(rec[:, :n], rec[:, n:2 * n])
    cols.update({c: rec[:, 2 * n + j] for j, c in enumerate(FRACTIONS)})
    return cols


def _records(state: RevState) -> np.ndarray:
    """The record rows (B, 2n + 4) of a state: eps, sig, the cell fractions."""
    fr = state.fractions()
    return np.column_stack([state.eps, state.sig, *[fr[c] for c in FRACTIONS]])


class GenericSegment:
    """The backend of :func:`run_segment` over the generic driver (``run``, ``state``,
    ``snapshot``, ``restore``, as :class:`~hmodel.loading.compiled.CompiledSegment`), for cell
    solvers without a compiled increment. ``states`` holds the states of the last ``run`` (for
    recording the solver's own columns)."""

    def __init__(self, rev: Rev, state: RevState, seg: Segment, start: np.ndarray, end: np.ndarray,
                 tangent: Tangent, settings: NewtonSettings, failures: dict | None = None):
        self.rev, self.seg, self.start, self.end = rev, seg, start, end
        self.tangent, self.settings, self.failures = tangent, settings, failures
        self._state = state
        self.states: list[RevState] = []

    def run(self, k_begin: int, k_end: int) -> np.ndarray:
        """Increments k_begin..k_end-1; returns their records (k_end - k_begin, B, 2n + 4)."""
        S = np.array(self.seg.stress_rows)
        self.states = []
        for k in range(k_begin, k_end):
            control = Control.of_step(S, self.seg.matrix, self.start, self.end, k, self.seg.n_steps)
            if self.failures is None:
                self._state = solve_increment(self.rev, self._state, control, self.tangent,
                                              self.settings)
            else:
                self._state = self._dropping(control)
            self.states.append(self._state)
        return np.stack([_records(s) for s in self.states]) if self.states else np.empty((0, 0, 0))

    def _dropping(self, control: Control) -> RevState:
        """``solve_increment`` of the points not in ``failures``; a point it names as failed is
        added there (:meth:`PointFailure.drop_into`) and the increment solved again for the others."""
        state, tangent = self._state, self.tangent
        B, n = state.n_points, state.n_components
        live = ~np.isin(np.arange(B), list(self.failures))
        if tangent.K is None or tangent.K.shape[0] != B:
            tangent.K = tangent.previous = None
        while live.any():
            idx = np.flatnonzero(live)
            sub_t = Tangent(None if tangent.K is None else tangent.K[idx],
                            None if tangent.previous is None else tangent.previous[idx])
            try:
                sub = solve_increment(self.rev, state.select(idx), control.of_points(idx), sub_t,
                                      self.settings)
            except PointFailure as e:
                live[e.renumber(idx).drop_into(self.failures)] = False
                continue
            if tangent.K is None:
                tangent.K, tangent.previous = np.zeros((B, n, n)), np.full((B, n), np.nan)
            tangent.K[idx], tangent.previous[idx] = sub_t.K, sub_t.previous
            return state.scatter(idx, sub)
        return state

    def state(self) -> RevState:
        return self._state

    def snapshot(self):
        t = self.tangent
        return (self._state, None if t.K is None else t.K.copy(),
                None if t.previous is None else t.previous.copy())

    def restore(self, snap) -> None:
        self._state, self.tangent.K, self.tangent.previous = snap


def alive(n: int, failures: dict | None) -> np.ndarray | None:
    """Recorder mask (n,) of the points not dropped after a failure (None: none dropped)."""
    return None if not failures else ~np.isin(np.arange(n), list(failures))


def run_segment(rev: Rev, state: RevState, seg: Segment, recorder: Recorder | None = None, *,
                stop: Callable[[dict[str, np.ndarray]], np.ndarray] | None = None,
                chunk: Callable[[RevState, int], int] | None = None,
                progress: Progress = None, tangent: Tangent | None = None,
                settings: NewtonSettings = NewtonSettings(), failures: dict | None = None,
                record_every: int = 1, compiled: bool | None = None) -> SegmentOutcome:
    """Apply a :class:`Segment` to every material point, recording its states into
    ``recorder`` (every ``record_every``-th, and the last).

    ``stop(columns)`` gets the columns (:func:`row_values`) of the first point's new states and
    returns for each row whether a criterion is met (or None: never); the segment ends on the
    first such state (``SegmentOutcome.met``: its columns). ``chunk(state, k)``, when given, is
    asked before increment k for the number of increments to run before it is asked again (a
    stability analysis probes the state between chunks), and shown the last state with
    k = n_steps + 1 (where a criterion ends the segment, it is not); in a chunk that fails, it
    is shown every state before the failing increment. ``progress(f)`` is told the fraction of
    the segment done. ``settings``: the mixed-control Newton's.

    ``failures``: None, and an increment that cannot be solved ends the segment with
    :class:`StageFailed`; or a dict, and a point whose increment cannot be solved is dropped
    instead (``failures[point]`` says why; it is left in its last solved state and recorded no
    further) while the others go on: a batch of independent material points, e.g. the parameter
    sets of a calibration. Points already in the dict are dropped from the start.

    ``compiled`` (default: whenever the REV's solver allows it) runs the compiled backend;
    ``False`` forces the generic one.
    """
    if seg.n_steps < 1:
        raise InputError(f"segment {seg.stage!r} needs at least one step, got {seg.n_steps}")
    B, n = state.n_points, state.n_components
    if seg.n_components != n:
        raise InputError(f"segment {seg.stage!r} has {seg.n_components} rows for states of "
                         f"{n} components")
    S = np.array(seg.stress_rows)
    end = np.broadcast_to(np.asarray(seg.values, float), (B, n))
    start = state.sig @ np.asarray(seg.matrix, float).T  # stress-row values at the start
    tangent = tangent or Tangent()
    if (supports(rev) if compiled is None else compiled):
        backend = CompiledSegment3D if n == 6 else CompiledSegment
        runner = backend(rev, state, S, seg.matrix, start, end, seg.n_steps, tangent, settings,
                         failures)
        default = CHUNK
    else:
        runner = GenericSegment(rev, state, seg, start, end, tangent, settings, failures)
        default = 1
    keep = lambda ks: (ks % record_every == 0) | (ks == seg.n_steps)  # noqa: E731
    k = 1
    while k <= seg.n_steps:
        size = chunk(runner.state(), k) if chunk is not None else default
        k_end = min(k + max(1, int(size)), seg.n_steps + 1)
        snap = runner.snapshot()
        try:
            rec = runner.run(k, k_end)
        except SolverError:
            runner.restore(snap)
            _one_by_one(runner, k, k_end, recorder, seg.stage, chunk, failures)  # raises
            raise AssertionError("a failed chunk ran through one increment at a time") from None
        met = stop(row_values(rec[:, 0])) if stop is not None else None
        hit = np.flatnonzero(met) if met is not None else np.empty(0, int)
        if len(hit):
            j = int(hit[0])
            if j + 1 < len(rec):  # back to the chunk's start, then exactly up to the crossing
                runner.restore(snap)
                rec = runner.run(k, k + j + 1)
            _record(recorder, runner, rec, seg.stage, np.arange(k, k + j + 1), keep, failures)
            if progress is not None:
                progress((k + j) / seg.n_steps)
            return SegmentOutcome(runner.state(), k + j, row_values(rec[-1:, 0]))
        _record(recorder, runner, rec, seg.stage, np.arange(k, k_end), keep, failures)
        if progress is not None:
            progress((k_end - 1) / seg.n_steps)
        k = k_end
    if chunk is not None:  # the segment's last state, shown too (what it asks for is not used)
        chunk(runner.state(), seg.n_steps + 1)
    return SegmentOutcome(runner.state(), seg.n_steps)


def _record(recorder: Recorder | None, runner, rec: np.ndarray, stage: str, ks: np.ndarray,
            keep, failures: dict | None) -> None:
    """Record the kept increments ``ks`` of a chunk: from the states where the backend keeps
    them (the solver's own columns too), else from the records."""
    if recorder is None:
        return
    kept = keep(ks)
    if runner.states:
        for s, k in zip(runner.states, kept):
            if k:
                recorder.record(s, stage, alive(s.n_points, failures))
        return
    n = (rec.shape[2] - len(FRACTIONS)) // 2
    rec = rec[kept]
    recorder.record_block(rec[:, :, :n], rec[:, :, n:2 * n], rec[:, :, 2 * n:], stage)


def _one_by_one(runner, k_begin: int, k_end: int, recorder: Recorder | None, stage: str, chunk,
                failures: dict | None) -> None:
    """Increments k_begin..k_end-1 one at a time, each recorded, until the one that fails;
    ``chunk`` (see :func:`run_segment`) is shown every state before it, the last converged one
    included (where a stability analysis matters most)."""
    for k in range(k_begin, k_end):
        if chunk is not None and k > k_begin:
            chunk(runner.state(), k)
        try:
            rec = runner.run(k, k + 1)
        except SolverError as e:
            points = e.points if isinstance(e, PointFailure) else ()
            raise StageFailed(" ".join(str(e).split()), k, points) from None
        _record(recorder, runner, rec, stage, np.array([k]), lambda ks: np.ones(len(ks), bool),
                failures)
