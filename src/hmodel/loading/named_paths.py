"""Loading paths at the material point (report §1.1.2), for a batch of material points.

Every path is a sequence of increments, each solved by :func:`solve_increment` (mixed control)
or applied directly (pure strain control). Default increments are converged: halving them
changes the peak stress ratio and the volumetric strain at 10 % axial strain by less than
0.1 % (``test_default_step_is_converged`` and ``test_first_order_convergence_rate`` in
``tests/test_loading.py``).

A ``progress`` callable, when given, receives the completed fraction of the path (0..1).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError, SolverError
from ..limits import check_count, steps_for
from ..rev import Rev, RevState
from ..rev.state import normal_components
from .result import COMPONENTS, Recorder
from .segment import MeanStressReaches, Progress, Segment, alive, run_segment
from .stages import AXIAL_STEP, Stage

#: Default strain increment of the isotropic compression (each of eps11, eps22).
ISO_STEP = 1e-5
#: Largest strain-component increment of one cell update along a strain path.
MAX_STRAIN_STEP = 1e-4


def _as_points(value, name: str) -> np.ndarray:
    arr = np.atleast_1d(np.asarray(value, dtype=float))
    if arr.ndim != 1 or not np.all(np.isfinite(arr)):
        raise InputError(f"{name} must be finite numbers, got {value!r}")
    return arr


def consolidate(rev: Rev, p0, state: RevState | None = None, step: float = ISO_STEP,
                recorder: Recorder | None = None, progress: Progress = None,
                max_steps: int = 1_000_000, failures: dict | None = None,
                compiled: bool | None = None) -> RevState:
    """Isotropic compression: equal strain increments until the mean stress reaches ``p0``.

    Each material point b stops at its own ``p0[b]`` [Pa]: the segment of
    :func:`compression_segment`, each point ending before the increment that would reach it
    (:class:`~hmodel.loading.segment.MeanStressReaches`), then one increment solved (mixed
    control on p, :func:`isotropic_segment`) so that p = p0 exactly (``failures`` and
    ``compiled``: see :func:`~hmodel.loading.segment.run_segment`).
    """
    p0 = _as_points(p0, "p0")
    if np.any(p0 <= 0):
        raise InputError(f"p0 must be positive, got {p0.tolist()}")
    if not (step > 0 and math.isfinite(step)):
        raise InputError(f"isotropic strain step must be a positive finite number, got {step}")
    state = state if state is not None else rev.initial(len(p0))
    if len(p0) not in (1, state.n_points):
        raise InputError(f"{len(p0)} pressures for {state.n_points} material points")
    p0 = np.broadcast_to(p0, state.n_points).copy()  # one pressure for every parameter set
    out = run_segment(rev, state, compression_segment(rev, step, max_steps), recorder,
                      stop=MeanStressReaches(p0), stop_before=True, progress=progress,
                      failures=failures, compiled=compiled)
    state = out.state
    short = ~(out.stopped if out.stopped is not None else np.zeros(state.n_points, bool))
    if failures:
        short &= alive(state.n_points, failures)
    if short.any():
        raise SolverError(f"isotropic compression did not reach p0 within {max_steps} steps "
                          f"(p = {state.p.tolist()} Pa at strain {state.eps[:, 0].tolist()})")
    # (a segment of one increment: compiled where the solver allows it)
    state = run_segment(rev, state, isotropic_segment(state, p0), failures=failures,
                        compiled=None if compiled is not False else False).state
    if recorder is not None:
        recorder.record(state, "consolidation", alive(state.n_points, failures))
    return state


def compression_segment(rev: Rev, step: float, max_steps: int) -> Segment:
    """At most ``max_steps`` isotropic strain increments: ``step`` on every normal component,
    no shear; a criterion ends it (:func:`consolidate`)."""
    n = rev.n_components
    values = np.zeros(n)
    values[:normal_components(n)] = step
    return Segment((False,) * n, np.eye(n), values, max_steps, "consolidation", per_increment=True)


def isotropic_segment(state: RevState, p0: np.ndarray) -> Segment:
    """One increment to the mean stress ``p0`` (B,) with equal normal strain increments and no
    shear strain: rows deps11 - deps22 = 0 (and deps22 - deps33 = 0 in 3D), p = p0, the
    shear strains held."""
    n = state.n_components
    normal = normal_components(n)
    M = np.zeros((n, n))
    for i in range(normal - 1):
        M[i, i], M[i, i + 1] = 1.0, -1.0
    M[normal - 1, :normal] = 1.0 / normal
    M[normal:, normal:] = np.eye(n - normal)
    values = np.zeros((state.n_points, n))
    values[:, normal - 1] = p0
    return Segment(tuple(r == normal - 1 for r in range(n)), M, values, 1, "consolidation")


def strain_steps(total: float, step: float, name: str) -> int:
    """Increments of at most ``step`` covering the strain ``total`` of ``name``, within the
    increments limit (:func:`hmodel.limits.max_increments`)."""
    if not math.isfinite(total) or total <= 0:
        raise InputError(f"{name} must be a positive finite strain, got {total}")
    if not (step > 0 and math.isfinite(step)):
        raise InputError(f"strain step must be a positive finite number, got {step}")
    return steps_for(total, step, f"{name} {total:g} in steps of {step:g}")


def biaxial(rev: Rev, state: RevState, axial_strain: float, undrained: bool = False,
            lateral_stress=None, step: float = AXIAL_STEP, recorder: Recorder | None = None,
            progress: Progress = None, failures: dict | None = None,
            compiled: bool | None = None) -> RevState:
    """Biaxial compression from ``state`` to ``axial_strain`` more axial strain.

    Drained: constant lateral stress sig22 = ``lateral_stress`` (default: the current sig22),
    solved by Newton on deps22 each increment. Undrained: isochoric, deps22 = -deps11.
    eps12 is held (rigid platens). ``failures``, ``compiled``: see :func:`run_segment`.
    """
    sig22 = None if lateral_stress is None else _as_points(lateral_stress, "lateral stress")
    seg = biaxial_segment(state, axial_strain, strain_steps(axial_strain, step, "axial strain"),
                          undrained, sig22)
    return run_segment(rev, state, seg, recorder, progress=progress, failures=failures,
                       compiled=compiled).state


def biaxial_segment(state: RevState, axial_strain: float, n_steps: int, undrained: bool = False,
                    lateral_stress=None, stage: str = "shear") -> Segment:
    """``axial_strain`` more axial strain in ``n_steps``, eps12 held: drained at lateral stress
    sig22 = ``lateral_stress`` (default: the current sig22), or undrained (deps22 = -deps11):
    the ``drained`` and ``undrained`` stages of :data:`~hmodel.loading.stages.PRESETS`."""
    if undrained:
        rows = {"eps11": axial_strain, "eps_v": 0.0, "eps12": 0.0}
    else:
        rows = {"eps11": axial_strain, "sig22": "hold" if lateral_stress is None else lateral_stress,
                "eps12": 0.0}
    return Stage(stage, rows, steps=n_steps).segment(state)


def oedometric(rev: Rev, state: RevState, axial_strain: float, step: float = AXIAL_STEP,
               recorder: Recorder | None = None, progress: Progress = None) -> RevState:
    """Oedometric compression: deps22 = deps12 = 0 (the ``oedometric`` stage)."""
    return _run(rev, state, {"eps11": axial_strain, "eps22": 0.0, "eps12": 0.0},
                strain_steps(axial_strain, step, "axial strain"), "oedometric", recorder, progress)


def constant_p(rev: Rev, state: RevState, axial_strain: float, step: float = AXIAL_STEP,
               recorder: Recorder | None = None, progress: Progress = None) -> RevState:
    """Axial compression at constant mean stress p = (sig11 + sig22)/2 (its current value; the
    ``constant_p`` stage)."""
    return _run(rev, state, {"eps11": axial_strain, "p": "hold", "eps12": 0.0},
                strain_steps(axial_strain, step, "axial strain"), "constant-p", recorder, progress)


def proportional(rev: Rev, state: RevState, direction, magnitude: float,
                 step: float = MAX_STRAIN_STEP, recorder: Recorder | None = None,
                 progress: Progress = None) -> RevState:
    """Proportional strain path: deps = magnitude * direction/|direction|, in equal steps (the
    ``proportional`` stage)."""
    d = np.asarray(direction, float)
    if d.shape != (3,) or not np.all(np.isfinite(d)) or not np.any(d):
        raise InputError(f"strain direction must be 3 finite numbers, not all zero, got {direction!r}")
    rows = dict(zip(("eps11", "eps22", "eps12"), magnitude * d / np.linalg.norm(d)))
    return _run(rev, state, rows, strain_steps(magnitude, step, "strain magnitude"), "proportional",
                recorder, progress)


def _run(rev, state, rows, n_steps, name, recorder, progress) -> RevState:
    """The stage of ``rows`` in ``n_steps`` increments, run on every point of ``state``."""
    seg = Stage(name, rows, steps=n_steps).segment(state)
    return run_segment(rev, state, seg, recorder, progress=progress).state


def strain_path(rev: Rev, eps: np.ndarray, state: RevState | None = None,
                max_step: float | None = None, recorder: Recorder | None = None,
                progress: Progress = None) -> RevState:
    """Follow cumulative strains ``eps`` (rows, n), one recorded state per row (n: the REV's
    components, :data:`~hmodel.loading.result.COMPONENTS`).

    Each row is reached from the previous one (the unloaded state for the first) in a segment
    of one increment, split into equal sub-steps when ``max_step`` is given and a strain
    component changes by more than it; the state is then put at the row's strain exactly (its
    stress recomputed there). The segments run on the generic driver, whose states are
    :meth:`Rev.step`'s (the compiled 3D trial agrees with it to round-off only).
    """
    eps = np.asarray(eps, dtype=float)
    names = ", ".join(f"eps{c}" for c in COMPONENTS[rev.n_components])
    if eps.ndim != 2 or eps.shape[1] != rev.n_components or not np.all(np.isfinite(eps)):
        raise InputError(f"strain path must be finite numbers in rows of ({names})")
    state = state if state is not None else rev.initial(1)
    prev = state.eps[0].copy()
    changes = np.abs(np.diff(np.vstack([prev, eps]), axis=0)).max(axis=1)
    subs = [1 if not max_step else steps_for(c, max_step, f"strain path row {i + 1}")
            for i, c in enumerate(changes)]
    check_count(sum(subs), "increments of the strain path")
    rows = (False,) * rev.n_components
    for i, (row, n) in enumerate(zip(eps, subs)):
        seg = Segment(rows, np.eye(rev.n_components), row - prev, n, "path")
        state = run_segment(rev, state, seg, compiled=False).state
        state = RevState(state.cells, state.flags, np.broadcast_to(row, state.eps.shape).copy(),
                         rev.stress(state.cells, row[None, :]))
        prev = row
        if recorder is not None:
            recorder.record(state, "path")
        if progress is not None:
            progress((i + 1) / len(eps))
    return state
