"""Whole tests from parameters to result tables: the functions behind ``hmodel run``.

2D (hexagonal cells in the plane, :class:`~hmodel.rev.Rev`): :func:`run_isotropic`,
:func:`run_biaxial`, :func:`run_strain_path`. 3D (bi-hexagons on the sphere,
:class:`~hmodel.rev.rev3d.Rev3D`, axis 1 axial): :func:`run_triaxial` (drained or undrained,
compression or extension), :func:`run_true_triaxial` (constant p and b) and
:func:`run_oedometer` (K0), each from an isotropic consolidation to every ``p0``, run as the
stages of :data:`~hmodel.loading.stages.PRESETS_3D`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..cell import CellSolver
from ..errors import InputError
from ..limits import check_rows
from ..params import Params
from ..rev import Rev
from ..rev.contacts import cell_contacts, check_contacts, fabric
from ..rev.model3d import check_3d_param_sets, params_3d
from ..rev.rev3d import Rev3D
from ..rev.sphere import Sphere
from . import named_paths
from .named_paths import AXIAL_STEP, ISO_STEP, Progress
from .result import PathResult, Recorder, columns_for
from .segment import run_segment
from .stages import Stage, check_b


# ``solver``: a cell solver (None: the closed form); resolve a spec with hmodel.solvers.get_solver.
# ``params``: one Params for every material point, or one per point (hmodel.params.check_batch),
# broadcast against the list of pressures.
def _meta(params, rev: Rev, test: str, **extra) -> dict:
    meta = {"test": test, "params": rev.params.to_dict(), "solver": rev.solver.name, **extra}
    if rev.n_sets > 1:  # the parameters of each point, in point order
        meta["point_params"] = [s.to_dict() for s in rev.sets]
    return meta


def _table_rows(params, n_pressures: int, per_point: int) -> tuple[int, int]:
    """The material points of a test (one per parameter set or pressure) and the rows of its
    table known before it runs, ``per_point`` each (a stage's increments; a consolidation counts
    its final state only, its increments are known as it runs), refused over the rows limit
    (:func:`~hmodel.limits.check_rows`) before anything is built."""
    n_points = max(1 if isinstance(params, Params) else len(params), n_pressures)
    rows = n_points * per_point
    check_rows(rows, f"{n_points:,} material point{'s' if n_points != 1 else ''} × {per_point:,} "
                     f"row{'s' if per_point != 1 else ''}")
    return n_points, rows


def _check_table(rev, n_points: int, rows: int) -> None:
    """Refuse, before the run, ``n_points`` points whose cells and table of ``rows`` rows
    would not fit in the memory budget together."""
    rev.check_size(n_points, rows=rows, columns=len(columns_for(rev.n_components)))


def run_isotropic(params: Params | Sequence[Params], p0, *, solver: CellSolver | None = None,
                  step: float = ISO_STEP, progress: Progress = None) -> PathResult:
    """Isotropic compression of one material point per value of ``p0`` [Pa]."""
    p0 = np.atleast_1d(np.asarray(p0, float))
    n_points, rows = _table_rows(params, len(p0), 1)
    rev = Rev(params, solver)
    _check_table(rev, n_points, rows)
    rec = Recorder(_meta(params, rev, "iso", p0=p0.tolist(), iso_step=step), rev.solver_fractions)
    named_paths.consolidate(rev, p0, step=step, recorder=rec, progress=progress)
    return rec.result()


def run_biaxial(params: Params | Sequence[Params], p0, axial_strain: float, *, undrained: bool = False,
                solver: CellSolver | None = None, iso_step: float = ISO_STEP,
                step: float = AXIAL_STEP, progress: Progress = None,
                drop_failed: bool = False, compiled: bool | None = None,
                contact_fabric: bool = False) -> PathResult:
    """Isotropic consolidation to each ``p0`` [Pa], then drained or undrained biaxial
    compression to ``axial_strain`` more axial strain (report §1.1.2, Fig. 1.7).

    With ``drop_failed``, a point whose Newton fails is dropped and the others go on; the
    result's ``meta["failed"]`` maps each dropped point to the reason (its rows stop there).
    ``compiled``: None (the compiled kernel where the cell solver has one) or False (the
    generic driver, e.g. to time or check the two against each other). ``contact_fabric``:
    the fabric of every point's contacts after consolidation and at the end, in
    ``meta["contact_fabric"]`` (:func:`contact_fabrics`; docs/model3d.md, "Contact fabric")."""
    n = named_paths.strain_steps(axial_strain, step, "axial strain")  # refused before any work
    p0 = np.atleast_1d(np.asarray(p0, float))
    n_points, rows = _table_rows(params, len(p0), n + 1)
    rev = Rev(params, solver)
    _check_table(rev, n_points, rows)
    rec = Recorder(_meta(params, rev, "undrained biaxial" if undrained else "drained biaxial",
                         p0=p0.tolist(), axial_strain=axial_strain, iso_step=iso_step, step=step),
                   rev.solver_fractions)

    def shear(state, p0, progress, failures):
        return named_paths.biaxial(rev, state, axial_strain, undrained=undrained, lateral_stress=p0,
                                   step=step, recorder=rec, progress=progress, failures=failures,
                                   compiled=compiled)
    _consolidate_then(rev, rec, p0, shear, iso_step=iso_step, progress=progress,
                      drop_failed=drop_failed, compiled=compiled, contact_fabric=contact_fabric)
    return rec.result()


def _consolidate_then(rev, rec: Recorder, p0: np.ndarray, shear, *, iso_step: float,
                      progress: Progress, drop_failed: bool, compiled: bool | None,
                      contact_fabric: bool = False) -> None:
    """Isotropic consolidation of ``rev``'s points to each ``p0`` (the first tenth of the
    progress), then ``shear(state, p0 per point (B,), progress, failures)``; with
    ``drop_failed``, the points that fail are dropped and listed in ``rec.meta["failed"]``;
    with ``contact_fabric``, the fabric of every point's contacts at the end of each stage in
    ``rec.meta["contact_fabric"]`` (:func:`contact_fabrics`)."""
    consolidation = None if progress is None else (lambda f: progress(0.1 * f))
    rest = None if progress is None else (lambda f: progress(0.1 + 0.9 * f))
    failures = {} if drop_failed else None
    if contact_fabric:
        check_contacts(rev)  # before any work
    state = named_paths.consolidate(rev, p0, step=iso_step, recorder=rec, progress=consolidation,
                                    failures=failures, compiled=compiled)
    consolidated = contact_fabrics(rev, state, failures) if contact_fabric else None
    end = shear(state, np.broadcast_to(p0, state.n_points).copy(), rest, failures)
    if contact_fabric:
        rec.meta["contact_fabric"] = {"consolidated": consolidated, "final": contact_fabrics(rev, end, failures)}
    if drop_failed:
        rec.meta["failed"] = {int(b): why for b, why in sorted(failures.items())}


def contact_fabrics(rev, state, failures: dict | None = None) -> list[dict | None]:
    """The fabric of each point's carrying contacts in ``state`` (:func:`hmodel.rev.contacts.fabric`
    of :func:`hmodel.rev.contacts.cell_contacts`, axis 1, as plain numbers), None for a point
    dropped (in ``failures``), not finite, or force-free."""
    out = []
    for b in range(state.n_points):
        if (failures and b in failures) or not np.all(np.isfinite(state.eps[b])):
            out.append(None)
            continue
        contacts = cell_contacts(rev, state, b)
        out.append(fabric(contacts).as_dict() if np.any(contacts.fn > 0.0) else None)
    return out


def run_strain_path(params: Params | Sequence[Params], eps, *, solver: CellSolver | None = None,
                    max_step: float | None = None, progress: Progress = None) -> PathResult:
    """Follow a table of cumulative strains (n, 2 or 3) from the unloaded state."""
    eps = np.asarray(eps, float)
    if eps.ndim == 2 and eps.shape[1] == 2:
        eps = np.column_stack([eps, np.zeros(len(eps))])
    n_points, rows = _table_rows(params, 1, len(eps) if eps.ndim else 1)
    rev = Rev(params, solver)
    _check_table(rev, n_points, rows)
    rec = Recorder(_meta(params, rev, "strain path", n_rows=len(eps), max_step=max_step),
                   rev.solver_fractions)
    named_paths.strain_path(rev, eps, max_step=max_step, recorder=rec, progress=progress)
    return rec.result()


# ---------------------------------------------------------------------- 3D laboratory tests

def _run_3d(params, p0, test: str, rows, n_steps: int, *, sphere: Sphere | None,
            solver, iso_step: float, progress: Progress, drop_failed: bool,
            compiled: bool | None, contact_fabric: bool = False, **meta) -> Recorder:
    """Isotropic consolidation of a :class:`Rev3D` to each ``p0``, then the stage whose rows
    ``rows(p0)`` gives (p0 per point, (B,)) in ``n_steps`` increments, recorded as ``shear``;
    ``params`` None: the 3D model's defaults with this solver (:func:`~hmodel.rev.model3d.params_3d`)."""
    if params is None:
        params = params_3d(solver)
    check_3d_param_sets(params)
    p0 = np.atleast_1d(np.asarray(p0, float))
    n_points, n_rows = _table_rows(params, len(p0), n_steps + 1)
    rev = Rev3D(params, sphere, solver)
    _check_table(rev, n_points, n_rows)
    s = rev.sphere
    rec = Recorder(_meta(params, rev, test, p0=p0.tolist(), iso_step=iso_step, **meta,
                         sphere={"order": s.order, "n_azimuth": s.n_azimuth,
                                 "alpha_omega": s.alpha_omega, "axis": list(s.axis),
                                 "cells": rev.n_cells}),
                   rev.solver_fractions)

    def shear(state, p0, progress, failures):
        seg = Stage("shear", rows(p0), steps=n_steps).segment(state)
        return run_segment(rev, state, seg, rec, progress=progress, failures=failures, compiled=compiled).state
    _consolidate_then(rev, rec, p0, shear, iso_step=iso_step, progress=progress,
                      drop_failed=drop_failed, compiled=compiled, contact_fabric=contact_fabric)
    return rec


