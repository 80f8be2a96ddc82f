"""The bi-hexagonal cell of the 3D H-model, solved in closed form (docs/model3d.md).

A bi-hexagon is two H-cells (report Fig. 1.2, eq. 1.2) in perpendicular planes that both
contain the cell's direction **n**: hexagon A in the plane (n, t1), hexagon B in the plane
(n, t2), sharing grains 1 and 4 on the n axis (ten grains, twelve contacts). Its three lengths
are l1 (grains 1-4, along n), l2 (hexagon A's columns, along t1) and l3 (hexagon B's columns,
along t2); the REV drives them by the projections of the 3D strain increment on the cell frame
(eq. 1.1 lifted, :mod:`hmodel.rev.rev3d`).

**Closure.** The unknowns are each hexagon's (δd1, δd2, δα). Grains 2, 3, 5, 6 touch only
grains of hexagon A (and 7-10 only of B), so each hexagon keeps its own grain-2 balance
(eqs. 1.5-1.6, row 3 of eq. 1.7). The shared grain 1 touches grains 2, 6 (A) and 7, 10 (B):
its balance across n holds by the mirror symmetries t1 -> -t1 and t2 -> -t2, and its balance
along n is carried by the external force that prescribes l1, exactly as in 2D, where grains 1
and 4 are the driven grains. The two hexagons therefore share one kinematic constraint, their
common l1 (rows 1 of both eq. 1.7 systems have the same δl1), and nothing else: with l1, l2,
l3 prescribed the 6x6 system is block-diagonal and the bi-hexagon is two 2D H-cells driven by
(δl1, δl2) and (δl1, δl3). It would couple if l1 were not prescribed (a stress-controlled cell)
or if the grains of the two hexagons touched (see ``cross`` below), neither of which this
closure admits.

**State layout** (``CellState.values``, last axis, :data:`BIHEX_FIELDS`): 16 fields, hexagon
A's 2D state ``d1, d2, alpha, N1, N2, T1, l1, l2`` then hexagon B's ``d1_b, d2_b, alpha_b,
N1_b, N2_b, T1_b, l1_b, l3``, each a valid 2D H-cell state (l1_b = l1 always: both follow the
same δl1). Because the first 8 fields are a 2D H-cell, code that reads ``state.d1`` etc. sees
hexagon A. **Flags** (:data:`BIHEX_FLAGS`, 11): hexagon A's five 2D flags, hexagon B's five,
and ``cross``: a grain of A and one of B closer than 2r (|x2 - x7| < 2r, which happens at
opening angles below 45°); the closure ignores those contacts, the flag reports them.

Units: as in 2D, lengths in m, forces in N with kn in N/m; 3D meso-volumes in m^3, so the
meso-stress is in Pa and scales with kn / r.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..errors import InputError, SolverError
from ..params import Params
from . import hertz_batch
from .base import STATE_BIHEXAGON, STATE_H_CELL, CellKernel, CellSolver
from .closed_form import (
    MECH_ANY,
    MECH_NONE,
    P_CROSS,
    P_HERTZ,
    P_R,
    P_RENEW,
    REGIME_WIDTH,
    ClosedFormSolver,
    cell_increment_hertz,
    cell_increment_prepared,
    kernel_params as cell_kernel_params,
    prepare_cell,
    prepared,
)
from .cross import cross_increment, cross_vsigma
from .hertz import extra_force
from .mesostress import contact_vsigma
from .renewal import RENEW_BIHEX, renew_bihex
from .state import FIELDS, FLAGS, CellFlags, CellState, initial_lengths

#: Fields of a bi-hexagon's state: hexagon A (plane n, t1), then hexagon B (plane n, t2).
BIHEX_FIELDS = FIELDS + ("d1_b", "d2_b", "alpha_b", "N1_b", "N2_b", "T1_b", "l1_b", "l3")
#: Diagnostics: hexagon A's 2D flags, hexagon B's, and ``cross`` (grains of A and B overlap).
BIHEX_FLAGS = FLAGS + tuple(f + "_b" for f in FLAGS) + ("cross",)
#: Meso-volume options of the 3D cell (Params.volume); ``hexagon-consistent`` has none in 3D.
VOLUMES_3D = ("hexagon", "rectangle", "box")


def kernel_params(params: Params):
    """The closed form's packed parameters (:func:`hmodel.cell.closed_form.kernel_params`), with
    renewal at the bi-hexagon's scale: both hexagons reborn together, not each as a 2D cell."""
    p = cell_kernel_params(params)
    if params.renewal == "rebirth":
        p[P_RENEW] = RENEW_BIHEX
    return p


