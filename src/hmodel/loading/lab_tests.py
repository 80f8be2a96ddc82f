"""Whole tests from parameters to result tables: the functions behind ``hmodel run``."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..cell import CellSolver
from ..params import Params
from ..rev import Rev
from . import named_paths
from .named_paths import AXIAL_STEP, ISO_STEP, Progress
from .result import PathResult, Recorder


# ``solver``: a cell solver (None: the closed form); resolve a spec with hmodel.solvers.get_solver.
# ``params``: one Params for every material point, or one per point (hmodel.params.check_batch),
# broadcast against the list of pressures.
def _meta(params, rev: Rev, test: str, **extra) -> dict:
    meta = {"test": test, "params": rev.params.to_dict(), "solver": rev.solver.name, **extra}
    if rev.n_sets > 1:  # the parameters of each point, in point order
        meta["point_params"] = [s.to_dict() for s in rev.sets]
    return meta


def run_isotropic(params: Params | Sequence[Params], p0, *, solver: CellSolver | None = None,
                  step: float = ISO_STEP, progress: Progress = None) -> PathResult:
    """Isotropic compression of one material point per value of ``p0`` [Pa]."""
    rev = Rev(params, solver)
    p0 = np.atleast_1d(np.asarray(p0, float))
    rec = Recorder(_meta(params, rev, "iso", p0=p0.tolist(), iso_step=step), rev.solver_fractions)
    named_paths.consolidate(rev, p0, step=step, recorder=rec, progress=progress)
    return rec.result()


def run_biaxial(params: Params | Sequence[Params], p0, axial_strain: float, *, undrained: bool = False,
                solver: CellSolver | None = None, iso_step: float = ISO_STEP,
                step: float = AXIAL_STEP, progress: Progress = None,
                drop_failed: bool = False, compiled: bool | None = None) -> PathResult:
    """Isotropic consolidation to each ``p0`` [Pa], then drained or undrained biaxial
    compression to ``axial_strain`` more axial strain (report §1.1.2, Fig. 1.7).

    With ``drop_failed``, a point whose Newton fails is dropped and the others go on; the
    result's ``meta["failed"]`` maps each dropped point to the reason (its rows stop there).
    ``compiled``: None (the compiled kernel where the cell solver has one) or False (the
    generic driver, e.g. to time or check the two against each other)."""
    named_paths.strain_steps(axial_strain, step, "axial strain")  # refused before any work
    rev = Rev(params, solver)
    p0 = np.atleast_1d(np.asarray(p0, float))
    rec = Recorder(_meta(params, rev, "undrained biaxial" if undrained else "drained biaxial",
                         p0=p0.tolist(), axial_strain=axial_strain, iso_step=iso_step, step=step),
                   rev.solver_fractions)
    consolidation = None if progress is None else (lambda f: progress(0.1 * f))
    shear = None if progress is None else (lambda f: progress(0.1 + 0.9 * f))
    failures = {} if drop_failed else None
    state = named_paths.consolidate(rev, p0, step=iso_step, recorder=rec, progress=consolidation,
                              failures=failures, compiled=compiled)
    p0 = np.broadcast_to(p0, state.n_points)
    named_paths.biaxial(rev, state, axial_strain, undrained=undrained, lateral_stress=p0, step=step,
                  recorder=rec, progress=shear, failures=failures, compiled=compiled)
    if drop_failed:
        rec.meta["failed"] = {int(b): why for b, why in sorted(failures.items())}
    return rec.result()


def run_strain_path(params: Params | Sequence[Params], eps, *, solver: CellSolver | None = None,
                    max_step: float | None = None, progress: Progress = None) -> PathResult:
    """Follow a table of cumulative strains (n, 2 or 3) from the unloaded state."""
    eps = np.asarray(eps, float)
    if eps.ndim == 2 and eps.shape[1] == 2:
        eps = np.column_stack([eps, np.zeros(len(eps))])
    rev = Rev(params, solver)
    rec = Recorder(_meta(params, rev, "strain path", n_rows=len(eps), max_step=max_step),
                   rev.solver_fractions)
    named_paths.strain_path(rev, eps, max_step=max_step, recorder=rec, progress=progress)
    return rec.result()