_SHEARS = {"eps23": 0.0, "eps13": 0.0, "eps12": 0.0}
#: How a drained triaxial test holds its sides (:func:`run_triaxial`): each lateral stress
#: (``free``, the preset ``drained``) or one radial strain and the radial stress (``equal``).
RADIAL = ("free", "equal")


def check_radial(radial: str) -> str:
    """``radial`` if it is one of :data:`RADIAL`, else a one-line InputError."""
    if radial not in RADIAL:
        raise InputError(f"radial must be one of {', '.join(RADIAL)}, got {radial!r}")
    return radial


def triaxial_rows(axial: float, p0, undrained: bool = False, radial: str = "free") -> dict:
    """The rows of a triaxial test's shear stage along axis 1 (:data:`~hmodel.loading.stages.ROWS_3D`),
    the shear strains held: ``axial`` of ε11 (negative in extension), then ε_v = ε22 − ε33 = 0
    (``undrained``), σ22 = σ33 = ``p0`` (drained, ``radial="free"``) or ε22 = ε33 with the radial
    stress (σ22 + σ33)/2 = ``p0`` (``radial="equal"``)."""
    if undrained:
        return {"eps11": axial, "eps_v": 0.0, "eps22-eps33": 0.0, **_SHEARS}
    if radial == "equal":
        return {"eps11": axial, "sig_r": p0, "eps22-eps33": 0.0, **_SHEARS}
    return {"eps11": axial, "sig22": p0, "sig33": p0, **_SHEARS}


