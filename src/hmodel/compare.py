"""Closed form against another cell solver at the macro scale (report §3.1), measured honestly.

Every comparison path (a loading recipe of ``hmodel.loading.comparison_paths``) runs twice from the same
parameters and increments, once per solver, and records the stress-strain curves and the wall
time of each run. Deviations are measured row by row on the shear part of the path (rows
correspond: same increments): the deviation of q relative to the peak |q| of the closed form
(maximum and RMS), and of the volumetric strain in strain units (maximum and RMS).

Paths (``standard_paths``, re-exported here): isotropic compression; drained biaxial at 100,
200 and 400 kPa; undrained biaxial; and three the report never tried: an unloading-reloading
cycle, oedometric compression and a path with rotating principal strain axes (ε12 ≠ 0).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from .cell import CellSolver
from .loading import PathSpec, Recorder, run_recipe
from .loading import standard_paths  # (also re-exported: the CLI, reproduce and tests)
from .loading.result import PathResult
from .params import Params
from .rev import Rev
from .solvers import get_solver


def run_path(params: Params, spec: PathSpec, solver: "str | CellSolver", step: float,
             iso_step: float) -> tuple[PathResult, float]:
    """One path with one solver: its result and wall time. A run that fails raises its
    SolverError with the rows recorded up to the failure as ``partial``."""
    from .errors import SolverError

    rev = Rev(params, get_solver(solver))
    rec = Recorder({"path": spec.name, "solver": rev.solver.name}, rev.solver_fractions)
    t = time.perf_counter()
    try:
        run_recipe(rev, spec, step, iso_step, rec)
    except SolverError as e:
        e.partial = rec.result()
        raise
    return rec.result(), time.perf_counter() - t


def warm_up(params: Params, solvers: "list[str | CellSolver]", step: float, iso_step: float) -> dict:
    """Run every comparison path once, shortened to two increments, with each solver; returns
    the seconds each took (solver name -> s). The first run of a compiled kernel includes its
    Numba compilation (tens of seconds on a fresh install); warmed up, the timed runs of
    :func:`compare_path` measure the computation only. A failure here is left to the timed run
    to report."""
    from .errors import SolverError

    seconds = {}
    for solver in solvers:
        solver = get_solver(solver)
        t = time.perf_counter()
        for spec in standard_paths(2 * step):
            try:
                run_path(params, spec, solver, step, max(iso_step, 1e-3))
            except SolverError:
                pass
        seconds[solver.name] = time.perf_counter() - t
    return seconds


def compare_path(params: Params, spec: PathSpec, other: "str | CellSolver", step: float,
                 iso_step: float, reference: "str | CellSolver" = "closed-form"
                 ) -> tuple[PathResult, PathResult | None, list[dict], dict]:
    """Both runs of one path: (reference, other or None, deviation rows, timings/status).

    ``reference`` is the closed form unless given (e.g. a REV of DEM cells, ``dem:hexagon-center``,
    against the surrogate that learned them). A run of the other solver that fails (a
    SolverError: the surrogate drove a cell or the mixed-control Newton out of bounds) is
    reported as such, with its message, not hidden."""
    from .errors import SolverError

    ref, t_ref = run_path(params, spec, reference, step, iso_step)
    try:
        res, t_other = run_path(params, spec, other, step, iso_step)
    except SolverError as e:
        return ref, None, [], {"seconds_reference": t_ref, "seconds_other": float("nan"),
                               "status": "failed: " + " ".join(str(e).split())[:200]}
    return ref, res, deviations(ref, res), {"seconds_reference": t_ref, "seconds_other": t_other,
                                             "status": "ok"}


def deviations(ref: PathResult, other: PathResult) -> list[dict]:
    """Per material point: max and RMS deviation of q (relative to peak |q|) and of eps_v.

    Rows are matched stage by stage (consolidation, then shear), by their index within the
    stage: a consolidation that reaches p0 one increment later (a slightly softer solver) must
    not shift every shear row against the other solver's.
    """
    out = []
    for b in range(ref.n_points):
        a, c = _by_stage(ref.point(b), other.point(b))
        qa, qc = a["q"], c["q"]
        peak = _q_scale(a)
        ev = c["eps_v"] - a["eps_v"]
        out.append({"point": b, "rows": len(qa), "peak_q": float(peak),
                    "q_max_dev_rel": float(np.abs(qc - qa).max(initial=0.0) / peak),
                    "q_rms_dev_rel": float(np.sqrt(np.mean((qc - qa) ** 2)) / peak) if len(qa) else 0.0,
                    "eps_v_max_dev": float(np.abs(ev).max(initial=0.0)),
                    "eps_v_rms_dev": float(np.sqrt(np.mean(ev ** 2))) if len(ev) else 0.0})
    return out


def _q_scale(a: dict) -> float:
    """What a deviation of q is relative to: the peak |q| of the reference, or on a path with no
    peak q (isotropic: q is round-off) the peak mean stress."""
    peak = np.abs(a["q"]).max(initial=0.0)
    if peak < 0.05 * np.abs(a["p"]).max(initial=0.0):
        peak = np.abs(a["p"]).max()
    return max(peak, 1e-12)


#: Least half-height of the q panels [kPa] and of the error panels [%]: round-off (the
#: isotropic path's q and errors) plots as a flat line on a readable scale rather than
#: magnified to fill the panel; the errors' maxima are written on it.
AXIS_Q_KPA, ERROR_AXIS_Q, ERROR_AXIS_EV = 1.0, 0.01, 1e-3


def _by_stage(a: PathResult, c: PathResult) -> tuple[dict, dict]:
    """q, p, eps_v, eps11 of the rows of both results matched stage by stage (index within a
    stage)."""
    stages = list(dict.fromkeys(np.asarray(a["stage"]).tolist()))
    keys = ("q", "p", "eps_v", "eps11")
    pa, pc = {k: [] for k in keys}, {k: [] for k in keys}
    for st in stages:
        sa, sc = a["stage"] == st, c["stage"] == st
        n = min(int(sa.sum()), int(sc.sum()))
        for k in pa:
            pa[k].append(np.asarray(a[k])[sa][:n])
            pc[k].append(np.asarray(c[k])[sc][:n])
    join = lambda d: {k: np.concatenate(v) if v else np.array([]) for k, v in d.items()}  # noqa: E731
    return join(pa), join(pc)


def _p0(r: PathResult) -> float:
    """Confining pressure of one point: the mean stress at the end of its consolidation."""
    c = r.stage("consolidation")["p"]
    return float(c[-1] if len(c) else r["p"][0])


def plot_overlay(name: str, ref: PathResult, other: PathResult, labels: tuple[str, str], path: Path) -> None:
    """The figure of :func:`overlay_figure`, written to ``path``."""
    overlay_figure(name, ref, other, labels).savefig(path, dpi=130)


def overlay_figure(name: str, ref: PathResult, other: PathResult, labels: tuple[str, str]) -> Figure:
    """q and volumetric strain against axial strain (or the path parameter), the stress path, and
    the errors: the second solver's Δq relative to the first's peak q (peak p where q has no
    peak, as in :func:`deviations`) and its Δεv, row by row within each stage, with their maxima."""
    fig = Figure(figsize=(19, 4.3), layout="constrained")
    axes = fig.subplots(1, 4)
    err_v = axes[3].twinx()
    worst_q = worst_v = 0.0
    scale_name = "peak q"
    for b in range(ref.n_points):
        for res, ls, lab in ((ref, "-", labels[0]), (other, "--", labels[1])):
            r = res.point(b)
            x = 100 * (r["eps11"] - r["eps11"][0]) if name != "rotation" else np.arange(len(r))
            tag = f"{lab}, p0 = {_p0(r) / 1e3:.0f} kPa" if ref.n_points > 1 else lab
            axes[0].plot(x, r["q"] / 1e3, ls, label=tag)
            axes[1].plot(x, 100 * r["eps_v"], ls)
            axes[2].plot(r["p"] / 1e3, r["q"] / 1e3, ls)
        a, o = _by_stage(ref.point(b), other.point(b))  # rows matched as in deviations()
        n = len(a["q"])
        x = 100 * (a["eps11"] - ref.point(b)["eps11"][0]) if name != "rotation" else np.arange(n)
        peak = _q_scale(a)  # as in deviations(): the table's numbers and the panel's agree
        if peak != np.abs(a["q"]).max(initial=0.0):
            scale_name = "peak p"
        dq, dv = 100 * (o["q"] - a["q"]) / peak, 100 * (o["eps_v"] - a["eps_v"])
        worst_q = max(worst_q, float(np.abs(dq).max(initial=0.0)))
        worst_v = max(worst_v, float(np.abs(dv).max(initial=0.0)))
        axes[3].plot(x, dq, label=f"Δq, p0 = {_p0(ref.point(b)) / 1e3:.0f} kPa")
        err_v.plot(x, dv, ":", color="0.4")
    xl = "ε11 [%]" if name != "rotation" else "state along the path"
    axes[0].set(xlabel=xl, ylabel="q = σ11 − σ22 [kPa]", title=name)
    axes[1].set(xlabel=xl, ylabel="εv [%] (compression > 0)")
    axes[2].set(xlabel="p [kPa]", ylabel="q [kPa]", title="stress path")
    axes[3].set(xlabel=xl, ylabel=f"Δq / {scale_name} [%] ({labels[1]} − {labels[0]})", title="errors")
    err_v.set_ylabel("Δεv [% strain] (dotted)")
    for ax, floor in ((axes[0], AXIS_Q_KPA), (axes[2], AXIS_Q_KPA), (axes[3], ERROR_AXIS_Q),
                      (err_v, ERROR_AXIS_EV)):
        lo, hi = ax.get_ylim()
        ax.set_ylim(min(lo, -floor), max(hi, floor))
        ax.ticklabel_format(axis="y", useOffset=False)
    axes[3].text(0.98, 0.02, f"max |Δq| / {scale_name} = {worst_q:.2g} %\nmax |Δεv| = {worst_v:.2g} % strain",
                 transform=axes[3].transAxes, fontsize=7, va="bottom", ha="right")
    axes[0].legend(fontsize=7)
    axes[3].legend(fontsize=7)
    return fig
