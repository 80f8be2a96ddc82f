"""The ``meso`` formulation: surrogates of richer cells (DEM mesostructures) through a summary state.

A richer DEM cell (the hexagon with a centre grain, ...) has no closed form and a state of
8 + 2g + g(g-1)/2 fields (grain centres, contact shear forces; :mod:`hmodel.cell.geometry`). Its
surrogate carries a summary of that state instead, 11 fields (:data:`STATE_FIELDS`): the 8
H-cell fields measured on the six hexagon grains (:data:`hmodel.cell.FIELDS`), which describe
the cell's shape and its outer contacts, and the cell's meso-stress times its meso-volume,
``Vs = V sigma`` (nn, tt, nt), the Love-Weber sum over all its contacts (eq. 1.11). What the
grains inside do enters through Vs, which is also all the REV needs of a cell (eqs. 1.13-1.14).

Learned fields z: alpha, N1, N2, T1 and, for richer cells, Vs_nn and Vs_tt (for H-cells Vs is
eq. 1.12 of the others). Vs_nt is not learned: eq. 1.12 has no nt term, and in DEM the free
inner grain leaves the cell's axis by little (|Vs_nt| <= 0.5 % of |Vs| in the hexagon-center
data; learning it, from its noise, made the other outputs worse). The network maps the summary before (forces over F = kn 2r, lengths over 2r) to an
incrementally multi-linear response: for a cell strain increment de, with e = de/m0, m0 = 1e-3,

    X = (alpha, l1/2r, l2/2r, N1/F, N2/F, T1/F, Vs_nn/F2r, Vs_tt/F2r)
    dz = A(X) e + sum_k <n_k(X) . e - c_k(X)^2> B_k(X),   k = 1..K (``mechanisms``, default 4),

<x> = max(x, 0): the network outputs the tangent A and, for each mechanism, a loading direction
n_k, a threshold c_k^2 >= 0 and a flow B_k. This is the form of a rate-independent cell's
increment to first order: linear within a contact regime (every contact sticking, sliding or
open), and continuous with a kink where the increment crosses into another regime: a contact
starts to slide on the line n_k . e = c_k^2 of the Coulomb trial (eq. 1.3), through e = 0 for a
contact already on the cone, beyond it for one inside (the increment must first use up the
margin), with one mechanism per independent kink. The increments of the data (<= 0.2 %) change
the state so little that the second-order term is below the data's noise. The form gives
exactly no change for no strain (no bias to accumulate over the thousands of increments of a
path); the network sees the state only, so the REV's Newton iterations and their
finite-difference probes reuse one evaluation per state. Loss: on dz/m0, an increment's error
counting in proportion to its size; or, with ``TrainConfig.secant_floor``, on the secant dz/|de|
down to increments of that size, which gives the first, elastic increments from a state their
weight (on the hexagon-center cell the loss on dz/m0 left them to the large increments' sliding,
and every network's ANN-REV was 2-4 % of peak q off at 100 kPa; see the documentation's DEM
cells page). Rows where a closed cell opens (forces cut to zero within the increment: not of
this form) are left out.

The way back enforces what holds for every such cell: lengths from the strain, d1 and d2 from
alpha and the lengths (eq. 1.2), N1, N2 >= 0 and zero where the geometry has the grains clearly
apart (d > 2r (1 + 1e-3)), |T1| <= tan(phi_g) N1 (eq. 1.3), Vs_nn, Vs_tt >= 0 (compressive contact forces),
and the meso-volume of the six driven
grains' hexagon, V = 2 d1 sin(alpha) (d2 + d1 cos(alpha)) (eq. 1.20, the DEM cells' meso-volume).
A cell with free grains (the hexagon-center cell) also gets a loose-cage gate: where the hexagon's
clearance at its centre, min(l1/2 - r, |(d2/2, l2/2)| - r), exceeds the reach of its free grains
(the sum of their radii) by more than gap_tol, they can rest without force and V sigma is the
hexagon's own, eq. 1.12 of the advanced fields; the learned inner part V sigma - eq. 1.12 fades
out linearly over the last ``cage_ramp`` of the reach before that. (On the hexagon-center DEM data,
the rows this gate calls loose have V sigma within 1 % of max |V sigma| of eq. 1.12. Without the
gate, cells that had opened completely in a REV regained a learned stress under further
extension; with a sudden switch instead of the ramp, a REV's q dropped by up to 30 % of its peak
in one increment where cages loosened.)

Rollout training (``TrainConfig.rollout``): single-increment errors pile up along a path, and a
REV feeds each cell its own previous output. :meth:`windows` cuts the data's paths (consecutive
start states of a Dataset 2) into windows of a few steps, and :meth:`rollout_error` steps the
network along them through the same way back as the REV (:meth:`_advanced`, NumPy and torch
alike), adding that error to the loss. Measured on the hexagon-center cell (benchmarks/dem_ann.py,
docs/dem.md): single-cell rollouts along the data's paths and cells driven along a DEM-REV's own
drained histories drift far less; it costs some accuracy of the first increments from rest.

What was tried before this form and measured worse is in the notes of the documentation
(2026-11-26, the hexagon-center ANN-REV).

Training rows come from any cell solver: a richer DEM cell's extra state columns give its
Love-Weber stress; for H-cells (``closed-form``, ``dem:standard``) it is eq. 1.12 of the fields
(with the extra contacts of over-compressed cells), as in the REV.

In the cell solver, a meso network sees the state only: one evaluation per increment gives the
learned response (:meth:`MesoFormulation.responses`; an ensemble's mean) that every trial
increment from that state applies in the compiled way back
(:func:`hmodel.cell.meso_kernel.meso_increment`), in the REV's compiled loading path
(:meth:`MesoFormulation.kernel`) and in :meth:`MesoFormulation.step_cells` alike.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..cell.base import CellKernel
from ..cell.geometry import CellGeometry
from ..cell.meso_kernel import advance_cells, kernel_params, pack_outputs, pack_responses
from ..cell.mesostress import contact_vsigma, meso_vsigma
from ..cell.state import FIELDS, CellState, initial_lengths
from ..errors import InputError
from ..params import Params
from .formulations import OUTPUTS, MaterialScales, Networks
from .torch_support import require_torch

MESO_FIELDS = ("Vs_nn", "Vs_tt", "Vs_nt")
STATE_FIELDS = FIELDS + MESO_FIELDS
_COL = {k: j for j, k in enumerate(STATE_FIELDS)}


@dataclass(frozen=True)
class MesoFormulation(MaterialScales):
    """Summary state, inputs, targets and decoding for cells of the solver ``cell``."""

    params: Params  #: the material the data was made with
    cell: str = "closed-form"  #: the data's cell solver (``dem:hexagon-center``, ...)
    mechanisms: int = 4  #: kinks of the incremental response (see the module docstring)
    #: Largest cell strain of one network step (None: any, one step per increment). A network
    #: trained with rollouts in sub-steps (``TrainConfig.rollout_substeps``) of this size is
    #: stepped so in the REV, whatever the REV increment: the cells' strain paths are then cut
    #: alike at every increment, and a learned response no longer depends on it (see the DEM
    #: cells page: rate independence).
    cell_step: float | None = None
    name: str = "meso"
    logit_column = None
    n_state = len(STATE_FIELDS)
    #: float32 inference: checked against float64 on every compared DEM-REV path.
    single_precision = True
    #: Two columns after one network's outputs, where :meth:`responses` puts cos and sin of alpha.
    spare_columns = 2
    #: Members' increments average (see :mod:`hmodel.surrogate.solver`).
    ensembles = True

    @property
    def richer(self) -> bool:
        """A richer cell (more than the H-cell's 8 fields): V sigma is learned, not eq. 1.12."""
        return self.geometry.n_fields > len(FIELDS)

    @property
    def learned(self) -> tuple[str, ...]:
        """Fields whose increments the network gives: the hexagon's shape and contact forces,
        and for richer cells V sigma (nn, tt)."""
        return ("alpha", "N1", "N2", "T1") + (("Vs_nn", "Vs_tt") if self.richer else ())

    @property
    def outputs(self) -> tuple[str, ...]:
        return OUTPUTS + ("Vs_nn_next", "Vs_tt_next")

    @property
    def input_names(self) -> tuple[str, ...]:
        return ("alpha", "l1/2r", "l2/2r", "N1/F", "N2/F", "T1/F", "Vs_nn/F2r", "Vs_tt/F2r")

    @property
    def n_outputs(self) -> int:
        """A (row-major, len(learned) x 2), then (n_k, c_k, B_k) per mechanism."""
        L = len(self.learned)
        return 2 * L + self.mechanisms * (L + 3)
    m0 = 1e-3  #: strain scale of the inputs and targets
    #: Relative gap beyond which a hexagon contact is open whatever the network says: well above
    #: the overlaps (~1e-4 of 2r at 100 kPa), so that a small error of the learned alpha, which
    #: eq. 1.2 turns into d1, never opens a contact (a gate at d > 2r did, all at once in a REV).
    gap_tol = 1e-3
    #: Width (relative to the free grains' reach) over which a cage's inner part fades out.
    cage_ramp = 1e-3

    def __post_init__(self) -> None:
        if not (self.cell == "closed-form" or self.cell.startswith("dem:")):
            raise InputError(f"the meso formulation needs H-cell or DEM data, got cells of {self.cell!r}")
        if self.cell_step is not None and not (math.isfinite(self.cell_step) and self.cell_step > 0):
            raise InputError(f"cell_step must be a positive strain, got {self.cell_step}")

    def to_dict(self) -> dict:
        return {"name": self.name, "params": self.params.to_dict(), "cell": self.cell,
                "mechanisms": self.mechanisms, "cell_step": self.cell_step}

    @cached_property
    def geometry(self) -> CellGeometry:
        """The cells' geometry: state layout and Love-Weber sum (H-cells: the standard cell's)."""
        return CellGeometry.from_spec(self.cell if self.cell.startswith("dem:") else "dem:standard")[0]

    # -- summary state ------------------------------------------------------------------
    def vsigma(self, full: np.ndarray) -> np.ndarray:
        """(V sigma_nn, V sigma_tt, V sigma_nt) (n, 3) of full cell states (n, n_fields): the
        Love-Weber sum of a richer cell's contacts; eq. 1.12 of an H-cell's fields, as the REV
        computes it (a sum over contacts rebuilt from positions would differ where the closed
        form's incremental d1, alpha drift from eq. 1.2 at second order: 1e-7 of a length is
        ~1e-3 of a force)."""
        full = np.asarray(full, float)
        if full.shape[1] == len(FIELDS):
            vs = meso_vsigma(self.params, CellState(np.ascontiguousarray(full)))
            return np.column_stack([vs, np.zeros(len(full))])
        return self.geometry.love_weber(self.params, full)[0]

    def summary(self, full: np.ndarray) -> np.ndarray:
        """Summary rows (n, 11) of full cell states (n, n_fields) of the data's solver."""
        return np.hstack([full[:, :8], self.vsigma(full)])

    def initial(self, params: Params, shape: tuple[int, ...] = ()) -> CellState:
        """Summary of unloaded cells of opening angle ``self.params.alpha0``, the one the model
        was trained for (``params``, the run's material, adds nothing to it)."""
        return CellState(np.broadcast_to(self._unloaded, (*shape, self.n_state)).copy())

    def initial_cells(self, params: Params, alpha0: np.ndarray) -> CellState:
        """Unloaded cells: a summary state knows one opening angle only, the trained one."""
        alpha0 = np.asarray(alpha0, float)
        if not np.allclose(alpha0, params.alpha0, rtol=0.0, atol=1e-12):
            raise InputError("a meso surrogate's cells start at the opening angle it was trained "
                             f"for (alpha0 = {np.degrees(params.alpha0):.6g} deg)")
        return self.initial(params, alpha0.shape)

    @cached_property
    def _unloaded(self) -> np.ndarray:
        """The summary (11,) of an unloaded cell."""
        full = (CellState.initial(self.params, (1,)) if self.cell == "closed-form"
                else self.geometry.initial(self.params, (1,))).values
        return self.summary(full)[0]

    def meso(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(V sigma) (..., 3) and meso-volume (...) of summary states (..., 11), for the REV."""
        d1, d2, a = values[..., 0], values[..., 1], values[..., 2]
        return values[..., 8:11], 2 * d1 * np.sin(a) * (d2 + d1 * np.cos(a))  # eq. 1.20

    def augment(self, c: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Database columns plus the meso-stress before and after (``Vs_nn``, ``Vs_nn_next``, ...)."""
        if "Vs_nn" in c:
            return c
        n_extra = self.geometry.n_fields - 8
        if n_extra and "state_extra" not in c:
            raise InputError(f"rows of {self.cell} cells need their state_extra columns (a DEM dataset "
                             f"or a sample made from one)")
        out = dict(c)
        for suffix, extra in (("", "state_extra"), ("_next", "state_extra_next")):
            full = np.column_stack([c[k + suffix] for k in FIELDS]
                                   + ([np.asarray(c[extra], float).reshape(len(c["deps1"]), -1)] if n_extra else []))
            vs = self.vsigma(full)
            for j, k in enumerate(MESO_FIELDS):
                out[k + suffix] = vs[:, j]
        return out

    # -- network inputs and targets -----------------------------------------------------
    def features(self, v: np.ndarray) -> np.ndarray:
        """X (n, 8 or 9) from summary states v (n, 11)."""
        d, F = 2 * self.radius, self.force_scale
        return _stack([v[:, 2], v[:, 6] / d, v[:, 7] / d, v[:, 3] / F, v[:, 4] / F, v[:, 5] / F,
                       v[:, 8] / (F * d), v[:, 9] / (F * d)])

    def _scales(self) -> np.ndarray:
        F, d = self.force_scale, 2 * self.radius
        return np.array([1.0, F, F, F] + [F * d] * (len(self.learned) - 4))

    def _hexagon(self, v: np.ndarray) -> np.ndarray:
        """V sigma (n, 3) of the six hexagon grains' contacts: eq. 1.12 of the first 8 fields."""
        vs = meso_vsigma(self.params, CellState(np.ascontiguousarray(v[:, :8])))
        return np.column_stack([vs, np.zeros(len(v))])

    def _learned_values(self, v: np.ndarray) -> np.ndarray:
        """The learned fields (n, len(learned)) of summary states v (n, 11)."""
        return _stack([v[:, 2], v[:, 3], v[:, 4], v[:, 5]] + ([v[:, 8], v[:, 9]] if self.richer else []))

    def inputs(self, c: dict[str, np.ndarray]) -> np.ndarray:
        c = self.augment(c)
        return self.features(np.column_stack([c[k] for k in STATE_FIELDS]))

    def targets(self, c: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """dz/m0 (n, len(learned)) and weights: 0 for the contact forces N1, N2, T1 on the rows
        where a closed hexagon contact opens. There they are cut to zero within the increment,
        which is not of the learned form (the kink does not pass through de = 0); the geometric
        gate of :meth:`advance` opens them instead. alpha and V sigma are fitted on every row.
        (Leaving these rows out entirely dropped 30 % of the hexagon-center rows, whose type-2
        contacts open as the centre grain pushes grains 2 and 3 apart.)"""
        c = self.augment(c)
        before = self._learned_values(np.column_stack([c[k] for k in STATE_FIELDS]))
        after = self._learned_values(np.column_stack([c[f"{k}_next"] for k in STATE_FIELDS]))
        Y = (after - before) / self._scales() / self.m0
        was_open = (c["N1"] <= 0) | (c["N2"] <= 0)
        opens = (np.asarray(c["open1"], bool) | np.asarray(c["open2"], bool)) & ~was_open
        W = np.ones_like(Y)
        W[opens, 1:4] = 0.0
        return Y, W

    def aux(self, c: dict[str, np.ndarray]) -> np.ndarray:
        """e = de/m0 (n, 2), which the head applies the response to."""
        return np.column_stack([c["deps1"], c["deps2"]]) / self.m0

    def head(self, out, e, target=None):
        """dz/m0 = A e + sum_k <n_k . e - c_k^2> B_k from network outputs (n, n_outputs); NumPy
        or torch."""
        return self.apply(self.response(out), e)

    def response(self, out):
        """The response of network outputs (n, n_outputs): tangent A (n, L, 2) and, per
        mechanism, n_k (n, K, 2), c_k^2 (n, K) and B_k (n, K, L); NumPy or torch."""
        L = len(self.learned)
        mech = out[:, 2 * L:].reshape(-1, self.mechanisms, L + 3)
        return out[:, :2 * L].reshape(-1, L, 2), mech[:, :, :2], mech[:, :, 2] ** 2, mech[:, :, 3:]

    @staticmethod
    def apply(response, e):
        """dz/m0 of a :meth:`response` for strains e = de/m0 (n, 2); NumPy or torch."""
        A, n, c2, B = response
        e1, e2 = e[:, 0:1], e[:, 1:2]
        load = n[:, :, 0] * e1 + n[:, :, 1] * e2 - c2
        einsum = np.einsum if isinstance(load, np.ndarray) else _torch().einsum  # no broadcast temporary
        return A[:, :, 0] * e1 + A[:, :, 1] * e2 + einsum("nk,nkl->nl", _positive(load), B)

    @staticmethod
    def mean_response(responses: list) -> tuple:
        """The response whose increment is the mean of the members' (an ensemble; NumPy): the
        mean tangent, and every member's mechanisms with its flow divided by their number."""
        if len(responses) == 1:
            return responses[0]
        A, n, c2, B = zip(*responses)
        return (sum(A) / len(A), np.concatenate(n, axis=1), np.concatenate(c2, axis=1),
                np.concatenate(B, axis=1) / len(B))

    def increment(self, out: np.ndarray, e1: np.ndarray, e2: np.ndarray) -> np.ndarray:
        """dz/m0 from network outputs and cell strains."""
        return self.head(out, np.column_stack([e1, e2]) / self.m0)

    def decode(self, c: dict[str, np.ndarray], out: np.ndarray) -> dict[str, np.ndarray]:
        """Predicted summary after the increment (``*_next`` columns) from network outputs."""
        c = self.augment(c)
        v = np.column_stack([c[k] for k in STATE_FIELDS])
        dl = np.column_stack([c["l1_next"] - c["l1"], c["l2_next"] - c["l2"]])
        new, _ = self.advance(v, self.increment(out, c["deps1"], c["deps2"]), dl)
        return {f"{k}_next": new[:, _COL[k]] for k in ("alpha", "N1", "N2", "T1") + MESO_FIELDS}

    # -- cell solver ----------------------------------------------------------------------
    def advance(self, v: np.ndarray, Y: np.ndarray, dl: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Summary states after length increments dl (n, 2), from targets Y = dz/m0; and flags.

        The lengths follow the strain, alpha the network, d1 and d2 the geometry (eq. 1.2); the
        normal forces the network, N >= 0, and zero where the geometry has the grains apart
        (d > 2r (1 + gap_tol): a learned force never holds an open contact); T1 the
        network within the Coulomb bound (eq. 1.3); V sigma is eq. 1.12 of these for H-cells, and
        for richer cells the learned V sigma_nn, V sigma_tt >= 0 (compressive contact forces)
        with V sigma_nt = 0."""
        cols = self._advanced(v, Y, dl)
        new = np.column_stack(cols + [np.zeros(len(v))] * (len(STATE_FIELDS) - len(cols)))
        if not self.richer:
            new[:, 8:11] = self._hexagon(new)
        n1, t1, l1, l2 = cols[3], cols[5], cols[6], cols[7]
        two_r = 2.0 * self.radius
        flags = np.column_stack([(n1 > 0) & (np.abs(t1) >= self.tan_phi * n1 * (1 - 1e-9)),
                                 n1 == 0, cols[4] == 0, l1 <= two_r, l2 <= two_r])
        return new, flags

    def _advanced(self, v, Y, dl) -> list:
        """The columns of :meth:`advance` (V sigma only for richer cells), for NumPy arrays or
        torch tensors alike: the same way back in the REV and in rollout training."""
        where, minimum, maximum, sin, cos = _ops(v)
        u = self._learned_values(v) + Y * _like(self._scales() * self.m0, Y)
        a = u[:, 0]
        l1, l2 = v[:, 6] + dl[:, 0], v[:, 7] + dl[:, 1]
        d1 = l2 / (2.0 * sin(a))  # eq. 1.2
        d2 = l1 - 2.0 * d1 * cos(a)
        apart = 2.0 * self.radius * (1.0 + self.gap_tol)
        n1 = where(d1 < apart, _positive(u[:, 1]), 0.0 * u[:, 1])
        n2 = where(d2 < apart, _positive(u[:, 2]), 0.0 * u[:, 2])
        t1 = minimum(maximum(u[:, 3], -self.tan_phi * n1), self.tan_phi * n1)  # eq. 1.3
        cols = [d1, d2, a, n1, n2, t1, l1, l2]
        if not self.richer:
            return cols
        vs = [_positive(u[:, 4]), _positive(u[:, 5])]
        reach, r_n, r_t = self._cage
        if reach:  # a loose cage: the inner grains carry nothing, V sigma is the hexagon's
            clearance = minimum(l1 / 2 - r_n, ((d2 / 2) ** 2 + (l2 / 2) ** 2) ** 0.5 - r_t)
            # weight of the learned inner part: 1 while the cage holds the grain, 0 once it is
            # loose by gap_tol, linear between (V sigma stays continuous in the strain)
            w = (reach * (1.0 + self.gap_tol) - clearance) / (reach * self.cage_ramp)
            w = minimum(maximum(w, 0.0 * w), 0.0 * w + 1.0)
            hexagon = contact_vsigma.py_func(d1, d2, cos(a), sin(a), n1, n2, t1)  # eq. 1.12
            vs = [h + w * (x - h) for h, x in zip(hexagon, vs)]
        return cols + vs

    @cached_property
    def _cage(self) -> tuple[float, float, float]:
        """The reach of the cell's free grains, half the span of a chain of them all (the sum of
        their radii; 0 without free grains: a cage whose clearance at its centre exceeds it holds
        them without force), and the radii of the grains driven along n (1, 4) and t (2, 3, 5, 6)."""
        m = self.geometry.cell(self.params, self.params.alpha0)
        reach = sum(r for r, d in zip(m.radii, m.drive) if d == "free")
        return float(reach), float(m.radii[0]), float(m.radii[1])

    # -- the cell solver's side ----------------------------------------------------------
    def max_increment(self, input_range: np.ndarray | None) -> float:
        """:attr:`cell_step`; without it any (the response is homogeneous in the increment)."""
        return math.inf if self.cell_step is None else self.cell_step

    def kernel(self, net: Networks, params: Params) -> CellKernel | None:
        """The compiled increment: the learned responses of the states (one network evaluation
        per increment), which every Newton trial applies in
        :func:`hmodel.cell.meso_kernel.meso_increment`. None with a :attr:`cell_step`: each
        sub-step needs the network at its own state, and the generic path takes them
        (:meth:`hmodel.surrogate.solver.SurrogateSolver.step`)."""
        if self.cell_step is not None:
            return None
        return CellKernel(kernel_params(self, params), lambda values: self.responses(net, values))

    def step_cells(self, net, params, v, e1, e2, dl):
        """One learned increment of summary states v (n, 11), in the compiled way back (the
        NumPy one, :meth:`advance`, in one pass; tested against it)."""
        new, flags, _ = advance_cells(v, np.ascontiguousarray(dl, float), kernel_params(self, params),
                                      self.responses(net, v))
        return new, flags

    def responses(self, net: Networks, v: np.ndarray) -> np.ndarray:
        """The learned responses (an ensemble's mean, :meth:`mean_response`) of summary states
        v (n, 11), which every trial increment from these states applies, as the compiled
        trial's rows (:func:`~hmodel.cell.meso_kernel.pack_responses`; one network's outputs are
        those rows already, followed by cos and sin of alpha in its two spare columns). There is
        no closed form to fall back to: cells outside the training domain stop the run or are
        extrapolated, counted either way."""
        X = self.features(v)
        outs, out = net.outputs(v, X)
        net.count_outside(out, lambda i: ", ".join(f"{k}={x:.4g}" for k, x in zip(self.input_names, X[i])))
        width = self.n_outputs
        if len(outs) == 1:
            wide = outs[0] if outs[0].shape[1] == width + self.spare_columns else None
            return pack_outputs(outs[0][:, :width], len(self.learned), v, wide)
        return pack_responses(self.mean_response([self.response(o[:, :width]) for o in outs]), v)

    # -- rollout training -------------------------------------------------------------------
    def windows(self, c: dict[str, np.ndarray], length: int) -> dict[str, np.ndarray]:
        """Stretches of ``length`` steps along the data's paths, for rollout training.

        The start states of a Dataset 2 (3) lie along paths (``path_id``: a proportional path
        of one cell, or a REV's cell along its loading), every ``start_every`` of strain:
        consecutive ones are the path's own steps, whose cell strain their lengths give. From
        every start state, a window holds the next ``length`` steps (fewer near a path's end,
        padded with zero steps of mask 0): summary states ``z0`` (W, 11), e = de/m0
        ``e`` (W, T, 2), length increments ``dl`` (W, T, 2), the learned fields after each step
        ``target`` (W, T, len(learned)) and ``mask`` (W, T)."""
        c = self.augment(c)
        key = np.column_stack([c["path_id"], c["start_strain"]])
        _, first = np.unique(key, axis=0, return_index=True)  # sorted by path, then strain
        pid, strain = c["path_id"][first], c["start_strain"][first]
        l0 = np.column_stack(initial_lengths(self.radius, c["alpha0"][first]))
        states = np.column_stack([c[k][first] for k in STATE_FIELDS])
        learned = self._learned_values(states)
        W = len(first)
        # each path's spacing of start states: its smallest step (the sample may lack some)
        paths, inverse = np.unique(pid, return_inverse=True)
        same = np.flatnonzero(np.diff(pid) == 0)
        spacing = np.full(len(paths), np.inf)
        np.minimum.at(spacing, inverse[same], np.diff(strain)[same])
        spacing = spacing[inverse]
        out = {"z0": states, "e": np.zeros((W, length, 2)), "dl": np.zeros((W, length, 2)),
               "target": np.zeros((W, length, learned.shape[1])), "mask": np.zeros((W, length))}
        for k in range(length):
            nxt = np.arange(W) + k + 1
            ok = nxt < W
            nxt = np.where(ok, nxt, W - 1)
            prev = nxt - 1
            ok &= (pid[nxt] == pid) & ((k == 0) | (out["mask"][:, max(k - 1, 0)] > 0))
            step = strain[nxt] - strain[prev]
            ok &= np.abs(step - spacing[nxt]) <= 1e-6 * spacing[nxt]  # a start state the sample lacks ends it
            dl = states[nxt, 6:8] - states[prev, 6:8]
            out["e"][ok, k] = -(dl / l0)[ok] / self.m0  # cell strain on the initial lengths
            out["dl"][ok, k] = dl[ok]
            out["target"][ok, k] = learned[nxt][ok]
            out["mask"][ok, k] = 1.0
        keep = out["mask"][:, 0] > 0
        return {k: a[keep] for k, a in out.items()}

    def rollout(self, net, z0, e, dl, scale_inputs, substeps: int = 1):
        """The learned fields (W, T, len(learned)) after each step of windows rolled out with the
        network ``net`` (torch, float64 states): each step's state is the previous step's
        output, as in a REV; each data step taken in ``substeps`` equal network steps (a REV at
        a finer increment than the data's; experimental, ``TrainConfig.rollout_substeps``)."""
        z = z0
        fields = []
        for k in range(e.shape[1]):
            for _ in range(substeps):
                out = net(scale_inputs(self.features(z)).float()).double()
                cols = self._advanced(z, self.head(out, e[:, k] / substeps), dl[:, k] / substeps)
                z = _stack(cols + [0.0 * cols[0]] * (len(STATE_FIELDS) - len(cols)))
            fields.append(self._learned_values(z))
        return _torch().stack(fields, 1)

    def rollout_error(self, net, z0, e, dl, target, mask, scale_inputs, substeps: int = 1):
        """Mean squared error (in units of dz/m0) of the learned fields along windows rolled out
        with ``net`` (:meth:`rollout`) against ``target`` (W, T, len(learned)), steps weighed
        by ``mask`` (W, T)."""
        scales = _like(self._scales() * self.m0, z0)
        err = (self.rollout(net, z0, e, dl, scale_inputs, substeps) - target) / scales
        return ((err * err).mean(2) * mask).sum() / mask.sum().clamp(min=1.0)


def _ops(a):
    """where, minimum, maximum, sin, cos of NumPy or torch, after the type of ``a``."""
    if isinstance(a, np.ndarray):
        return np.where, np.minimum, np.maximum, np.sin, np.cos
    torch = require_torch()
    return torch.where, torch.minimum, torch.maximum, torch.sin, torch.cos


_torch = require_torch


def _positive(x):
    return 0.5 * (x + abs(x))


def _like(const: np.ndarray, a):
    """``const`` as an array of ``a``'s kind (a torch tensor of its dtype and device)."""
    if isinstance(a, np.ndarray):
        return const
    torch = require_torch()
    return torch.as_tensor(const, dtype=a.dtype, device=a.device)


def _stack(cols: list):
    if isinstance(cols[0], np.ndarray):
        return np.column_stack(cols)
    torch = require_torch()
    return torch.stack(cols, dim=1)
