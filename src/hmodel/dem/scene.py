"""Many independent DEM cells in one YADE scene: settings, input, run, results.

:func:`simulate` takes a list of (mesostructure, increments) pairs, one per cell, builds one
scene holding every cell (side by side, never touching), drives each cell by its own
increments of (l1, l2) and returns one :class:`CellRun` per cell: the task ``runs`` of YADE
(:mod:`hmodel.dem.yade`). :func:`scene_settings` are the scene's material and numerics, the same
for the DEM cell solver's task ``increment``; read :mod:`hmodel.dem.yade.scripts.cell_scene` for
the scene, the contact law, the driving and the quasi-static criterion.

Units: lengths in m (the unit of the grain radius), forces in N (kn in N/m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..limits import check_memory
from ..params import Params
from ..cell.mesostructure import TYPE1, TYPE1_SIGN, TYPE2, Mesostructure
from .yade import run

#: Columns of a contact row: local grain indices, normal force (compression positive),
#: tangential component f.(e_y, -e_x), force on j by i (x, y), branch vector x_j - x_i.
CONTACT_COLUMNS = ("i", "j", "fn", "ft", "fx", "fy", "bx", "by")
#: Memory of one cell's record after one increment [bytes], an upper estimate: YADE records every
#: cell of a scene after every increment (centres, contact rows, forces) and answers them as JSON
#: text, read back here into lists, arrays and the derived states. Measured about 11 KiB, for a
#: standard cell (4 cells over 2,000 increments) and a bi-hexagon (over 3,000); three times that.
RECORD_BYTES = 32 * 2**10


def scene_bytes(n_cells: float, n_increments: float) -> float:
    """Estimated memory [bytes] of a YADE scene of ``n_cells`` cells driven over ``n_increments``
    increments (the longest cell's: every cell is recorded after each, and at the start)."""
    return float(n_cells) * (float(n_increments) + 1.0) * RECORD_BYTES


def check_scene(n_cells: float, n_increments: float, what: str) -> None:
    """Refuse (:class:`~hmodel.limits.WorkTooLarge`) a scene of :func:`scene_bytes` over the
    memory budget, before its cells or increments are built; ``what`` names the request."""
    check_memory(scene_bytes(n_cells, n_increments), what)


@dataclass(frozen=True)
class DEMOptions:
    """Numerical settings of a DEM run.

    Attributes
    ----------
    tol : float
        Quasi-static criterion: max |F| on a free DOF / mean contact force <= tol.
    max_iter : int
        Relaxation time steps allowed per increment before the run fails.
    substeps : int
        Time steps over which one increment is applied (constant velocity).
    damping : float
        Cundall's non-viscous damping of NewtonIntegrator.
    dt_safety : float
        O.dt = dt_safety * PWaveTimeStep().
    check_every : int
        Time steps between two evaluations of the criterion.
    detect_margin : float
        Relative margin of contact detection on the first step only (initially touching grains).
    timeout : float
        Wall-clock limit of the YADE process [s] (of one request of the cell solver).
    max_cells : int
        Cells per request of the cell solver (:mod:`hmodel.dem.solver`): the cells of a request
        share one scene, where balanced cells are frozen but still stepped, so one cell slow to
        balance holds every cell of its request (a 10,000-cell request ran past the timeout).
    """

    tol: float = 1e-4
    max_iter: int = 20000
    substeps: int = 200
    damping: float = 0.4
    dt_safety: float = 0.5
    check_every: int = 10
    detect_margin: float = 0.01
    timeout: float = 600.0
    max_cells: int = 1000

    def __post_init__(self) -> None:
        if not (self.max_cells >= 1 and self.tol > 0 and self.max_iter >= 0 and self.substeps >= 1 and 0 <= self.damping < 1
                and 0 < self.dt_safety <= 1 and self.check_every >= 1 and self.detect_margin >= 0):
            raise InputError(f"invalid DEM options {self}")


@dataclass(frozen=True)
class CellRun:
    """The recorded states of one DEM cell: step 0 is the initial state, then one per increment.

    Attributes
    ----------
    mesostructure : Mesostructure
    positions : ndarray, shape (S+1, g, 2)
        Grain centres in the cell frame [m].
    contacts : list of ndarray, length S+1, each (m_k, 8)
        Closed contacts, columns :data:`CONTACT_COLUMNS`.
    forces : ndarray, shape (S+1, g, 2)
        Resultant contact force on every grain [N] (the reaction of the driving on a driven
        direction, about zero on a free one).
    unbalanced : ndarray, shape (S+1,)
        Unbalanced-force ratio reached after each increment.
    iterations : ndarray, shape (S+1,)
        Time steps spent on each increment (driving + relaxation).
    """

    mesostructure: Mesostructure
    positions: np.ndarray
    contacts: list[np.ndarray] = field(repr=False)
    forces: np.ndarray = field(repr=False)
    unbalanced: np.ndarray
    iterations: np.ndarray

    @property
    def n_steps(self) -> int:
        return len(self.positions) - 1


def _contact_force(rows: np.ndarray, pair: tuple[int, int]) -> tuple[float, float]:
    """(fn, ft) of the contact between local grains ``pair`` (i < j), zeros if it is open."""
    hit = rows[(rows[:, 0] == pair[0]) & (rows[:, 1] == pair[1])] if len(rows) else rows
    return (float(hit[0, 2]), float(hit[0, 3])) if len(hit) else (0.0, 0.0)


def hcell_state(run: CellRun) -> np.ndarray:
    """H-cell state (S+1, 8) ``d1, d2, alpha, N1, N2, T1, l1, l2`` of a standard-cell run.

    d1, alpha: mean over the four type-1 branches 1-2, 1-6, 4-3, 4-5 (alpha = angle of the
    branch to n); d2, N2: mean over 2-3 and 5-6; N1, T1: mean over the type-1 contacts, N
    compression positive and T1 the tangential force on grain 2 by grain 1 along
    (sin alpha, -cos alpha) (and its mirror images), the sign of :mod:`hmodel.cell.closed_form`
    and of eq. 1.12. l1 = distance 1-4, l2 = distance between the rows 2-3 and 5-6.
    """
    x = run.positions
    out = np.empty((len(x), 8))
    for k, rows in enumerate(run.contacts):
        p = x[k]
        b1 = np.array([p[j] - p[i] for i, j in TYPE1])
        d1 = np.hypot(b1[:, 0], b1[:, 1])
        alpha = np.arctan2(np.abs(b1[:, 1]), np.abs(b1[:, 0]))
        d2 = [np.hypot(*(p[j] - p[i])) for i, j in TYPE2]
        f1 = np.array([_contact_force(rows, c) for c in TYPE1])
        f2 = np.array([_contact_force(rows, c) for c in TYPE2])
        out[k] = (d1.mean(), np.mean(d2), alpha.mean(), f1[:, 0].mean(), f2[:, 0].mean(),
                  np.mean(f1[:, 1] * np.array(TYPE1_SIGN)), p[3, 0] - p[0, 0],
                  0.5 * (p[1, 1] + p[2, 1] - p[4, 1] - p[5, 1]))
    return out


def scene_settings(params: Params, r_ref: float, options: DEMOptions) -> dict:
    """The scene's material and numerics, as YADE's cell tasks read them.

    Every contact has stiffnesses kn and kt_kn kn and friction angle phi_g [rad]; every grain has
    the mass of a sphere of radius ``r_ref`` [m] (the largest grain) and density 1: the
    quasi-static result does not depend on it, the time step does. Cells lie ``2 r_ref`` apart.
    """
    return {"kn": params.kn, "kt_kn": params.kt_kn, "phi_g": params.phi_g, "r_ref": r_ref,
            "density": 1.0, "mass": 4.0 / 3.0 * math.pi * r_ref ** 3, "gap": 2.0 * r_ref,
            "tol": options.tol, "max_iter": options.max_iter, "substeps": options.substeps,
            "damping": options.damping, "dt_safety": options.dt_safety,
            "check_every": options.check_every, "detect_margin": options.detect_margin}


def simulate(cells: list[tuple[Mesostructure, np.ndarray]], params: Params,
             options: DEMOptions | None = None) -> tuple[list[CellRun], dict]:
    """Run every cell under its own increments in one YADE scene.

    Parameters
    ----------
    cells : list of (Mesostructure, ndarray (S_c, 2))
        Each cell and its increments (dl1, dl2) [m] (negative is shortening). Cells with fewer
        increments than the longest stay still afterwards and are recorded only for theirs.
    params : Params
        kn, kt_kn, phi_g are used; every contact has stiffnesses kn and kt_kn * kn.
    options : DEMOptions

    Returns
    -------
    (list of CellRun, dict)
        The runs and run information (``dt``, ``iterations``, ``wall_s``).
    """
    options = options or DEMOptions()
    if not cells:
        raise InputError("no DEM cell to simulate")
    spec = scene_settings(params, max(float(np.max(m.radii)) for m, _ in cells), options)
    spec["cells"] = []
    for m, inc in cells:
        inc = np.asarray(inc, float).reshape(-1, 2)
        if not np.all(np.isfinite(inc)):
            raise InputError("DEM increments must be finite")
        spec["cells"].append({"radii": m.radii.tolist(), "pos": m.positions.tolist(),
                              "drive": list(m.drive), "l": [m.l1, m.l2],
                              "half_width": m.half_width, "increments": inc.tolist()})
    result = run("runs", spec, timeout=options.timeout)
    runs = []
    for (m, inc), rec in zip(cells, result["cells"]):
        n = len(np.reshape(inc, (-1, 2))) + 1
        rec = rec[:n]
        runs.append(CellRun(
            mesostructure=m,
            positions=np.array([r["pos"] for r in rec], float),
            contacts=[np.array(r["contacts"], float).reshape(-1, len(CONTACT_COLUMNS)) for r in rec],
            forces=np.array([r["forces"] for r in rec], float),
            unbalanced=np.array([r["unbalanced"] for r in rec], float),
            iterations=np.array([r["iterations"] for r in rec], int)))
    info = {k: result[k] for k in ("dt", "iterations", "wall_s")}
    return runs, info
