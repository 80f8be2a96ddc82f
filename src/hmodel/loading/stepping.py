"""One loading stage run in chunks of increments, stopping where a criterion is first met.

A stage is a :class:`~hmodel.loading.paths.Segment` (report §1.1.2: three constraint rows,
strain changes spread evenly, stress targets moved linearly). It runs in the compiled kernel
where the REV's solver allows it (:class:`~hmodel.loading.compiled.CompiledSegment`), in
chunks; before each chunk the runner's arrays are copied. When a stopping criterion is met at
row j of a chunk, the runner goes back to the copy and runs exactly the increments up to j:
the same increments from the same state give the same states, so the stage ends on the first
state that meets the criterion, and the cost is at most one chunk run twice. Without a
compiled increment the generic driver (:func:`~hmodel.loading.control.solve_increment`) runs
one increment per chunk, so nothing is re-run.

An increment that cannot be solved (a stress target the material cannot carry) ends the stage
with :class:`StageFailed`, after every increment before it has been recorded.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import SolverError
from ..rev import Rev, RevState
from .compiled import CompiledSegment, supports
from .control import Control, Tangent, solve_increment
from .newton import NewtonSettings
from .paths import Segment
from .result import FRACTIONS, Recorder

#: Increments per chunk of the compiled kernel (a criterion re-runs at most one chunk).
CHUNK = 100


class StageFailed(SolverError):
    """An increment of a stage could not be solved: ``increment`` (1-based) of the stage, the
    solver's reason in the message; the states before it are recorded."""

    def __init__(self, message: str, increment: int):
        super().__init__(message)
        self.increment = increment