def default_radial(params: Params | Sequence[Params] | None) -> str:
    """The sides of a drained triaxial test where none are named: ``equal`` (one radial strain)
    where a parameter set makes the bi-hexagons follow the lateral strain about their axis
    (``lateral="axisymmetric"``: their lateral cells open and leave the REV no stiffness across
    the axis, so that free sides bifurcate, docs/mechanisms.md, "One radial strain"), ``free``
    (the preset, the published model's) otherwise."""
    sets = [params] if params is None or isinstance(params, Params) else list(params)
    return "equal" if any(isinstance(p, Params) and p.lateral == "axisymmetric" for p in sets) else "free"


def run_triaxial(params: Params | Sequence[Params] | None, p0, axial_strain: float, *,
                 undrained: bool = False, extension: bool = False, radial: str | None = None,
                 sphere: Sphere | None = None, solver=None, iso_step: float = ISO_STEP,
                 step: float = AXIAL_STEP, progress: Progress = None, drop_failed: bool = False,
                 compiled: bool | None = None, contact_fabric: bool = False) -> PathResult:
    """The triaxial test of the 3D H-model (axis 1 axial, the shear strains held): isotropic
    consolidation to each ``p0`` [Pa], then ``axial_strain`` (its magnitude) of axial
    compression, or with ``extension`` of axial unloading (σ11 < σ22 = σ33), drained (σ22 =
    σ33 = p0) or undrained (eps_v = 0, eps22 = eps33): the ``drained`` and ``undrained``
    stages of :data:`~hmodel.loading.stages.PRESETS_3D`.

    ``radial`` (:data:`RADIAL`): how the drained test holds the sides. ``free`` (the preset):
    σ22 and σ33 each held at p0, each lateral strain free. ``equal``: one radial strain, a
    cylinder's (ε22 = ε33), and the radial stress (σ22 + σ33)/2 held at p0, as the undrained
    test always has it. None: :func:`default_radial` of the parameters (``equal`` where they
    set ``lateral="axisymmetric"``, else ``free``). They are one test wherever the material
    answers an axisymmetric strain with an axisymmetric stress and its lateral tangent is
    definite; where a REV's cells leave it no stiffness across the axis (force-free lateral
    cells, docs/mechanisms.md, "One radial strain"), the free test may bifurcate, σ22 = σ33
    holding at unequal lateral strains that round-off picks.

    ``params``: one Params for every material point, or one per point, used as given (their
    ``sliding_rhs`` included: ``Params()`` is the report's λ, with which this test stops near
    1 % axial strain); None: the 3D model's defaults, ``sliding_rhs="equilibrium"`` or a learned
    cell's own (:func:`~hmodel.rev.model3d.params_3d`, which also builds them with other values,
    as ``hmodel run triaxial`` does). ``sphere``: the directions, azimuths and fabric (default
    ``Sphere()``); ``solver``: a 3D cell solver, or a 2D H-cell solver stepping the hexagons of
    every bi-hexagon (default the closed-form bi-hexagon;
    :func:`~hmodel.rev.model3d.cell_solver_3d`). ``drop_failed``, ``compiled``: as
    :func:`run_biaxial`. The result has the 3D columns of
    :func:`~hmodel.loading.result.columns_for` (q = σ11 - (σ22 + σ33)/2, negative in
    extension; the Lode angle and b)."""
    n = named_paths.strain_steps(axial_strain, step, "axial strain")  # refused before any work
    radial = check_radial(default_radial(params) if radial is None else radial)
    d = -axial_strain if extension else axial_strain

    def rows(p0):
        return triaxial_rows(d, p0, undrained, radial)
    test = f"{'undrained' if undrained else 'drained'} triaxial {'extension' if extension else 'compression'}"
    rec = _run_3d(params, p0, test, rows, n, sphere=sphere, solver=solver, iso_step=iso_step,
                     progress=progress, drop_failed=drop_failed, compiled=compiled,
                     contact_fabric=contact_fabric, axial_strain=axial_strain, step=step,
                     **({"radial": radial} if radial != "free" else {}))
    return rec.result()


