"""The DEM standard cell against the closed form (eq. 1.7) on Dataset-1/2-like loadings.

Paths (Dataset 1): from the unloaded cell, constant increments of cell strain
(d eps1, d eps2) = step (cos theta, sin theta), compression positive, dl = -l0 d eps, for a few
directions theta. Probes (Dataset 2): from the states of those paths at chosen steps, one
increment of the same magnitude in ``n_probe`` directions. All cells run in one YADE scene.

Deviations are measured per quantity q in (N1, N2, T1, alpha) as max |q_DEM - q_CF| over the
states of a path (or over the probe endpoints of a start state) divided by the range of q over
the DEM path (floored at 1e-9 kn r for forces, 1e-9 rad for alpha). The closed form is run at
the path's step and, to separate its own step-size error, with each step split into
``refine`` sub-steps.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..cell.closed_form import ClosedFormSolver
from ..cell.mesostructure import standard
from ..cell.state import IDX, CellState
from ..cell.state import initial_cells
from ..errors import InputError
from ..limits import check_count
from ..params import Params
from .scene import CellRun, DEMOptions, check_scene, hcell_state, simulate

QUANTITIES = ("N1", "N2", "T1", "alpha")
#: Default path directions [deg]. Extension-dominated paths (e.g. 120 deg) carry forces ~1e-4 of
#: the others before the cell opens; their deviations relative to that tiny range are large.
DEFAULT_DIRECTIONS = (0.0, 45.0, 90.0, -30.0)


@dataclass
class Validation:
    """Result of :func:`validate`.

    ``rows`` is the deviation table (one dict per path or probe set and quantity); ``dem`` and
    ``cf``/``cf_fine`` hold the H-cell states (P, S+1, 8) of the paths; ``runs`` the DEM runs
    (paths first, then probes); ``wall_s`` the wall time of the YADE run.
    """

    params: Params
    directions_deg: np.ndarray
    strain: np.ndarray
    dem: np.ndarray
    cf: np.ndarray
    cf_fine: np.ndarray
    rows: list[dict]
    runs: list[CellRun] = field(repr=False)
    wall_s: float = 0.0
    dem_info: dict = field(default_factory=dict)

    def worst(self, column: str = "dev_cf_fine") -> dict[str, float]:
        """Largest deviation per quantity over all rows."""
        return {q: max(r[column] for r in self.rows if r["quantity"] == q) for q in QUANTITIES}


def _cf_path(params: Params, alpha0: float, dl: np.ndarray, n: int, refine: int,
             start: CellState | None = None) -> np.ndarray:
    """Closed-form states (P, n+1, 8) under constant increments dl (P, 2), each split in ``refine``."""
    solver = ClosedFormSolver()
    state = start if start is not None else initial_cells(params, np.full(len(dl), alpha0))
    out = [state.values.copy()]
    for _ in range(n):
        for _ in range(refine):
            state, _ = solver.step(params, state, dl[:, 0] / refine, dl[:, 1] / refine)
        out.append(state.values.copy())
    return np.stack(out, axis=1)


def _scale(params: Params, q: str) -> float:
    return 1e-9 if q == "alpha" else 1e-9 * params.kn * params.radius


def validate(params: Params, strain: float = 0.03, steps: int = 30,
             directions_deg=DEFAULT_DIRECTIONS, probe_at=(0.5, 1.0), n_probe: int = 8,
             refine: int = 10, options: DEMOptions | None = None, progress=None) -> Validation:
    """Run the DEM standard cell and the closed form on the same paths and probes.

    Parameters
    ----------
    params : Params
        Material; alpha0 is the cells' opening angle. The closed form's sliding closure is
        ``params.sliding_rhs``; the DEM obeys grain equilibrium, i.e. ``equilibrium``.
    strain : float
        Total cell strain of every path (norm of (eps1, eps2)).
    steps : int
        Increments per path; the path step is strain / steps.
    directions_deg : sequence of float
        Directions theta of the paths in the (eps1, eps2) plane [deg].
    probe_at : sequence of float
        Fractions of the path where probes start (rounded to a step >= 1); empty: no probes.
    n_probe : int
        Probe directions, evenly spaced over 360 deg.
    refine : int
        Sub-steps of the refined closed form.
    progress : callable, optional
        Receives the completed fraction.
    """
    if not (math.isfinite(strain) and 0 < strain <= 0.5):
        raise InputError(f"strain must lie in (0, 0.5], got {strain}")
    if steps < 1 or refine < 1 or n_probe < 0:
        raise InputError("steps and refine must be >= 1, n_probe >= 0")
    theta = np.radians(np.asarray(directions_deg, float)).reshape(-1)
    if theta.size == 0 or not np.all(np.isfinite(theta)):
        raise InputError("at least one finite path direction is needed")
    report = progress or (lambda f: None)
    check_count(steps, "increments per path (--steps)")
    starts = sorted({min(steps, max(1, round(f * steps))) for f in probe_at}) if n_probe else []
    # one scene: the paths, and a cell per probe and start state, recorded to the longest's end
    n_cells = len(theta) * (1 + len(starts) * n_probe)
    check_scene(n_cells, max([steps] + [k + 1 for k in starts]),
                f"{len(theta)} DEM cell paths of {steps:,} increments"
                + (f" and {n_probe:,} probes from {len(starts)} states of each" if starts else "")
                + f" ({n_cells:,} cells in one YADE scene)")
    step = strain / steps
    cell = standard(params.radius, params.alpha0)
    dl = np.stack([-cell.l1 * step * np.cos(theta), -cell.l2 * step * np.sin(theta)], axis=-1)
    phi = 2 * np.pi * np.arange(n_probe) / max(n_probe, 1)
    dprobe = np.stack([-cell.l1 * step * np.cos(phi), -cell.l2 * step * np.sin(phi)], axis=-1)
    cells = [(cell, np.tile(d, (steps, 1))) for d in dl]
    for p in range(len(theta)):
        for k in starts:
            cells += [(cell, np.vstack([np.tile(dl[p], (k, 1)), dprobe[j:j + 1]])) for j in range(n_probe)]
    report(0.05)
    t0 = time.perf_counter()
    runs, info = simulate(cells, params, options)
    wall = time.perf_counter() - t0
    report(0.8)
    P = len(theta)
    dem = np.stack([hcell_state(r) for r in runs[:P]])
    cf = _cf_path(params, params.alpha0, dl, steps, 1)
    cf_fine = _cf_path(params, params.alpha0, dl, steps, refine)
    rows = []
    for p in range(P):
        span = {q: max(float(np.ptp(dem[p, :, IDX[q]])), _scale(params, q)) for q in QUANTITIES}
        for q in QUANTITIES:
            i = IDX[q]
            rows.append({"kind": "path", "theta_deg": math.degrees(theta[p]), "start_step": 0,
                         "quantity": q, "range": span[q],
                         "dev_cf": float(np.max(np.abs(dem[p, :, i] - cf[p, :, i]))) / span[q],
                         "dev_cf_fine": float(np.max(np.abs(dem[p, :, i] - cf_fine[p, :, i]))) / span[q],
                         "cf_step_error": float(np.max(np.abs(cf[p, :, i] - cf_fine[p, :, i]))) / span[q],
                         "dev_increment": float("nan"),
                         "max_unbalanced": float(runs[p].unbalanced.max())})
        for s, k in enumerate(starts):
            first = P + (p * len(starts) + s) * n_probe
            probe_runs = runs[first:first + n_probe]
            end = np.array([hcell_state(r)[-1] for r in probe_runs])
            begin = np.array([hcell_state(r)[-2] for r in probe_runs])
            start_cf = CellState(np.repeat(cf[p, k][None], n_probe, axis=0))
            start_fine = CellState(np.repeat(cf_fine[p, k][None], n_probe, axis=0))
            pcf = _cf_path(params, params.alpha0, dprobe, 1, 1, start_cf)[:, -1]
            pfine = _cf_path(params, params.alpha0, dprobe, 1, refine, start_fine)[:, -1]
            for q in QUANTITIES:
                i = IDX[q]
                inc_dem, inc_fine = end[:, i] - begin[:, i], pfine[:, i] - cf_fine[p, k, i]
                inc_scale = max(float(np.max(np.abs(inc_fine))), _scale(params, q))
                rows.append({"kind": "probe", "theta_deg": math.degrees(theta[p]), "start_step": k,
                             "quantity": q, "range": span[q],
                             "dev_cf": float(np.max(np.abs(end[:, i] - pcf[:, i]))) / span[q],
                             "dev_cf_fine": float(np.max(np.abs(end[:, i] - pfine[:, i]))) / span[q],
                             "cf_step_error": float(np.max(np.abs(pcf[:, i] - pfine[:, i]))) / span[q],
                             "dev_increment": float(np.max(np.abs(inc_dem - inc_fine))) / inc_scale,
                             "max_unbalanced": float(max(r.unbalanced.max() for r in probe_runs))})
    report(1.0)
    strain_axis = step * np.arange(steps + 1)
    return Validation(params, np.degrees(theta), strain_axis, dem, cf, cf_fine, rows, runs, wall, info)


def plot_validation(v: Validation, path: "str | Path") -> None:
    """N1, N2, T1, alpha along every path: DEM (markers) over the closed form (lines)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 7.5), layout="constrained")
    axes = fig.subplots(2, 2)
    units = {"N1": "N", "N2": "N", "T1": "N", "alpha": "deg"}
    for ax, q in zip(axes.flat, QUANTITIES):
        i = IDX[q]
        conv = np.degrees if q == "alpha" else (lambda x: x)
        for p, th in enumerate(v.directions_deg):
            line, = ax.plot(100 * v.strain, conv(v.cf[:, :, i][p]), "-", lw=1.2, label=f"θ = {th:g}° closed form")
            ax.plot(100 * v.strain, conv(v.cf_fine[:, :, i][p]), ":", lw=1, color=line.get_color())
            ax.plot(100 * v.strain, conv(v.dem[:, :, i][p]), "o", ms=3, mfc="none", color=line.get_color())
        ax.set_xlabel("cell strain along the path [%]")
        ax.set_ylabel(f"{q} [{units[q]}]")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7, title="lines: closed form (dotted: refined); o: DEM", title_fontsize=7)
    fig.suptitle(f"DEM (YADE) vs closed form, standard cell, α0 = {v.params.alpha0_deg:g}°")
    fig.savefig(path, dpi=110)


