"""The bi-hexagon as a DEM cell: the 3D H-model's cell (docs/model3d.md) built from
ten spheres in YADE, the cell solver ``dem:bihexagon`` that can take the closed-form
:class:`~hmodel.cell.bihex.BiHexSolver`'s place.

Grains (local indices): 0-5 are hexagon A's 2D grains 1-6 (the order of
:func:`hmodel.cell.mesostructure.standard`) in the plane (n, t1); 6, 7, 8, 9 are grains 7, 8,
9, 10, hexagon B's 2D grains 2, 3, 5, 6 in the plane (n, t2) (:data:`HEXAGONS`). Grains 1 and 4
are driven along n with l1, A's lateral grains along t1 with l2, B's along t2 with l3; the
YADE scene (:mod:`hmodel.dem.yade.scripts.bihex_cells`) keeps every other translation free and
relaxes the cell to equilibrium, the 2D DEM cells' law and criterion (docs/dem.md).

**State** (``CellState.values``): :data:`~hmodel.cell.bihex.BIHEX_FIELDS`, each hexagon's eight
H-cell fields measured on its six grains as the 2D DEM cell measures them
(:func:`hmodel.dem.solver.measure`); **flags**: :data:`~hmodel.cell.bihex.BIHEX_FLAGS`, each
hexagon's five 2D DEM flags and ``cross`` (a lateral grain of A and one of B closer than 2r).
A state is rebuilt mirror-symmetric (:func:`lift`: each hexagon as the 2D DEM cell rebuilds
it), so the solver's answer depends on the state and the increment only. **Meso-stress**: that
of the closed form's fields (:meth:`BiHexSolver.meso`, eq. 1.12 per hexagon, the Love-Weber sum
over the twelve contacts).

**Cross contacts.** The closure ignores contacts between A's and B's lateral grains
(docs/model3d.md, "Contacts between the two hexagons"), and so does this cell solver: YADE's
collision masks keep them apart, so the state holds every force of the cell. :func:`simulate`
with ``cross=True`` lets them touch (the validation measures what they change; the 16-field
state cannot carry their forces from one solver step to the next).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..cell.bihex import (
    BIHEX_FIELDS,
    BIHEX_FLAGS,
    BiHexSolver,
    check_params,
    initial_bihex,
)
from ..cell.base import STATE_BIHEXAGON
from ..cell.geometry import CellGeometry
from ..cell.state import CellFlags, CellState
from ..errors import InputError
from ..params import Params
from .scene import DEMOptions, scene_settings
from .solver import _INTEGER, _NUMERICS, SOLVER_OPTIONS, DEMSolver, measure
from .yade import run

#: The bi-hexagon's grain of each 2D grain 1-6 of hexagon A and of hexagon B.
HEXAGONS = ((0, 1, 2, 3, 4, 5), (0, 6, 7, 3, 8, 9))
#: The cell-frame axis (n, t1, t2) = (0, 1, 2) of each hexagon's t direction.
PLANE_AXES = (1, 2)
#: How each grain is driven (the YADE scene's ``drive``).
DRIVE = ("n", "t1", "t1", "n", "t1", "t1", "t2", "t2", "t2", "t2")
#: Lateral grains of hexagon A and of hexagon B (those the closure keeps apart).
LATERAL = ((1, 2, 4, 5), (6, 7, 8, 9))
#: The H-cell of each hexagon: its state layout, unpacking and packing.
_HEXAGON = CellGeometry("standard")


@dataclass(frozen=True)
class BiHexRuns:
    """Bi-hexagons under their increments: ``values`` (n, S+1, 16) and ``flags`` (n, S, 11) of
    every step (0 the start), grain centres ``positions`` (n, S, 10, 3) and contact rows
    ``contacts`` (n lists of S arrays (m, 9), :mod:`~hmodel.dem.yade.scripts.bihex_cells`'
    columns) after each increment, ``unbalanced`` and relaxation ``iterations`` (n, S);
    ``info``: YADE's ``dt`` and ``wall_s``."""

    values: np.ndarray
    flags: np.ndarray
    positions: np.ndarray = field(repr=False)
    contacts: list = field(repr=False)
    unbalanced: np.ndarray = field(repr=False)
    iterations: np.ndarray = field(repr=False)
    info: dict = field(default_factory=dict)