def run_true_triaxial(params: Params | Sequence[Params] | None, p0, b: float, axial_strain: float, *,
                      sphere: Sphere | None = None, solver=None, iso_step: float = ISO_STEP,
                      step: float = AXIAL_STEP, progress: Progress = None,
                      drop_failed: bool = False, compiled: bool | None = None,
                      contact_fabric: bool = False) -> PathResult:
    """The drained true triaxial test at constant mean stress p = p0 and constant b: isotropic
    consolidation to each ``p0`` [Pa], then ``axial_strain`` of compression along axis 1 (the
    major principal stress) with the rows p = p0, (σ22 - σ33) - b (σ11 - σ33) = 0 (the
    principal axes stay 1, 2, 3 with σ11 >= σ22 >= σ33) and the shear strains held: the
    ``true_triaxial`` stage of :data:`~hmodel.loading.stages.PRESETS_3D`. Its Lode angle is
    atan(√3 b / (2 - b)) (0° at b = 0, triaxial compression; 60° at b = 1, extension).
    Other arguments: as :func:`run_triaxial`."""
    b = check_b(b, "true triaxial test")
    n = named_paths.strain_steps(axial_strain, step, "axial strain")
    rec = _run_3d(params, p0, "true triaxial", lambda p0: {"eps11": axial_strain, "p": p0, "b": b,
                                                              **_SHEARS},
                     n, sphere=sphere, solver=solver, iso_step=iso_step, progress=progress,
                     drop_failed=drop_failed, compiled=compiled, contact_fabric=contact_fabric, b=b,
                     axial_strain=axial_strain,
                     step=step)
    return rec.result()