def check_params(params: Params) -> None:
    """Refuse parameters the 3D cell has no meaning for (one-line :class:`InputError`)."""
    if params.volume not in VOLUMES_3D:
        raise InputError(f"parameter volume must be one of {', '.join(VOLUMES_3D)} for the 3D "
                         f"H-model, got {params.volume!r} (eq. 1.21's virtual l1* is not shared by "
                         "the two hexagons of a bi-hexagon)")
    if params.cross_contacts != "none":
        low = params.alpha0 - params.alpha0_half_width
        if low < math.pi / 4.0 - 1e-12:
            raise InputError(f"cross_contacts={params.cross_contacts} needs opening angles of at least "
                             f"45 deg (alpha0 - spread), got {math.degrees(low):.4g}: below, an "
                             "unloaded bi-hexagon's two hexagons overlap")


@njit(cache=True, inline="always", error_model="numpy")
def cross_contact(dn, l2, l3, two_r):
    """Whether a grain of hexagon A (at (±d2/2, ±l2/2, 0) in the cell frame) and one of hexagon
    B (at (±d2_b/2, 0, ±l3/2)) are closer than 2r; dn = (d2 - d2_b) / 2."""
    return dn * dn + 0.25 * (l2 * l2 + l3 * l3) < two_r * two_r


@njit(cache=True, inline="always", error_model="numpy")
def bihex_prepared_width(p):
    """Width of the part of a bi-hexagon's increment that its committed state fixes
    (:func:`hmodel.cell.closed_form.prepare_cell` of both hexagons, read by
    :func:`bihex_increment`): both hexagons' with linear contacts
    (:func:`hmodel.cell.closed_form.prepared`); none with Hertz-Mindlin contacts (measured in 2D
    to gain nothing) or with contacts between the hexagons, whose coupled increment
    (:func:`hmodel.cell.cross.cross_increment`) starts from the states themselves."""
    if prepared(p) and p[P_CROSS] == 0.0:
        return 2 * REGIME_WIDTH
    return 0


@njit(cache=True, inline="always", error_model="numpy")
def bihex_increment(values, i, dl1, dl2, dl3, p, out, flags, pre, mech):
    """Advance bi-hexagon ``values[i]`` (16 fields) by (δl1, δl2, δl3) into ``out[i]`` and
    ``flags[i]`` (11), indexed in place (no row views, see closed_form.cell_update): each
    hexagon is the 2D increment of eq. 1.7 with the shared δl1
    (:func:`hmodel.cell.closed_form.cell_increment_prepared`, linear contacts from ``pre[i]``,
    both hexagons' :func:`hmodel.cell.closed_form.prepare_cell` of ``values``, of width
    :func:`bihex_prepared_width`), or, with contacts between the hexagons (``P_CROSS``), the
    coupled increment of :func:`hmodel.cell.cross.cross_increment`. ``mech``
    (:data:`~hmodel.cell.closed_form.MECH_NONE`, ...): the cell the caller's loop updates, a
    constant there. Returns False when either hexagon's increment failed."""
    # docs/mechanisms.md, "Contacts between the two hexagons"
    if mech == MECH_ANY and p[P_CROSS] != 0.0:
        ok = cross_increment(values, i, dl1, dl2, dl3, p, out, flags)
    elif mech == MECH_ANY and p[P_HERTZ] != 0.0:  # nothing prepared (bihex_prepared_width)
        ok_a = cell_increment_hertz(values, i, dl1, dl2, p, out, flags, MECH_NONE, 0)
        ok = cell_increment_hertz(values, i, dl1, dl3, p, out, flags, MECH_NONE, 1) and ok_a
    else:
        # MECH_NONE for each hexagon whatever the loop: a hexagon is never reborn as a 2D cell
        # (kernel_params: RENEW_BIHEX below), and the 2D mechanisms' code (Hertz-Mindlin's
        # branch, the cell's rebirth), present though never run, made this update about five
        # times as slow in a loop of it alone (docs/notes/2026-12-07-per-state-preparation-3d.md)
        ok_a = cell_increment_prepared(values, i, dl1, dl2, p, out, flags, MECH_NONE, pre, 0)
        ok = cell_increment_prepared(values, i, dl1, dl3, p, out, flags, MECH_NONE, pre, 1) and ok_a
    if mech == MECH_ANY and p[P_RENEW] == RENEW_BIHEX:  # docs/mechanisms.md, "Renewal"
        renew_bihex(out, flags, i, 2.0 * p[P_R])
    flags[i, 10] = cross_contact(0.5 * (out[i, 1] - out[i, 9]), out[i, 7], out[i, 15],
                                 2.0 * p[P_R])
    return ok


