"""One loading segment for a batch of material points: the one runner (report §1.1.2).

A :class:`Segment` is ``n_steps`` equal increments under n fixed constraint rows (see
:class:`~hmodel.loading.control.Control`; n = 3 in 2D, 6 in 3D): strain rows spread their total
change evenly, stress rows move their target linearly from the value at the start of the
segment; or, with ``per_increment``, strain rows only, each increment taking ``values`` and a
stop criterion ending the segment (an isotropic compression to p0). :func:`run_segment` runs it
on one of two backends with one interface (``run``, ``state``, ``snapshot``, ``restore``,
``freeze``): the compiled kernel of :mod:`hmodel.loading.compiled` where the REV's cell solver
has a compiled increment, the generic driver (:func:`~hmodel.loading.control.solve_increment`)
otherwise.

A stop criterion is per point: each material point stops on its own, the others go on, and the
segment ends when every point has stopped (or been dropped). The compiled backend runs chunks of
:data:`CHUNK` increments; before each chunk the runner's arrays are copied. When a point meets a
criterion at row j of a chunk, the runner takes that point back to the copy and runs exactly its
increments up to j: the same increments from the same state give the same states, so the point
ends on the first state that meets the criterion (or, ``stop_before``, on the one before it),
and the cost is at most one chunk run twice. A :class:`MeanStressReaches` criterion both
backends evaluate themselves after every increment (the compiled one in its kernel), so nothing
is run twice. The generic backend runs one increment per chunk, so nothing is re-run. An increment that cannot be solved ends the
segment with :class:`StageFailed` (which names the increment and the points), after every
increment before it has been recorded; with a ``failures`` dict, the points that fail are
dropped instead and the others go on.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import InputError, PointFailure, SolverError
from ..rev import Rev, RevState
from ..rev.state import mean_stress
from .compiled import CompiledSegment, supports
from .control import Control, Tangent, solve_increment
from .newton import NewtonSettings, solve
from .result import FRACTIONS, Recorder, stress_columns

#: Increments per chunk of the compiled kernel (a criterion re-runs at most one chunk).
CHUNK = 100

Progress = Callable[[float], None] | None


@dataclass(frozen=True)
class Segment:
    """``n_steps`` equal increments under fixed constraint rows (see :class:`Control`).

    Strain rows spread ``values[r]`` (a total strain change) evenly over the steps; stress
    rows move their target linearly from the value at the start of the segment to
    ``values[r]``. ``values`` is (n,) or (B, n). With ``per_increment``, every row is a strain
    row and each increment takes ``values`` itself: a segment of at most ``n_steps`` increments
    that a stop criterion ends (:func:`run_segment`).
    """

    stress_rows: tuple[bool, ...]
    matrix: np.ndarray
    values: np.ndarray
    n_steps: int
    stage: str
    per_increment: bool = False

    def __post_init__(self):
        if self.per_increment and any(self.stress_rows):
            raise InputError(f"segment {self.stage!r} takes the same values every increment: its rows "
                             "must all be strain rows (a stress target moves along a known length)")

    @classmethod
    def components(cls, kinds: str, values, n_steps: int, stage: str) -> Segment:
        """Per-component segment, ``kinds`` like ``"ESE"`` (E: strain change, S: final stress),
        one letter per component."""
        c = Control.components(kinds, np.atleast_2d(values))
        return cls(tuple(c.stress_rows), c.matrix, np.asarray(values, float), n_steps, stage)

    @property
    def n_components(self) -> int:
        return len(self.stress_rows)

    @property
    def spread(self) -> int:
        """The increments a strain row's value is spread over: ``n_steps``, or 1 where each
        increment takes it (``per_increment``)."""
        return 1 if self.per_increment else self.n_steps


@dataclass(frozen=True)
class MeanStressReaches:
    """A stop criterion of :func:`run_segment`: point b's mean stress p reaches ``target[b]``
    [Pa] (one value: every point's). A function of the columns of new states, as any
    criterion; the backends evaluate it themselves after every increment instead (the compiled
    one in its kernel), with p as :func:`~hmodel.rev.state.mean_stress` computes it."""

    target: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "target", np.atleast_1d(np.asarray(self.target, float)))

    def __call__(self, cols: dict[str, np.ndarray]) -> np.ndarray:
        p = np.asarray(cols["p"])
        return p >= np.tile(self.target, len(p) // len(self.target))

    def fraction(self, state: RevState, ended: np.ndarray) -> float:
        """How far the points are from their targets: the least p / target, those ``ended``
        counted as there."""
        return float(np.clip(np.min(np.where(ended, 1.0, state.p / self.target)), 0.0, 1.0))


class StageFailed(PointFailure):
    """An increment of a segment could not be solved: ``increment`` (1-based) of the segment,
    the failing ``points``, the solver's reason in the message; the states before it are
    recorded."""

    def __init__(self, message: str, increment: int, points=()):
        super().__init__(message, points)
        self.increment = increment


@dataclass
class SegmentOutcome:
    """How a segment ended: its final state, the increments run (by the point that ran
    longest), and where a criterion ended points early, which (``stopped`` (B,)) and the columns
    (:func:`row_values`, arrays (B,), NaN for the others) of the state each ended on."""

    state: RevState
    increments: int
    met: dict[str, np.ndarray] | None = None
    stopped: np.ndarray | None = None


def row_values(rec: np.ndarray) -> dict[str, np.ndarray]:
    """Columns of the result table (:func:`~hmodel.loading.result.columns_for`) from records
    (K, 2n + 4): eps (n), sig (n), the cell fractions (4)."""
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
    ``snapshot``, ``restore``, ``freeze``, as :class:`~hmodel.loading.compiled.CompiledSegment`),
    for cell solvers without a compiled increment. ``states`` holds the states of the last
    ``run`` and ``moved`` the points each took an increment in (for recording the solver's own
    columns)."""

    def __init__(self, rev: Rev, state: RevState, seg: Segment, start: np.ndarray, end: np.ndarray,
                 tangent: Tangent, settings: NewtonSettings, failures: dict | None = None,
                 until: np.ndarray | None = None, before: bool = False):
        self.rev, self.seg, self.start, self.end = rev, seg, start, end
        self.tangent, self.settings, self.failures = tangent, settings, failures
        self._state = state
        self.states: list[RevState] = []
        self.moved: list[np.ndarray] = []
        B = state.n_points
        #: points a stop criterion ended: they take no more increments
        self.frozen = np.zeros(B, bool)
        #: each point's mean stress at which ``run`` ends it (None: no such criterion;
        #: ``before``: on the state before the increment that reaches it), and the increment
        #: that did (0: none yet), as :class:`~hmodel.loading.compiled.CompiledSegment`'s kernel
        self.until = None if until is None else np.broadcast_to(np.asarray(until, float), B)
        self.before = bool(before)
        self.met_at = np.zeros(B, np.int64)
        #: whether ``run`` returns the records (else NaN: the caller records the states)
        self.records = True
        self._deps: np.ndarray | None = None  # a strain-only increment (the same each time)

    @property
    def evaluates_stop(self) -> bool:
        """Whether ``run`` itself ends points at a mean stress (``until``)."""
        return self.until is not None

    def run(self, k_begin: int, k_end: int, caps: np.ndarray | None = None) -> np.ndarray:
        """Increments k_begin..k_end-1 (each point below its ``caps`` (B,), where given);
        returns their records (k_end - k_begin, B, 2n + 4), NaN where a point took none."""
        S = np.array(self.seg.stress_rows)
        self.states, self.moved = [], []
        rows = []
        strain_only = not S.any()
        everyone = np.ones(self._state.n_points, bool)
        for k in range(k_begin, k_end):
            if caps is not None:
                moving = ~self.frozen & (k < caps)
            else:
                moving = ~self.frozen if self.frozen.any() else everyone
            # With strain rows only, the points that ended stay in the solver's batch (their
            # increment unused): a batched solver (a network, whose float32 products depend on
            # the batch) then sees one batch through the segment.
            batch = everyone if strain_only else moving
            if strain_only and self._deps is None:  # the same increment every time
                self._deps = _known(self.seg.matrix, self.end / self.seg.spread)
            deps = self._deps if strain_only else None
            if deps is None:
                control = Control.of_step(S, self.seg.matrix, self.start, self.end, k, self.seg.spread)
            tangent = self._tangent_copy() if self.until is not None and self.before else None
            if deps is not None:
                new = self._strained(deps, batch)
            elif self.failures is None and batch.all():
                new = solve_increment(self.rev, self._state, control, self.tangent, self.settings)
            else:
                new = self._solve(control, batch)
            old, self._state = self._state, new if moving.all() else new.where(moving, self._state)
            moved = moving if not self.failures else moving & alive(len(moving), self.failures)
            if self.until is not None:
                moved = self._until(k, moved, old, tangent)
            self.states.append(self._state)
            self.moved.append(moved)
            if self.records:
                r = _records(self._state)
                r[~moved] = np.nan
                rows.append(r)
        n, B = self._state.n_components, self._state.n_points
        if not rows:
            return np.full((k_end - k_begin, B, 2 * n + len(FRACTIONS)), np.nan)
        return np.stack(rows)

    def _until(self, k: int, moved: np.ndarray, old: RevState, tangent) -> np.ndarray:
        """End the points of ``moved`` whose mean stress reached ``until`` in increment k
        (``before``: back to their state ``old`` and ``tangent`` rows); returns the points
        whose increment stands."""
        hit = moved & (mean_stress(self._state.sig) >= self.until)
        if not hit.any():
            return moved
        self.met_at[hit] = k
        self.frozen |= hit
        if not self.before:
            return moved
        self._state = old.where(hit, self._state)
        K, previous = tangent
        if K is not None and self.tangent.K is not None and K.shape == self.tangent.K.shape:
            self.tangent.K[hit] = K[hit]
        if previous is not None and self.tangent.previous is not None \
                and previous.shape == self.tangent.previous.shape:
            self.tangent.previous[hit] = previous[hit]
        return moved & ~hit

    def _tangent_copy(self):
        t = self.tangent
        return (None if t.K is None else t.K.copy(), None if t.previous is None else t.previous.copy())

    def _solve(self, control: Control, batch: np.ndarray) -> RevState:
        """``solve_increment`` of the points of ``batch`` (B,) not in ``failures``; with a
        ``failures`` dict, a point it names as failed is added there
        (:meth:`PointFailure.drop_into`) and the increment solved again for the others."""
        state, tangent = self._state, self.tangent
        B, n = state.n_points, state.n_components
        live = batch & ~np.isin(np.arange(B), list(self.failures or ()))
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
                e.renumber(idx)
                if self.failures is None:
                    raise
                live[e.drop_into(self.failures)] = False
                continue
            if tangent.K is None:
                tangent.K, tangent.previous = np.zeros((B, n, n)), np.full((B, n), np.nan)
            tangent.K[idx], tangent.previous[idx] = sub_t.K, sub_t.previous
            return state.scatter(idx, sub)
        return state

    def _strained(self, deps: np.ndarray, batch: np.ndarray) -> RevState:
        """A strain-only increment ``deps`` (B, n) of the points of ``batch`` not in
        ``failures``: one REV step, the one trial Newton would make (:func:`_known`), the
        tangent left as ``solve_increment`` leaves it."""
        state, tangent = self._state, self.tangent
        B, n = state.n_points, state.n_components
        if self.failures is None and batch.all():
            if tangent.K is None or tangent.K.shape[0] != B:
                tangent.K = np.zeros((B, n, n))
            return self.rev.step(state, deps)
        live = batch & ~np.isin(np.arange(B), list(self.failures or ()))
        if tangent.K is None or tangent.K.shape[0] != B:
            tangent.K = tangent.previous = None
        if not live.any():
            return state
        idx = np.flatnonzero(live)
        sub = self.rev.step(state.select(idx), deps[idx])
        if tangent.K is None:
            tangent.K, tangent.previous = np.zeros((B, n, n)), np.full((B, n), np.nan)
        return state.scatter(idx, sub)

    def state(self) -> RevState:
        return self._state

    def snapshot(self):
        return (self._state, *self._tangent_copy(), self.frozen.copy(), self.met_at.copy())

    def restore(self, snap, points: np.ndarray | None = None) -> None:
        """Go back to a :meth:`snapshot`: every point, or the ``points`` (B,) mask's (the
        others keep their state; the tangent rows of the points are the snapshot's where it
        had one)."""
        state, K, previous, frozen, met_at = snap
        if points is None or points.all():
            self._state, self.tangent.K, self.tangent.previous = state, K, previous
            self.frozen, self.met_at = frozen.copy(), met_at.copy()
            return
        idx = np.flatnonzero(points)
        self._state = self._state.scatter(idx, state.select(idx))
        t = self.tangent
        if K is not None and t.K is not None and t.K.shape == K.shape:
            t.K[idx] = K[idx]
        if previous is not None and t.previous is not None and t.previous.shape == previous.shape:
            t.previous[idx] = previous[idx]
        self.frozen[idx], self.met_at[idx] = frozen[idx], met_at[idx]

    def freeze(self, points: np.ndarray) -> None:
        """The points of the mask (B,) take no more increments (a criterion ended them)."""
        self.frozen |= points


def _known(matrix: np.ndarray, values: np.ndarray) -> np.ndarray | None:
    """The strain increment (B, n) of strain rows ``matrix`` only, of values (B, n) (those of
    :func:`~hmodel.loading.newton.segment_targets`): M^-1 v per point as Newton's one trial
    takes it (:func:`~hmodel.loading.newton.solve`); None where the rows are dependent (then
    Newton says so)."""
    out = np.empty(values.shape)
    for b, v in enumerate(values):
        x = solve(matrix, v)
        if x is None:
            return None
        out[b] = x
    return out


def alive(n: int, failures: dict | None) -> np.ndarray | None:
    """Recorder mask (n,) of the points not dropped after a failure (None: none dropped)."""
    return None if not failures else ~np.isin(np.arange(n), list(failures))


def run_segment(rev: Rev, state: RevState, seg: Segment, recorder: Recorder | None = None, *,
                stop: Callable[[dict[str, np.ndarray]], np.ndarray] | None = None,
                stop_before: bool = False,
                chunk: Callable[[RevState, int], int] | None = None,
                progress: Progress = None, tangent: Tangent | None = None,
                settings: NewtonSettings = NewtonSettings(), failures: dict | None = None,
                record_every: int = 1, compiled: bool | None = None) -> SegmentOutcome:
    """Apply a :class:`Segment` to every material point, recording its states into
    ``recorder`` (every ``record_every``-th, and the last).

    ``stop(columns)`` gets the columns (:func:`row_values`) of new states, arrays over the rows
    of the increments run by every point in turn (increment-major: row i is point i % B), each
    row once and in order, and returns for each row whether a criterion is met (or None:
    never). Each point ends on its first state that meets it (``stop_before``: on the state
    before that one, which is not kept), the others go on; the segment ends when every point
    has (or was dropped). A :class:`MeanStressReaches` criterion the backends evaluate
    themselves, increment by increment.
    ``chunk(state, k)``, when given, is asked before increment k for the number of increments
    to run before it is asked again (a stability analysis probes the state between chunks),
    and shown the last state with k = n_steps + 1 (where criteria end the segment, it is not);
    in a chunk that fails, it is shown every state before the failing increment.
    ``progress(f)`` is told the fraction of the segment done (for a :class:`MeanStressReaches`
    criterion, how near the points are to their targets). ``settings``: the mixed-control
    Newton's.

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
    end = np.asarray(seg.values, float)
    if end.shape != (B, n):
        end = np.broadcast_to(end, (B, n))
    start = state.sig @ np.asarray(seg.matrix, float).T  # stress-row values at the start
    tangent = tangent or Tangent()
    until = stop.target if isinstance(stop, MeanStressReaches) else None  # (the runner's own)
    if (supports(rev) if compiled is None else compiled):
        runner = CompiledSegment(rev, state, S, seg.matrix, start, end, seg.spread, tangent, settings,
                                 failures, until=until, before=stop_before)
        default = CHUNK
    else:
        runner = GenericSegment(rev, state, seg, start, end, tangent, settings, failures,
                                until=until, before=stop_before)
        # (the states are recorded; the records are what a criterion reads)
        runner.records = stop is not None and (until is None or not stop_before)
        default = 1
    keep = lambda ks: (ks % record_every == 0) | (ks == seg.n_steps)  # noqa: E731
    ended = np.zeros(B, bool)  # the points a criterion ended
    last = np.full((B, 2 * n + len(FRACTIONS)), np.nan)  # the records of the states they ended on
    k = 1
    while k <= seg.n_steps:
        size = chunk(runner.state(), k) if chunk is not None else default
        k_end = min(k + max(1, int(size)), seg.n_steps + 1)
        snap = runner.snapshot()
        dropped = set(failures) if failures is not None and stop is not None else None
        try:
            rec = runner.run(k, k_end)
        except SolverError:
            runner.restore(snap)
            _one_by_one(runner, k, k_end, recorder, seg.stage, chunk, failures)  # raises
            raise AssertionError("a failed chunk ran through one increment at a time") from None
        hit, ends = _met(stop, runner, rec, k, stop_before, ended)
        short = hit & (ends < k_end) & (not runner.evaluates_stop)  # back to the chunk's start ...
        _record(recorder, runner, rec, seg.stage, np.arange(k, k_end), keep, failures, ~short)
        if hit.any() and not stop_before:
            last[hit] = rec[ends[hit] - 1 - k, np.flatnonzero(hit)]
        if short.any():  # ... then each up to its end
            runner.restore(snap, short)
            if dropped is not None:  # a failure after a point's end is not its own
                for b in np.flatnonzero(short):
                    if int(b) not in dropped:
                        failures.pop(int(b), None)
            top = int(ends[short].max())
            if top > k:
                again = runner.run(k, top, caps=np.where(short, ends, k))
                _record(recorder, runner, again, seg.stage, np.arange(k, top), keep, failures, short)
        if hit.any():
            ended |= hit
            runner.freeze(hit)
            if stop_before:
                last[hit] = _records(runner.state())[hit]
        live = ~ended if not failures else ~ended & alive(B, failures)
        if stop is not None and not live.any():  # every point ended (or was dropped)
            done = int(ends[hit].max()) - 1 if hit.any() else k_end - 1
            _tell(progress, stop, runner, ended, failures, done / seg.n_steps)
            return _outcome(runner.state(), done, ended, last)
        _tell(progress, stop, runner, ended, failures, (k_end - 1) / seg.n_steps)
        k = k_end
    if chunk is not None:  # the segment's last state, shown too (what it asks for is not used)
        chunk(runner.state(), seg.n_steps + 1)
    return _outcome(runner.state(), seg.n_steps, ended, last)


def _met(stop, runner, rec: np.ndarray, k: int, before: bool,
         ended: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The points (B,) a criterion ends in a chunk (increments k.., records ``rec``), not
    ``ended`` before, and each point's end (exclusive, see :func:`_first_met`)."""
    B = len(ended)
    if stop is None:
        return np.zeros(B, bool), np.full(B, k + len(rec))
    if runner.evaluates_stop:
        return (runner.met_at >= k) & ~ended, runner.met_at + (0 if before else 1)
    return _first_met(stop, rec, k, before, ended)


def _outcome(state: RevState, increments: int, ended: np.ndarray, last: np.ndarray) -> SegmentOutcome:
    if not ended.any():
        return SegmentOutcome(state, increments)
    return SegmentOutcome(state, increments, row_values(last), ended.copy())


def _first_met(stop, rec: np.ndarray, k: int, before: bool,
               ended: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The points (B,) whose new states of a chunk (records (K, B, 2n + 4) of increments k..)
    meet ``stop`` (see :func:`run_segment`), and each one's end: the increment after its first
    such state (``before``: that state's own), exclusive."""
    K, B = rec.shape[:2]
    met = stop(row_values(rec.reshape(K * B, -1)))
    if met is None:
        return np.zeros(B, bool), np.full(B, k + K)
    met = np.broadcast_to(np.asarray(met, bool), (K * B,)).reshape(K, B)
    met = met & np.isfinite(rec[..., 0]) & ~ended  # rows of no state (dropped, ended) meet nothing
    hit = met.any(axis=0)
    return hit, k + met.argmax(axis=0) + (0 if before else 1)


def _tell(progress: Progress, stop, runner, ended: np.ndarray, failures: dict | None,
          fraction: float) -> None:
    """``progress`` of the increments' ``fraction``, or of how near the points are to the
    targets of a :class:`MeanStressReaches` criterion (the dropped and ended ones there)."""
    if progress is None:
        return
    if isinstance(stop, MeanStressReaches):
        gone = ended if not failures else ended | ~alive(len(ended), failures)
        fraction = stop.fraction(runner.state(), gone)
    progress(fraction)


def _record(recorder: Recorder | None, runner, rec: np.ndarray, stage: str, ks: np.ndarray,
            keep, failures: dict | None, points: np.ndarray | None = None) -> None:
    """Record the kept increments ``ks`` of a chunk, of the ``points`` (B,) mask (None: all):
    from the states where the backend keeps them (the solver's own columns too), else from the
    records (NaN rows: no state there)."""
    if recorder is None:
        return
    kept = keep(ks)
    if runner.states:
        for s, moved, k in zip(runner.states, runner.moved, kept):
            if k:
                recorder.record(s, stage, moved if points is None else moved & points)
        return
    n = (rec.shape[2] - len(FRACTIONS)) // 2
    rec = rec[kept]
    recorder.record_block(rec[:, :, :n], rec[:, :, n:2 * n], rec[:, :, 2 * n:], stage, points)


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