def lift(params: Params, values: np.ndarray) -> tuple[np.ndarray, list[list]]:
    """Grain centres (n, 10, 3) in the cell frame and tangential-force rows [i, j, fx, fy, fz]
    (force on grain j by grain i, i < j) of bi-hexagon states (n, 16): each hexagon rebuilt as
    the 2D DEM cell rebuilds an H-cell (:meth:`CellGeometry.unpack`), in its plane."""
    values = np.asarray(values, float)
    n = len(values)
    pos = np.zeros((n, 10, 3))
    shear: list[list] = [[] for _ in range(n)]
    for h, (grains, axis) in enumerate(zip(HEXAGONS, PLANE_AXES)):
        p2, ft = _HEXAGON.unpack(params, values[:, 8 * h:8 * h + 8])
        _, closed = _HEXAGON.normal_forces(params, p2)
        pos[:, list(grains), 0] = p2[..., 0]
        pos[:, list(grains), axis] = p2[..., 1]
        for c, (i, j) in enumerate(_HEXAGON.pairs):
            b = p2[:, j] - p2[:, i]
            e = b / np.hypot(b[:, 0], b[:, 1])[:, None]
            for k in np.flatnonzero(closed[:, c] & (ft[:, c] != 0.0)):
                t = np.zeros(3)  # ft (e_t, -e_n) in the hexagon's plane, the 2D sign
                t[0], t[axis] = ft[k, c] * e[k, 1], -ft[k, c] * e[k, 0]
                gi, gj = grains[i], grains[j]
                if gi > gj:
                    gi, gj, t = gj, gi, -t
                shear[k].append([gi, gj, *t.tolist()])
    return pos, shear


def project(positions: np.ndarray, contacts: list, h: int) -> tuple[np.ndarray, list[list]]:
    """Hexagon h's 2D cell: centres (n, 6, 2) in its plane and its contact rows
    [i, j, fn, ft] (2D local indices, ft = f.(e_t, -e_n) as :func:`hmodel.dem.scene.hcell_state`)
    of bi-hexagon centres (n, 10, 3) and 3D contact rows (n lists of rows)."""
    grains, axis = HEXAGONS[h], PLANE_AXES[h]
    local = {g: k for k, g in enumerate(grains)}
    pos2 = np.asarray(positions, float)[:, list(grains)][..., [0, axis]]
    rows2 = []
    for rows in contacts:
        out = []
        for r in rows:
            i, j = int(r[0]), int(r[1])
            if i not in local or j not in local:
                continue
            a, b = local[i], local[j]
            f = np.array([r[3], r[3 + axis]])
            br = np.array([r[6], r[6 + axis]])
            if a > b:
                a, b, f, br = b, a, -f, -br
            e = br / np.hypot(*br)
            out.append([a, b, float(r[2]), float(f[0] * e[1] - f[1] * e[0])])
        rows2.append(out)
    return pos2, rows2


def state_of(params: Params, positions: np.ndarray, contacts: list) -> tuple[np.ndarray, np.ndarray]:
    """Bi-hexagon states (n, 16) and flags (n, 11) of grain centres (n, 10, 3) and contact rows:
    each hexagon measured as a 2D DEM cell (:func:`hmodel.dem.solver.measure`), ``cross`` from
    the centres."""
    positions = np.asarray(positions, float)
    n = len(positions)
    values = np.empty((n, len(BIHEX_FIELDS)))
    flags = np.empty((n, len(BIHEX_FLAGS)), bool)
    for h in range(2):
        v, f = measure(_HEXAGON, params, *project(positions, contacts, h))
        values[:, 8 * h:8 * h + 8], flags[:, 5 * h:5 * h + 5] = v, f
    gap = positions[:, list(LATERAL[0]), None, :] - positions[:, None, list(LATERAL[1]), :]
    flags[:, 10] = np.linalg.norm(gap, axis=-1).min(axis=(1, 2)) < 2.0 * params.radius
    return values, flags


def request(params: Params, values: np.ndarray, increments: np.ndarray, options: DEMOptions,
            cross: bool = False, cross_friction: bool = True) -> dict:
    """The YADE request (task ``bihex``) of bi-hexagons (n, 16) under increments (n, S, 3)."""
    pos, shear = lift(params, values)
    req = scene_settings(params, params.radius, options)
    req["cells"] = [{"radii": [params.radius] * 10, "pos": pos[k].tolist(), "drive": list(DRIVE),
                     "l": [float(values[k, 6]), float(values[k, 7]), float(values[k, 15])],
                     "shear": shear[k], "increments": increments[k].tolist(), "cross": bool(cross),
                     "cross_friction": bool(cross_friction)}
                    for k in range(len(values))]
    return req