def run_oedometer(params: Params | Sequence[Params] | None, p0, axial_strain: float, *,
                  sphere: Sphere | None = None, solver=None, iso_step: float = ISO_STEP,
                  step: float = AXIAL_STEP, progress: Progress = None, drop_failed: bool = False,
                  compiled: bool | None = None, contact_fabric: bool = False) -> PathResult:
    """Oedometric compression of the 3D H-model: isotropic consolidation to each ``p0`` [Pa],
    then ``axial_strain`` along axis 1 with no lateral strain (eps22 = eps33 = 0, the shears
    held: the ``oedometric`` stage of :data:`~hmodel.loading.stages.PRESETS_3D`).

    The coefficient of earth pressure at rest K0 = σr/σa, σr = (σ22 + σ33)/2, σa = σ11, is
    the column ``K0`` of every row and, at the end of the test, ``meta["K0"]`` (one per point;
    NaN for a point dropped by ``drop_failed``). Other arguments: as :func:`run_triaxial`."""
    n = named_paths.strain_steps(axial_strain, step, "axial strain")
    rec = _run_3d(params, p0, "oedometer", lambda p0: {"eps11": axial_strain, "eps22": 0.0,
                                                                 "eps33": 0.0, **_SHEARS},
                            n, sphere=sphere, solver=solver, iso_step=iso_step, progress=progress,
                            drop_failed=drop_failed, compiled=compiled, contact_fabric=contact_fabric,
                            axial_strain=axial_strain,
                            step=step)
    result = rec.result()
    cols = dict(result.columns)
    with np.errstate(divide="ignore", invalid="ignore"):
        cols["K0"] = 0.5 * (cols["sig22"] + cols["sig33"]) / cols["sig11"]
    k0 = []
    for b in range(int(cols["point"].max()) + 1 if len(cols["point"]) else 0):
        rows = (cols["point"] == b) & (cols["stage"] == "shear")
        done = rows.any() and b not in rec.meta.get("failed", {})
        k0.append(float(cols["K0"][rows][-1]) if done else float("nan"))
    return PathResult(cols, {**result.meta, "K0": k0})