@njit(cache=True, error_model="numpy")
def bihex_hertz_increments(values, work_a, work_b, p, out, flags):
    """:func:`bihex_increment` of every bi-hexagon of ``values`` with Hertz-Mindlin contacts and
    none between the hexagons: hexagon A of each by its length increments ``work_a[DL1]``,
    ``work_a[DL2]`` (δl1, δl2), B by ``work_b``'s (δl1, δl3), all at once
    (:func:`hmodel.cell.hertz_batch.update`, the same values to the last bit), then each cell's
    rebirth and contact flag. Returns False when a hexagon's increment failed."""
    ok_a = hertz_batch.update(values, work_a, p, out, flags, MECH_NONE, 0)
    ok = hertz_batch.update(values, work_b, p, out, flags, MECH_NONE, 1) and ok_a
    two_r = 2.0 * p[P_R]
    renew = p[P_RENEW] == RENEW_BIHEX
    for i in range(values.shape[0]):
        if renew:  # docs/mechanisms.md, "Renewal"
            renew_bihex(out, flags, i, two_r)
        flags[i, 10] = cross_contact(0.5 * (out[i, 1] - out[i, 9]), out[i, 7], out[i, 15], two_r)
    return ok


@njit(cache=True, inline="always", error_model="numpy")
def bihex_vsigma(v, i, kn, hertz, two_r, cross):
    """V σ in the cell frame, (nn, t1t1, t2t2), of bi-hexagon state ``v[i]`` (16 fields).

    Love-Weber (eq. 1.11) over the twelve contacts: each hexagon contributes eq. 1.12 in its own
    plane (its nn term to σ_nn, its tt term to σ_t1t1 for A, σ_t2t2 for B); the extra contacts
    of docs/model.md step 3 (Fig. 1.6): grains 1-4 once (shared) when l1 <= 2r, grains 2-6/3-5
    when l2 <= 2r, 7-10/8-9 when l3 <= 2r, each of force kn (2r - l), or c (2r - l)^(3/2) of
    Hertz-Mindlin contacts (``hertz`` = c; :func:`hmodel.cell.hertz.extra_force`); with
    ``cross`` nonzero, the eight contacts between the hexagons
    (:func:`hmodel.cell.cross.cross_vsigma`). Off-diagonal terms vanish by the mirror symmetries.
    """
    ann, att = contact_vsigma(v[i, 0], v[i, 1], math.cos(v[i, 2]), math.sin(v[i, 2]), v[i, 3],
                              v[i, 4], v[i, 5])
    bnn, btt = contact_vsigma(v[i, 8], v[i, 9], math.cos(v[i, 10]), math.sin(v[i, 10]),
                              v[i, 11], v[i, 12], v[i, 13])
    l1, l2, l3 = v[i, 6], v[i, 7], v[i, 15]
    nn = ann + bnn
    if l1 <= two_r:
        nn += extra_force(kn, hertz, two_r - l1) * l1
    if l2 <= two_r:
        att += 2.0 * extra_force(kn, hertz, two_r - l2) * l2
    if l3 <= two_r:
        btt += 2.0 * extra_force(kn, hertz, two_r - l3) * l3
    if cross != 0.0:
        cnn, ctt1, ctt2 = cross_vsigma(kn, hertz, two_r, v[i, 1] - v[i, 9], l2, l3)
        nn += cnn
        att += ctt1
        btt += ctt2
    return nn, att, btt