def simulate(params: Params, values: np.ndarray, increments: np.ndarray,
             options: DEMOptions | None = None, cross: bool = False, yade=None,
             cross_friction: bool = True) -> BiHexRuns:
    """Bi-hexagons of states ``values`` (n, 16) under their increments (n, S, 3) of
    (l1, l2, l3) [m] in one YADE scene, one increment after the other without rebuilding
    (so with ``cross`` the contacts between the hexagons keep their tangential forces);
    ``cross_friction`` False makes those contacts frictionless (``cross_contacts=frictionless``'s
    assumption), True gives them the scene's friction.

    ``yade``: a :class:`~hmodel.dem.yade.YadeServer` to ask (default: a process of its own).
    """
    check_params(params)
    options = options or DEMOptions()
    values = np.asarray(values, float).reshape(-1, len(BIHEX_FIELDS))
    inc = np.asarray(increments, float).reshape(len(values), -1, 3)
    if not len(values) or not inc.shape[1]:
        raise InputError("no DEM bi-hexagon increment to run")
    if not np.all(np.isfinite(inc)):
        raise InputError("DEM increments must be finite")
    payload = request(params, values, inc, options, cross, cross_friction)
    answer = (yade.request("bihex", payload, timeout=options.timeout) if yade is not None
              else run("bihex", payload, timeout=options.timeout))
    recs = answer["cells"]
    S = inc.shape[1]
    pos = np.array([[r["pos"] for r in rec] for rec in recs], float).reshape(len(values), S, 10, 3)
    contacts = [[np.array(r["contacts"], float).reshape(-1, 9) for r in rec] for rec in recs]
    new, flags = state_of(params, pos.reshape(-1, 10, 3), [c for rec in contacts for c in rec])
    out = np.concatenate([values[:, None], new.reshape(len(values), S, -1)], axis=1)
    return BiHexRuns(out, flags.reshape(len(values), S, -1), pos, contacts,
                     np.array([[r["unbalanced"] for r in rec] for rec in recs], float),
                     np.array([[r["iterations"] for r in rec] for rec in recs], int),
                     {"dt": answer["dt"], "wall_s": answer["wall_s"]})


def _numerics(spec: str) -> dict:
    """The :class:`DEMOptions` changes of ``dem:bihexagon[:K=V,...]``."""
    parts = spec.split(":")
    if parts[:2] != ["dem", "bihexagon"] or len(parts) > 3:
        raise InputError(f"the DEM bi-hexagon's spec is dem:bihexagon[:K=V,...], got {spec!r}")
    _, opts = CellGeometry.from_spec("dem:standard:" + (parts[2] if len(parts) > 2 else ""))
    unknown = [k for k in opts if k not in _NUMERICS]
    if unknown:
        raise InputError(f"unknown option {unknown[0]!r} of {spec!r} (numerics: {', '.join(_NUMERICS)})")
    return {k: (int(v) if k in _INTEGER else v) for k, v in opts.items()}


class DEMBiHexSolver(DEMSolver):
    """Bi-hexagons of spheres in YADE (``dem:bihexagon[:K=V,...]``, K among the numerics of
    :class:`DEMOptions`): the 3D cell solver of the module docstring, three length increments
    per cell (:meth:`step`), for :class:`hmodel.rev.Rev3D` on the generic loading driver.
    Requests, caching and the YADE process are the 2D DEM solver's (:class:`DEMSolver`)."""

    n_lengths = 3
    state_kind = STATE_BIHEXAGON
    length_columns = (6, 7, 15)
    n_flags = len(BIHEX_FLAGS)

    def __init__(self, spec: str = "dem:bihexagon", options: DEMOptions | None = None):
        numerics = _numerics(spec)
        #: the layout of each hexagon (the H-cell's)
        self.geometry = _HEXAGON
        self.name = "dem:bihexagon" + (":" + ",".join(f"{k}={v:g}" for k, v in numerics.items())
                                       if numerics else "")
        self.options = replace(options or SOLVER_OPTIONS, **numerics)
        self.stress_rtol = 1e-7
        self.bytes_per_cell = 8192
        self._server = None
        self._last = None
        self._closed_form = BiHexSolver()

    def __repr__(self) -> str:
        return f"DEMBiHexSolver({self.name!r})"

    @property
    def n_fields(self) -> int:
        return len(BIHEX_FIELDS)

    def field_names(self) -> tuple[str, ...]:
        return BIHEX_FIELDS

    def initial_cells(self, params: Params, alpha0: np.ndarray) -> CellState:
        return initial_bihex(params, alpha0)

    def initial(self, params: Params, shape: tuple[int, ...] = ()) -> CellState:
        return initial_bihex(params, np.full(shape, params.alpha0))

    def step(self, params: Params, state: CellState, dl1, dl2, dl3) -> tuple[CellState, CellFlags]:
        """One increment (δl1, δl2, δl3) [m] of every bi-hexagon, as :class:`BiHexSolver.step`."""
        check_params(params)
        return self._step(params, state, (dl1, dl2, dl3))

    def _run(self, params: Params, values: np.ndarray, dl: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        new, flags = [], []
        for k in range(0, len(values), self.options.max_cells):
            runs = simulate(params, values[k:k + self.options.max_cells],
                            dl[k:k + self.options.max_cells, None, :], self.options, yade=self.yade())
            new.append(runs.values[:, -1])
            flags.append(runs.flags[:, -1])
        return np.concatenate(new), np.concatenate(flags)

    def meso(self, params: Params, state: CellState) -> tuple[np.ndarray, np.ndarray]:
        """(V σ (..., 6), meso-volume (...)) of the fields, as the closed form
        (:meth:`BiHexSolver.meso`)."""
        return self._closed_form.meso(params, state)


__all__ = ["HEXAGONS", "BiHexRuns", "DEMBiHexSolver", "lift", "simulate", "state_of"]
