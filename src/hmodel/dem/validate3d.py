"""The DEM bi-hexagon against the closed-form bi-hexagon (``hmodel dem validate --dim 3``).

Paths: from the unloaded bi-hexagon, constant increments of the cell strains along
(n, t1, t2), compression positive, ``step * d / |d|`` for a few directions d (:data:`PATHS`),
δl_k = -l_k0 δε_k; each chosen for what it makes the cell do (sliding in one hexagon, in both,
in neither, a hexagon opening). Every path runs in one YADE scene
(:func:`hmodel.dem.bihex.simulate`), increment after increment, once as the closure's cell (the
lateral grains of the two hexagons kept apart) and, with ``cross``, once more with them free to
touch, which the closure ignores (docs/model3d.md, "Contacts between the two hexagons").

Deviations per path: forces, max |F_DEM - F_CF| / max |F_CF| over the path's steps and the six
forces (N1, N2, T1 of both hexagons); angles, max |α_DEM - α_CF| [rad] over both hexagons;
stress, max |Vσ_DEM - Vσ_CF| / max |Vσ_CF| over the three cell-frame components, Vσ_DEM the
Love-Weber sum over the DEM contacts (cross contacts included) and Vσ_CF the closed form's
(:meth:`~hmodel.cell.bihex.BiHexSolver.meso`). The closed form runs with each step split in
``refine`` sub-steps (``cf_step_error``: its own step-size error, the same measure between the
plain and refined runs).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..cell.bihex import BIHEX_FIELDS, BIHEX_FLAGS, BiHexSolver, initial_bihex
from ..cell.state import CellState
from ..errors import InputError
from ..limits import check_count
from ..params import Params
from .bihex import BiHexRuns, simulate
from .scene import DEMOptions, check_scene
from .solver import SOLVER_OPTIONS

#: Default paths: name -> direction of (ε_n, ε_t1, ε_t2), compression positive.
PATHS = {
    "axial": (1.0, 0.0, 0.0),        # both hexagons alike, no sliding
    "triaxial": (1.0, -0.5, -0.5),   # both hexagons slide
    "plane": (1.0, -1.0, 0.0),       # A slides, B compressed along n only
    "mixed": (1.0, 1.0, -1.0),       # B slides, A does not
    "opening": (0.0, 1.0, -1.0),     # A slides, B opens
    "isotropic": (1.0, 1.0, 1.0),    # no sliding; A and B lateral grains overlap
    "unequal": (0.3, 1.0, 0.7),      # lateral grains overlap with d2 of A and B unequal
}
#: DEM numerics of the validation: the cell solver's (quasi-static criterion 1e-10) with each
#: increment driven over 1000 time steps instead of 100. The DEM's deviation from the closed form
#: is the transient of the driving: its grains lag the quasi-static path within an increment,
#: which matters where a contact slides, most in the first increment from the unloaded cell,
#: whose Coulomb limit starts at 0 (5 x 0.1 % on the triaxial path: 1.2e-3 of the largest force
#: at 100 steps, 1.1e-4 at 1000, at about the same cost: relaxing dominates).
VALIDATION_OPTIONS = replace(SOLVER_OPTIONS, substeps=1000)
#: Force fields of both hexagons (N1, N2, T1, N1_b, N2_b, T1_b) and angle fields (alpha, alpha_b).
FORCES = tuple(BIHEX_FIELDS.index(f) for f in ("N1", "N2", "T1", "N1_b", "N2_b", "T1_b"))
ANGLES = tuple(BIHEX_FIELDS.index(f) for f in ("alpha", "alpha_b"))


@dataclass
class Validation3D:
    """Result of :func:`validate_bihex`: ``rows`` the deviation table (one dict per path and
    cross setting); per path ``dem`` (P, S+1, 16) (``dem_cross``: with cross contacts, or
    None), ``cf``/``cf_fine`` the closed form's states, ``vsig_dem``/``vsig_cf`` (P, S+1, 3)
    the cell-frame V σ (``vsig_dem_cross``: with cross contacts, or None); ``strain`` (S+1,) the strain along the paths; the DEM runs."""

    params: Params
    names: list[str]
    directions: np.ndarray
    strain: np.ndarray
    dem: np.ndarray
    dem_cross: np.ndarray | None
    cf: np.ndarray
    cf_fine: np.ndarray
    vsig_dem: np.ndarray
    vsig_cf: np.ndarray
    rows: list[dict]
    runs: list[BiHexRuns] = field(repr=False)
    wall_s: float = 0.0
    vsig_dem_cross: np.ndarray | None = None

    def worst(self, cross: bool = False) -> dict[str, float]:
        """Largest deviation of each kind over the paths (without or with cross contacts)."""
        rows = [r for r in self.rows if r["cross"] == cross]
        return {k: max(r[k] for r in rows) for k in ("dev_force", "dev_alpha", "dev_stress")}


def love_weber(positions: np.ndarray, contacts: list) -> np.ndarray:
    """V σ (nn, t1t1, t2t2) [N m] of DEM bi-hexagons, the Love-Weber sum Σ f ⊗ b over their
    contact rows (eq. 1.11, compression positive: f the force on j by i, b = x_j - x_i)."""
    out = np.zeros((len(contacts), 3))
    for k, rows in enumerate(contacts):
        rows = np.asarray(rows, float).reshape(-1, 9)
        out[k] = np.einsum("ma,ma->a", rows[:, 3:6], rows[:, 6:9])
    return out


def closed_form_path(params: Params, dl: np.ndarray, steps: int, refine: int) -> np.ndarray:
    """Closed-form bi-hexagon states (P, steps+1, 16) under constant increments dl (P, 3), each
    split into ``refine`` sub-steps."""
    solver = BiHexSolver()
    state = initial_bihex(params, np.full(len(dl), params.alpha0))
    out = [state.values.copy()]
    for _ in range(steps):
        for _ in range(refine):
            state, _ = solver.step(params, state, *(dl / refine).T)
        out.append(state.values.copy())
    return np.stack(out, axis=1)


def _deviations(dem: np.ndarray, cf: np.ndarray) -> tuple[float, float]:
    f = max(float(np.max(np.abs(cf[..., FORCES]))), 1e-300)
    return (float(np.max(np.abs(dem[..., FORCES] - cf[..., FORCES]))) / f,
            float(np.max(np.abs(dem[..., ANGLES] - cf[..., ANGLES]))))


def validate_bihex(params: Params, strain: float = 0.03, steps: int = 30, paths=tuple(PATHS),
                   refine: int = 10, cross: bool = True, options: DEMOptions | None = None,
                   progress=None, cross_friction: bool = True) -> Validation3D:
    """Run the DEM bi-hexagon and the closed form on the same paths.

    Parameters
    ----------
    params : Params
        Material; the closed form's sliding closure is ``params.sliding_rhs`` (the DEM obeys
        grain equilibrium, ``equilibrium``).
    strain : float
        Cell strain of every path (norm of (ε_n, ε_t1, ε_t2)).
    steps : int
        Increments per path.
    paths : sequence of str or of (name, direction)
        Names of :data:`PATHS`, or (name, 3 numbers) pairs.
    refine : int
        Sub-steps of the refined closed form.
    cross : bool
        Also run every path with the two hexagons' lateral grains free to touch.
    options : DEMOptions
        DEM numerics (default :data:`VALIDATION_OPTIONS`).
    progress : callable, optional
        Receives the completed fraction.
    cross_friction : bool
        Whether the cross contacts of that run have the scene's friction (True) or none (False:
        like for like with ``cross_contacts=frictionless``).
    """
    if not (np.isfinite(strain) and 0 < strain <= 0.5):
        raise InputError(f"strain must lie in (0, 0.5], got {strain}")
    if steps < 1 or refine < 1:
        raise InputError("steps and refine must be >= 1")
    check_count(steps, "increments per path (--steps)")
    names, dirs = [], []
    for p in paths:
        if isinstance(p, str):
            if p not in PATHS:
                raise InputError(f"unknown bi-hexagon path {p!r} (known: {', '.join(PATHS)})")
            p = (p, PATHS[p])
        d = np.asarray(p[1], float)
        if d.shape != (3,) or not np.all(np.isfinite(d)) or not np.any(d):
            raise InputError(f"a bi-hexagon path direction is 3 finite numbers, not all 0; got {p[1]!r}")
        names.append(str(p[0]))
        dirs.append(d / np.linalg.norm(d))
    if not names:
        raise InputError("at least one bi-hexagon path is needed")
    # a scene of one bi-hexagon per path, run once more with cross contacts (the first kept)
    check_scene(len(names) * (2 if cross else 1), steps,
                f"{len(names)} DEM bi-hexagon paths of {steps:,} increments"
                + (" (each run with and without cross contacts)" if cross else ""))
    report = progress or (lambda f: None)
    options = options or VALIDATION_OPTIONS
    dirs = np.array(dirs)
    v0 = initial_bihex(params, np.full(len(dirs), params.alpha0)).values
    l0 = v0[:, [6, 7, 15]]
    dl = -l0 * (strain / steps) * dirs
    inc = np.repeat(dl[:, None, :], steps, axis=1)
    report(0.05)
    t0 = time.perf_counter()
    runs = [simulate(params, v0, inc, options)]
    report(0.5 if cross else 0.8)
    if cross:
        runs.append(simulate(params, v0, inc, options, cross=True, cross_friction=cross_friction))
    wall = time.perf_counter() - t0
    report(0.85)
    cf = closed_form_path(params, dl, steps, 1)
    cf_fine = closed_form_path(params, dl, steps, refine)
    vsig_cf = BiHexSolver().meso(params, CellState(cf_fine))[0][..., :3]
    rows, vsig_dem = [], []
    for run in runs:
        n, S = run.positions.shape[:2]
        vs = love_weber(run.positions.reshape(n * S, 10, 3), [c for rec in run.contacts for c in rec])
        vs = np.concatenate([np.zeros((n, 1, 3)), vs.reshape(n, S, 3)], axis=1)
        vsig_dem.append(vs)
        with_cross = run is not runs[0]
        for p, name in enumerate(names):
            dev_f, dev_a = _deviations(run.values[p], cf_fine[p])
            err_f, err_a = _deviations(cf[p], cf_fine[p])
            flags = run.flags[p]
            rows.append({
                "path": name, "d_n": dirs[p, 0], "d_t1": dirs[p, 1], "d_t2": dirs[p, 2], "cross": with_cross,
                "max_force": float(np.max(np.abs(cf_fine[p][:, list(FORCES)]))),
                "dev_force": dev_f, "dev_alpha": dev_a,
                "dev_stress": float(np.max(np.abs(vs[p] - vsig_cf[p]))) / max(float(np.max(np.abs(vsig_cf[p]))), 1e-300),
                "cf_step_error_force": err_f, "cf_step_error_alpha": err_a,
                "sliding_steps": int(flags[:, [0, 5]].any(axis=1).sum()),
                "open_steps": int(flags[:, [1, 2, 6, 7]].any(axis=1).sum()),
                "cross_steps": int(flags[:, BIHEX_FLAGS.index("cross")].sum()),
                "max_unbalanced": float(run.unbalanced[p].max())})
    report(1.0)
    return Validation3D(params, names, dirs, (strain / steps) * np.arange(steps + 1), runs[0].values,
                        runs[1].values if cross else None, cf, cf_fine, vsig_dem[0], vsig_cf, rows,
                        runs, wall, vsig_dem[1] if cross else None)


def path_rows(v: Validation3D) -> list[dict]:
    """One row per path and step: strain, then every field and the cell-frame V σ of the DEM
    (``_dem``; ``_dem_cross`` with cross contacts), the closed form (``_cf``) and the refined
    closed form (``_cf_fine``)."""
    out = []
    comps = ("vsig_nn", "vsig_t1t1", "vsig_t2t2")
    arrays = [("dem", v.dem), ("cf", v.cf), ("cf_fine", v.cf_fine)]
    if v.dem_cross is not None:
        arrays.insert(1, ("dem_cross", v.dem_cross))
    for p, name in enumerate(v.names):
        for s, e in enumerate(v.strain):
            row = {"path": name, "strain": e}
            for tag, arr in arrays:
                row.update({f"{f}_{tag}": arr[p, s, i] for i, f in enumerate(BIHEX_FIELDS)})
            row.update({f"{c}_dem": v.vsig_dem[p, s, i] for i, c in enumerate(comps)})
            if v.vsig_dem_cross is not None:
                row.update({f"{c}_dem_cross": v.vsig_dem_cross[p, s, i] for i, c in enumerate(comps)})
            row.update({f"{c}_cf_fine": v.vsig_cf[p, s, i] for i, c in enumerate(comps)})
            out.append(row)
    return out


def plot_bihex_validation(v: Validation3D, path: str | Path) -> None:
    """N1, N2, T1 of both hexagons and V σ_t1t1 along every path: DEM (markers; crosses with
    cross contacts) over the refined closed form (lines; dashed: hexagon B)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 7.5), layout="constrained")
    axes = fig.subplots(2, 2)
    panels = (("N1", "N1_b"), ("N2", "N2_b"), ("T1", "T1_b"), None)
    x = 100 * v.strain
    for ax, panel in zip(axes.flat, panels):
        for p, name in enumerate(v.names):
            if panel is None:
                line, = ax.plot(x, v.vsig_cf[p, :, 1], "-", lw=1.2, label=name)
                ax.plot(x, v.vsig_dem[p, :, 1], "o", ms=3, mfc="none", color=line.get_color())
                if v.vsig_dem_cross is not None:
                    ax.plot(x, v.vsig_dem_cross[p, :, 1], "x", ms=3, color=line.get_color())
                continue
            ia, ib = (BIHEX_FIELDS.index(f) for f in panel)
            line, = ax.plot(x, v.cf_fine[p, :, ia], "-", lw=1.2, label=name)
            ax.plot(x, v.cf_fine[p, :, ib], "--", lw=1.0, color=line.get_color())
            for i in (ia, ib):
                ax.plot(x, v.dem[p, :, i], "o", ms=3, mfc="none", color=line.get_color())
                if v.dem_cross is not None:
                    ax.plot(x, v.dem_cross[p, :, i], "x", ms=3, color=line.get_color())
        ax.set_xlabel("cell strain along the path [%]")
        ax.set_ylabel("V σ_t1t1 [N m]" if panel is None else f"{panel[0]} (A), {panel[1]} (B) [N]")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7, title="lines: closed form (dashed: B); o: DEM; x: DEM, cross contacts",
                      title_fontsize=7)
    fig.suptitle(f"DEM bi-hexagon (YADE) vs closed form, α0 = {v.params.alpha0_deg:g}°")
    fig.savefig(path, dpi=110)