#: Bi-hexagons whose state-only part :func:`bihex_step_kernel` holds at a time: one increment
#: per state gains nothing from the preparation, and an array of every cell's (24 numbers a
#: cell) would more than double the memory a large batch moves.
STEP_CHUNK = 256


@njit(cache=True, error_model="numpy")
def bihex_step_kernel(values, dl, p, out, flags):
    """Advance every bi-hexagon (:func:`bihex_increment`); ``values``/``out`` (n, 16), ``dl``
    (n, 3) = (δl1, δl2, δl3), ``flags`` (n, 11). Returns the index of the first failed cell, or
    -1. Each cell's state-only part is prepared just before its increment, chunk by chunk
    (:data:`STEP_CHUNK`; the compiled trial's one closed form, the same values to the last bit)."""
    bad = -1
    n = values.shape[0]
    pre = np.empty((min(n, STEP_CHUNK), bihex_prepared_width(p)))
    for s in range(0, n, STEP_CHUNK):
        e = min(s + STEP_CHUNK, n)
        v, o, f = values[s:e], out[s:e], flags[s:e]  # views per chunk, not per cell
        for j in range(e - s):
            prepare_cell(v, j, p, pre)
            if not bihex_increment(v, j, dl[s + j, 0], dl[s + j, 1], dl[s + j, 2], p, o, f,
                                   pre, MECH_ANY) and bad < 0:
                bad = s + j
    return bad