def draw_cell(run: CellRun, path: "str | Path", step: int = -1, title: str | None = None) -> None:
    """Grains as circles at a recorded step, contacts as lines whose width and colour follow
    the normal force."""
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    pos = run.positions[step]
    rows = run.contacts[step]
    m = run.mesostructure
    fig = Figure(figsize=(6, 5), layout="constrained")
    ax = fig.subplots()
    colors = {"n": "#9ecae1", "t": "#fdd0a2", "free": "#c7e9c0"}
    for k, (x, r) in enumerate(zip(pos, m.radii)):
        ax.add_patch(Circle(x, r, fc=colors[m.drive[k]], ec="k", lw=0.8))
        ax.text(x[0], x[1], str(k + 1), ha="center", va="center", fontsize=9)
    fmax = float(np.max(np.abs(rows[:, 2]))) if len(rows) else 0.0
    cmap = colormaps["viridis"]
    for c in rows:
        i, j, fn = int(c[0]), int(c[1]), c[2]
        w = 0.5 + 5 * abs(fn) / fmax if fmax > 0 else 0.5
        ax.plot(*zip(pos[i], pos[j]), "-", lw=w, color=cmap(abs(fn) / fmax if fmax > 0 else 0))
    if fmax > 0:
        sm = ScalarMappable(cmap=cmap, norm=Normalize(0, fmax))
        fig.colorbar(sm, ax=ax, label="normal force [N]")
    ext = m.half_width * 1.1
    ax.set_xlim(-ext, ext)
    ax.set_ylim(-ext, ext)
    ax.set_aspect("equal")
    ax.set_xlabel("n [m]")
    ax.set_ylabel("t [m]")
    ax.set_title(title or f"{m.name} cell, step {step % (run.n_steps + 1)}")
    fig.savefig(path, dpi=110)