def row_values(rec: np.ndarray) -> dict[str, np.ndarray]:
    """Columns of the result table (see :data:`~hmodel.loading.result.COLUMNS`) from kernel
    records (K, 10) of one point: eps (3), sig (3), the cell fractions (4)."""
    sig = rec[:, 3:6]
    p, q = 0.5 * (sig[:, 0] + sig[:, 1]), sig[:, 0] - sig[:, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        q_p = np.where(p != 0, q / np.where(p != 0, p, 1.0), 0.0)
    cols = {"eps11": rec[:, 0], "eps22": rec[:, 1], "eps12": rec[:, 2], "sig11": sig[:, 0],
            "sig22": sig[:, 1], "sig12": sig[:, 2], "p": p, "q": q, "eps_v": rec[:, 0] + rec[:, 1],
            "q_p": q_p}
    cols.update({c: rec[:, 6 + j] for j, c in enumerate(FRACTIONS)})
    return cols


class _GenericSegment:
    """The interface of :class:`CompiledSegment` (run, state, snapshot, restore) over the
    generic driver, for cell solvers without a compiled increment."""

    def __init__(self, rev: Rev, state: RevState, seg: Segment, start: np.ndarray, end: np.ndarray,
                 tangent: Tangent, settings: NewtonSettings):
        self.rev, self.seg, self.start, self.end = rev, seg, start, end
        self.tangent, self.settings = tangent, settings
        self._state = state

    def run(self, k_begin: int, k_end: int) -> np.ndarray:
        S = np.array(self.seg.stress_rows)
        rec = np.empty((k_end - k_begin, self._state.n_points, 10))
        for k in range(k_begin, k_end):
            control = Control.of_step(S, self.seg.matrix, self.start, self.end, k, self.seg.n_steps)
            self._state = solve_increment(self.rev, self._state, control, self.tangent, self.settings)
            fr = self._state.fractions()
            rec[k - k_begin] = np.column_stack([self._state.eps, self._state.sig,
                                                *[fr[c] for c in FRACTIONS]])
        return rec

    def state(self) -> RevState:
        return self._state

    def snapshot(self):
        t = self.tangent
        return self._state, (None if t.K is None else t.K.copy()), (None if t.previous is None else t.previous.copy())

    def restore(self, snap) -> None:
        self._state, self.tangent.K, self.tangent.previous = snap


@dataclass
class StageOutcome:
    """How a stage ended: its final state, the increments run, and where a criterion ended it
    early, the columns (:func:`row_values`, arrays of one row) of the state that met it."""

    state: RevState
    increments: int
    met: dict[str, np.ndarray] | None = None


def run_stage(rev: Rev, state: RevState, seg: Segment, recorder: Recorder,
              stop: Callable[[dict[str, np.ndarray]], np.ndarray] | None = None,
              chunk: Callable[[RevState, int], int] | None = None,
              progress: Callable[[int], None] | None = None,
              tangent: Tangent | None = None,
              settings: NewtonSettings = NewtonSettings()) -> StageOutcome:
    """Run ``seg`` on one material point, recording every state into ``recorder``.

    ``stop(columns)`` gets the columns (:func:`row_values`) of a chunk of new states and returns
    for each row whether a criterion is met (or None: never); the stage ends on the first such
    state (``StageOutcome.met``: its columns).
    ``chunk(state, k)``, when given, is asked before increment k for the number of increments
    to run before it is asked again (a stability analysis probes the state between chunks), and
    shown the last state with k = n_steps + 1 (where a criterion ends the stage, it is not); in
    a chunk that fails, it is shown every state before the failing increment.
    ``progress(n)`` is told of every n increments done. Raises :class:`StageFailed`.
    """
    S = np.array(seg.stress_rows)
    B = state.n_points
    end = np.broadcast_to(np.asarray(seg.values, float), (B, 3))
    start = state.sig @ np.asarray(seg.matrix, float).T
    tangent = tangent or Tangent()
    if supports(rev):
        runner = CompiledSegment(rev, state, S, seg.matrix, start, end, seg.n_steps, tangent, settings)
        default = CHUNK
    else:
        runner = _GenericSegment(rev, state, seg, start, end, tangent, settings)
        default = 1
    k = 1
    while k <= seg.n_steps:
        size = chunk(runner.state(), k) if chunk is not None else default
        k_end = min(k + max(1, int(size)), seg.n_steps + 1)
        snap = runner.snapshot()
        try:
            rec = runner.run(k, k_end)
        except SolverError:
            runner.restore(snap)
            _one_by_one(runner, k, k_end, recorder, seg.stage, chunk)  # raises where it fails
            raise AssertionError("a failed chunk ran through one increment at a time") from None
        met = stop(row_values(rec[:, 0])) if stop is not None else None
        hit = np.flatnonzero(met) if met is not None else np.empty(0, int)
        if len(hit):
            j = int(hit[0])
            if j + 1 < len(rec):  # back to the chunk's start, then exactly up to the crossing
                runner.restore(snap)
                rec = runner.run(k, k + j + 1)
            _record(recorder, rec, seg.stage)
            if progress is not None:
                progress(j + 1)
            return StageOutcome(runner.state(), k + j, row_values(rec[-1:, 0]))
        _record(recorder, rec, seg.stage)
        if progress is not None:
            progress(k_end - k)
        k = k_end
    if chunk is not None:  # the stage's last state, shown too (what it asks for is not used)
        chunk(runner.state(), seg.n_steps + 1)
    return StageOutcome(runner.state(), seg.n_steps)


def _record(recorder: Recorder, rec: np.ndarray, stage: str) -> None:
    recorder.record_block(rec[:, :, :3], rec[:, :, 3:6], rec[:, :, 6:], stage)


def _one_by_one(runner, k_begin: int, k_end: int, recorder: Recorder, stage: str, chunk=None) -> None:
    """Increments k_begin..k_end-1 one at a time, each recorded, until the one that fails;
    ``chunk`` (see :func:`run_stage`) is shown every state before it, the last converged one
    included (where a stability analysis matters most)."""
    for k in range(k_begin, k_end):
        if chunk is not None and k > k_begin:
            chunk(runner.state(), k)
        try:
            rec = runner.run(k, k + 1)
        except SolverError as e:
            raise StageFailed(" ".join(str(e).split()), k) from None
        _record(recorder, rec, stage)