@njit(cache=True, error_model="numpy")
def bihex_vsigma_kernel(values, kn, hertz, two_r, cross, out):
    """V σ in the cell frame, (nn, t1t1, t2t2) (n, 3), of bi-hexagon states (n, 16)
    (:func:`bihex_vsigma`)."""
    for i in range(values.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = bihex_vsigma(values, i, kn, hertz, two_r, cross)


def bihex_volume(params: Params, values: np.ndarray) -> np.ndarray:
    """Meso-volume [m^3] of bi-hexagon states (..., 16) for ``params.volume``.

    ``hexagon`` (default): the virtual box of eqs. 1.20-1.21 lifted, l1* l2* l3* with
    l1* = d2 + d1 cos α (mean of the two hexagons), l2* = 2 d1 sin α (A), l3* = 2 d1_b sin α_b
    (B); ``rectangle``: l1 l2 l3 (eq. 1.18 lifted); ``box``: (l1 + 2r)(l2 + 2r)(l3 + 2r)
    (eq. 1.19 lifted).
    """
    v = np.asarray(values, float)
    if params.volume == "rectangle":
        return v[..., 6] * v[..., 7] * v[..., 15]
    if params.volume == "box":
        two_r = 2.0 * params.radius
        return (v[..., 6] + two_r) * (v[..., 7] + two_r) * (v[..., 15] + two_r)
    l1s = 0.5 * (v[..., 1] + v[..., 0] * np.cos(v[..., 2]) + v[..., 9] + v[..., 8] * np.cos(v[..., 10]))
    return l1s * 2 * v[..., 0] * np.sin(v[..., 2]) * 2 * v[..., 8] * np.sin(v[..., 10])


def initial_bihex(params: Params, alpha0: np.ndarray) -> CellState:
    """Unloaded bi-hexagons with their own opening angles α0 (both hexagons alike: d1 = d2 = 2r,
    no force, lengths from eq. 1.2, l3 = l2)."""
    a = np.asarray(alpha0, float)
    d = 2.0 * params.radius
    l10, l20 = initial_lengths(params.radius, a)
    z = np.zeros_like(a)
    hexagon = [z + d, z + d, a, z, z, z, l10, l20]
    return CellState(np.ascontiguousarray(np.stack(hexagon + hexagon, axis=-1)))


def check_hexagon(solver) -> None:
    """Refuse a 2D cell solver that cannot step the hexagons of a bi-hexagon (one-line
    :class:`InputError` naming why): the decomposition into two H-cells sharing δl1
    (docs/model3d.md) holds for H-cells of eq. 1.7, whose state is eq. 1.2's eight fields and
    whose meso-stress is eq. 1.12 of them; a DEM cell solver (the 3D model's DEM cell is a solver
    of its own, ``dem:bihexagon``), a surrogate learned from DEM cells and a cell state of another
    kind (a learned ``meso`` summary) are not such a hexagon here. Read from the solver's
    declarations (:class:`~hmodel.cell.base.CellSolver`)."""
    if not isinstance(solver, CellSolver):
        raise InputError(f"not a cell solver: {solver!r}")
    name = solver.name
    if solver.n_lengths != 2:
        raise InputError(f"the hexagons of a bi-hexagon are 2D cells (two lengths), got the 3D cell "
                         f"solver {name!r}")
    if solver.dem_cells and solver.learned:
        raise InputError("the surrogate learned the DEM cell it was trained on, not the closed-form H-cell: "
                         "the 3D H-model's bi-hexagon is two closed-form H-cells sharing dl1, and "
                         "its learned 3D cell takes a surrogate of that H-cell (e.g. surrogate:default)")
    if solver.dem_cells:
        raise InputError(f"the 3D H-model's hexagons are H-cells of the closed form or a surrogate of it; "
                         f"{name!r} is a DEM cell solver (YADE): the 3D model's DEM cell is the "
                         "bi-hexagon of spheres, dem:bihexagon")
    if solver.state_kind != STATE_H_CELL:
        raise InputError(f"the cell solver {name!r} keeps other cell states than the H-cell's "
                         f"{len(FIELDS)} fields (eq. 1.2), whose eq. 1.12 stress the bi-hexagon sums; "
                         "give a surrogate of the H-cell's increment (e.g. surrogate:default)")


class BiHexSolver(CellSolver):
    """The bi-hexagonal 3D cell: two eq. 1.7 systems sharing δl1.

    The 3D counterpart of :class:`hmodel.cell.ClosedFormSolver`; its :meth:`step` takes three
    length increments. Used by :class:`hmodel.rev.Rev3D`.

    Parameters
    ----------
    hexagon : CellSolver, optional
        The 2D H-cell solver that steps each hexagon (default: the closed form, compiled). With
        l1, l2, l3 prescribed the closure is exactly two 2D H-cell increments, (δl1, δl2) for
        hexagon A and (δl1, δl3) for hexagon B (docs/model3d.md), so any solver of the 2D H-cell
        steps a bi-hexagon: a surrogate of the closed-form H-cell (``surrogate:default``)
        makes the **learned 3D cell**. Both hexagons of every bi-hexagon go through one call of
        ``hexagon.step`` (one batch of 2S H-cells). A learned hexagon has no compiled 3D trial:
        :meth:`kernel` is None and the REV runs on the generic loading driver. Refused
        (:func:`check_hexagon`): richer or DEM cells, surrogates of them, ``meso`` summary states.
    """

    #: lengths driven by the strain: l1 (n), l2 (t1), l3 (t2)
    n_lengths = 3
    state_kind = STATE_BIHEXAGON

    def __init__(self, hexagon: CellSolver | None = None):
        if hexagon is not None:
            check_hexagon(hexagon)
        #: the 2D solver of each hexagon
        self.hexagon = ClosedFormSolver() if hexagon is None else hexagon
        #: learned where the hexagons are
        self.learned = self.hexagon.learned
        #: whether both hexagons are the compiled closed form (:func:`bihex_step_kernel`)
        self.closed_form = type(self.hexagon) is ClosedFormSolver
        #: cells may start apart, each with its α0 in its state (``alpha0_spread``): the closed
        #: form's hexagons read nothing else of α0
        self.spread_alpha0 = self.closed_form
        #: the hexagons' (the closed form's: Hertz-Mindlin contacts, and bi-hexagons reborn),
        #: and, in closed form, contacts between the hexagons (:mod:`hmodel.cell.cross`)
        self.mechanisms = (self.hexagon.mechanisms | {"cross_contacts=frictionless"}
                           if self.closed_form else self.hexagon.mechanisms)
        #: the hexagon solver's name: ``closed-form``, ``surrogate``, ...
        self.name = self.hexagon.name
        #: exact to round-off in closed form; the hexagon solver's tolerance otherwise
        self.stress_rtol = float(self.hexagon.stress_rtol)
        #: two H-cells' state, flags and buffers (the 2D cell's, twice)
        self.bytes_per_cell = 2 * int(self.hexagon.bytes_per_cell)

    def __repr__(self) -> str:
        return "BiHexSolver()" if self.closed_form else f"BiHexSolver(hexagon={self.hexagon!r})"

    @property
    def counts(self) -> dict | None:
        """The hexagon solver's counters (a surrogate's cell updates, fallbacks; each hexagon
        counts once), or None."""
        return self.hexagon.counts

    @property
    def domain(self) -> dict | None:
        """The training domain of the hexagon solver, which sees the material's parameters as
        they are (a family surrogate's); None: any material."""
        return self.hexagon.domain

    @property
    def trained_params(self) -> dict | None:
        """The material parameters the hexagon solver's cells were trained with, or None."""
        return self.hexagon.trained_params

    def field_names(self) -> tuple[str, ...]:
        return BIHEX_FIELDS

    def initial(self, params: Params, shape: tuple[int, ...] = ()) -> CellState:
        """Unloaded bi-hexagons of shape ``shape`` (opening angle params.alpha0)."""
        return initial_bihex(params, np.full(shape, params.alpha0))

    def initial_cells(self, params: Params, alpha0: np.ndarray) -> CellState:
        return initial_bihex(params, alpha0)

    def meso(self, params: Params, state: CellState) -> tuple[np.ndarray, np.ndarray]:
        """(V σ in the cell frame (..., 6), meso-volume (...)).

        V σ [N m] as the symmetric 3x3 tensor in the frame (n, t1, t2), components in the order
        (nn, t1t1, t2t2, t1t2, nt2, nt1) (tensor, not engineering, shear; compression
        positive); the shear terms are zero by the cell's symmetries. Volume by
        :func:`bihex_volume`.
        """
        values = np.ascontiguousarray(np.asarray(state.values, float).reshape(-1, len(BIHEX_FIELDS)))
        diag = np.empty((values.shape[0], 3))
        p = kernel_params(params)
        bihex_vsigma_kernel(values, params.kn, p[P_HERTZ], 2.0 * params.radius, p[P_CROSS], diag)
        out = np.zeros((values.shape[0], 6))
        out[:, :3] = diag
        shape = state.values.shape[:-1]
        return out.reshape(*shape, 6), bihex_volume(params, state.values)

    def kernel(self, params: Params) -> CellKernel | None:
        """None for a hexagon solver other than the closed form (the learned 3D cell runs on the
        generic loading driver: the compiled 3D trial applies eq. 1.7). The closed form's
        compiled increment: the 2D closed form's packed parameters
        (:func:`hmodel.cell.closed_form.kernel_params`), which both hexagons' increments take
        (:func:`bihex_increment`, called by the compiled 3D REV trial
        :func:`hmodel.rev.kernels3d.bihex_trial`)."""
        check_params(params)
        if not self.closed_form:
            return None
        return CellKernel(kernel_params(params))

    def fractions(self, params: Params, state: CellState) -> dict[str, np.ndarray]:
        """The hexagon solver's own diagnostics (a gated surrogate's ``gated``), as the mean of
        the two hexagons of each bi-hexagon; none in closed form."""
        if self.closed_form:
            return {}
        v = np.asarray(state.values, float)
        both = CellState(np.ascontiguousarray(np.stack([v[..., :8], v[..., 8:]], axis=-2)))
        return {k: np.mean(np.asarray(hit, float), axis=-1)
                for k, hit in self.hexagon.fractions(params, both).items()}

    def step(self, params: Params, state: CellState, dl1, dl2, dl3) -> tuple[CellState, CellFlags]:
        """One increment of every bi-hexagon.

        Parameters
        ----------
        params : Params
        state : CellState
            Bi-hexagons before the increment, values (S, 16).
        dl1, dl2, dl3 : array_like, broadcastable to S
            Increments [m] of l1 (along n, shared by both hexagons), l2 (hexagon A, along t1)
            and l3 (hexagon B, along t2); negative is shortening.

        Returns
        -------
        (CellState, CellFlags)
            State (S, 16) and flags (S, 11) after the increment.
        """
        check_params(params)
        values = np.asarray(state.values, float)
        if values.shape[-1] != len(BIHEX_FIELDS):
            raise InputError(f"a bi-hexagon state has {len(BIHEX_FIELDS)} fields, got {values.shape[-1]}")
        shape = values.shape[:-1]
        flat = np.ascontiguousarray(values.reshape(-1, len(BIHEX_FIELDS)))
        dl = np.empty((flat.shape[0], 3))
        for k, d in enumerate((dl1, dl2, dl3)):
            dl[:, k] = np.broadcast_to(d, shape).reshape(-1)
        if not self.closed_form:
            if params.cross_contacts != "none":
                raise InputError(f"cross_contacts={params.cross_contacts} is implemented by the "
                                 f"closed-form bi-hexagon only, not by {self.name!r} hexagons")
            out, flags = self.compose(params, flat, dl)
            return (CellState(out.reshape(*shape, len(BIHEX_FIELDS))),
                    CellFlags(flags.reshape(*shape, len(BIHEX_FLAGS))))
        out = np.empty_like(flat)
        flags = np.empty((flat.shape[0], len(BIHEX_FLAGS)), dtype=np.bool_)
        p = kernel_params(params)
        bad = bihex_step_kernel(flat, dl, p, out, flags)
        if bad >= 0:
            raise SolverError(
                f"bi-hexagon increment could not be solved (singular eq. 1.7 or non-finite result) "
                f"for cell {np.unravel_index(bad, shape) if shape else ()} with state "
                f"{dict(zip(BIHEX_FIELDS, flat[bad].round(12)))} and dl={tuple(dl[bad].round(15))}")
        return (CellState(out.reshape(*shape, len(BIHEX_FIELDS))),
                CellFlags(flags.reshape(*shape, len(BIHEX_FLAGS))))

    def compose(self, params: Params, flat: np.ndarray, dl: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bi-hexagons (S, 16) advanced by ``dl`` (S, 3) with the hexagon solver: hexagons A
        (S, 8) driven by (δl1, δl2) and B (S, 8) by (δl1, δl3), stacked as one batch of 2S
        H-cells in one ``hexagon.step`` call; returns the states (S, 16) and flags (S, 11)."""
        S = flat.shape[0]
        cells = CellState(np.concatenate([flat[:, :8], flat[:, 8:]]))
        new, fl = self.hexagon.step(params, cells, np.concatenate([dl[:, 0], dl[:, 0]]),
                                    np.concatenate([dl[:, 1], dl[:, 2]]))
        nv, nf = np.asarray(new.values, float), np.asarray(fl.flags, bool)
        out = np.ascontiguousarray(np.concatenate([nv[:S], nv[S:]], axis=1))
        flags = np.empty((S, len(BIHEX_FLAGS)), dtype=np.bool_)
        flags[:, :5], flags[:, 5:10] = nf[:S], nf[S:]
        two_r = 2.0 * params.radius
        dn = 0.5 * (out[:, 1] - out[:, 9])
        flags[:, 10] = dn * dn + 0.25 * (out[:, 7] ** 2 + out[:, 15] ** 2) < two_r * two_r
        return out, flags


__all__ = ["BIHEX_FIELDS", "BIHEX_FLAGS", "VOLUMES_3D", "BiHexSolver", "bihex_increment",
           "bihex_prepared_width", "bihex_volume", "bihex_vsigma", "check_hexagon", "check_params",
           "initial_bihex"]
