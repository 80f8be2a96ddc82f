"""The ``meso`` formulation: surrogates of richer cells (DEM mesostructures) through a summary state.

:class:`MesoFormulation` learns any cell, the H-cell and richer DEM cells alike, through its
summary state (:mod:`hmodel.surrogate.formulations.meso_summary`: the 8 H-cell fields and the
Love-Weber meso-stress times the meso-volume), with a network that sees the summary only and
outputs an incrementally multi-linear response (:mod:`hmodel.surrogate.formulations.meso_head`),
trained on single increments and, for richer cells, on rollouts along the data's paths
(:mod:`hmodel.surrogate.formulations.meso_rollout`, whose :class:`MesoTraining` holds the
formulation's training options).

Loss: on dz/m0, an increment's error counting in proportion to its size; or, with
``secant_floor``, on the secant dz/|de| down to increments of that size, which gives the first,
elastic increments from a state their weight. Rows where a closed cell opens (forces cut to zero
within the increment: not of the learned form) are left out of the force targets.

The way back (:meth:`MesoFormulation.advance`) enforces what holds for every such cell: lengths
from the strain, d1 and d2 from alpha and the lengths (eq. 1.2), N1, N2 >= 0 and zero where the
geometry has the grains clearly apart (d > 2r (1 + ``gap_tol``)), |T1| <= tan(phi_g) N1
(eq. 1.3), Vs_nn, Vs_tt >= 0 (compressive contact forces). A cell with free grains (the
hexagon-center cell) also gets a loose-cage gate: where the hexagon's clearance at its centre,
min(l1/2 - r, |(d2/2, l2/2)| - r), exceeds the reach of its free grains (the sum of their radii)
by more than ``gap_tol``, they can rest without force and V sigma is the hexagon's own, eq. 1.12
of the advanced fields; the learned inner part V sigma - eq. 1.12 fades out linearly over the
last ``cage_ramp`` of the reach before that. Why each of these choices was made, and what was
tried and measured worse, is in the notes of the documentation (2026-11-26, the hexagon-center
ANN-REV).

In the cell solver, a meso network sees the state only: one evaluation per increment gives the
learned response (:meth:`MesoFormulation.responses`; an ensemble's mean) that every trial
increment from that state applies in the compiled way back
(:func:`hmodel.cell.meso_kernel.meso_increment`), in the REV's compiled loading path
(:meth:`MesoFormulation.kernel_params`) and in :meth:`MesoFormulation.step_cells` alike. There
is no closed form to fall back to: cells outside the training domain stop the run or are
extrapolated, counted either way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from ...cell.base import STATE_H_CELL
from ...cell.meso_kernel import advance_cells, pack_outputs, pack_responses
from ...cell.meso_kernel import kernel_params as meso_kernel_params
from ...cell.mesostress import contact_vsigma
from ...cell.state import CellState
from ...errors import InputError
from ...params import Params
from .base import OUTPUTS, Formulation, Increment, Networks, material_features
from .meso_head import MesoHead, array_ops, like, positive, stack
from .meso_rollout import MesoRollout, MesoTraining, RolloutLoss, jumps, secant_weights
from .meso_summary import COLUMN, MESO_FIELDS, STATE_FIELDS, MesoSummary

__all__ = ["MESO_FIELDS", "STATE_FIELDS", "MesoFormulation", "MesoTraining"]


@dataclass(frozen=True)
class MesoFormulation(MesoSummary, MesoHead, MesoRollout, Formulation):
    """Summary state, inputs, targets and decoding for cells of the solver ``cell``."""

    params: Params  #: the material the data was made with
    cell: str = "closed-form"  #: the data's cell solver (``dem:hexagon-center``, ...)
    mechanisms: int = 4  #: kinks of the incremental response (:mod:`.meso_head`)
    #: Largest cell strain of one network step (None: any, one step per increment). A network
    #: trained with rollouts in sub-steps (``rollout_substeps``) of this size is stepped so in
    #: the REV, whatever the REV increment: the cells' strain paths are then cut alike at every
    #: increment, and a learned response no longer depends on it (see the DEM cells page: rate
    #: independence).
    cell_step: float | None = None
    #: A family's material inputs (``("kt_kn", "tan_phi_g", "alpha0")``), after the summary
    #: state's; () for one material.
    material_inputs: tuple[str, ...] = ()
    name: str = "meso"
    #: One network call for the cells of several materials (:meth:`step_cells_sets`).
    steps_sets = True
    #: A narrower student learns its head's increments (:mod:`hmodel.surrogate.distill`).
    distils = True
    #: float32 inference: checked against float64 on every compared DEM-REV path.
    single_precision = True
    #: Two columns after one network's outputs, where :meth:`responses` puts cos and sin of alpha.
    spare_columns = 2
    #: Members' increments average (see :mod:`hmodel.surrogate.solver`).
    ensembles = True
    state_only = True
    #: A summary state has no exact solver to hand a cell to.
    falls_back = False
    #: Relative gap beyond which a hexagon contact is open whatever the network says: well above
    #: the overlaps (~1e-4 of 2r at 100 kPa), so that a small error of the learned alpha, which
    #: eq. 1.2 turns into d1, never opens a contact.
    gap_tol = 1e-3
    #: Width (relative to the free grains' reach) over which a cage's inner part fades out.
    cage_ramp = 1e-3

    @property
    def outputs(self) -> tuple[str, ...]:
        return OUTPUTS + ("Vs_nn_next", "Vs_tt_next")

    def __post_init__(self) -> None:
        cell = self.cell_solver
        # the summary reads an H-cell's eight fields, then a DEM geometry's extra ones
        if cell.learned or cell.n_lengths != 2 or not (cell.state_kind == STATE_H_CELL or cell.geometry is not None):
            raise InputError(f"the meso formulation needs H-cell or DEM data, got cells of {self.cell!r}")
        if self.cell_step is not None and not (math.isfinite(self.cell_step) and self.cell_step > 0):
            raise InputError(f"cell_step must be a positive strain, got {self.cell_step}")

    def to_dict(self) -> dict:
        d = {"name": self.name, "params": self.params.to_dict(), "cell": self.cell,
             "mechanisms": self.mechanisms, "cell_step": self.cell_step}
        if self.material_inputs:
            d["material_inputs"] = list(self.material_inputs)
        return d

    # -- a family network (material inputs) -------------------------------------------------
    def for_material(self, params: Params | None) -> MesoFormulation:
        """This formulation for the material ``params`` (a family network's run): the Coulomb
        bound, the force unit and the cell's geometry (its free grain's radius at α0) are the
        run's; the same formulation for one material or ``params`` None."""
        if not self.material_inputs or params is None or params == self.params:
            return self
        known = self._materials  # a REV asks at every increment: its cage and scales once
        if params not in known:
            known[params] = replace(self, params=params)
        return known[params]

    @cached_property
    def _materials(self) -> dict:
        """The formulations :meth:`for_material` made, by material."""
        return {}

    @cached_property
    def _kernels(self) -> dict:
        """The compiled way back's parameters of :meth:`_kernel_params`, by material."""
        return {}

    def _kernel_params(self, params: Params) -> np.ndarray:
        """The compiled way back's parameters for the material ``params``, made once per material
        (a many-set REV asks for every set at every sub-step)."""
        known = self._kernels
        if params not in known:
            known[params] = meso_kernel_params(self.for_material(params), params)
        return known[params]

    def _row_materials(self, c: dict[str, np.ndarray]) -> list[tuple[np.ndarray, MesoFormulation]]:
        """The rows of each material of database rows ``c`` (a family's data: kt/kn, φg per
        path, α0 per path or REV) and the formulation for it; one group without material columns."""
        if not self.material_inputs or "kt_kn" not in c:
            return [(np.arange(len(c["deps1"])), self)]
        keys = np.column_stack([c["kt_kn"], c["phi_g"], c["alpha0"]])
        uniq, inverse = np.unique(keys, axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        return [(np.flatnonzero(inverse == j),
                 self.for_material(self.params.with_(kt_kn=float(k), phi_g=float(f), alpha0=float(a))))
                for j, (k, f, a) in enumerate(uniq)]

    def augment(self, c: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Database columns plus the meso-stress before and after, each material's rows with
        its own cell geometry (a family's data)."""
        groups = self._row_materials(c)
        if len(groups) == 1 or "Vs_nn" in c:
            return MesoSummary.augment(groups[0][1], c)
        parts = [(rows, MesoSummary.augment(f, {k: v[rows] for k, v in c.items()})) for rows, f in groups]
        out = dict(c)
        for k in parts[0][1]:
            if k not in c:
                col = np.empty(len(c["deps1"]))
                for rows, part in parts:
                    col[rows] = part[k]
                out[k] = col
        return out

    def features(self, v: np.ndarray, params: Params | None = None, material=None) -> np.ndarray:
        """Network inputs of summary states v (n, 11) of the material ``params`` (None: the
        trained one): the summary's (:meth:`MesoHead.features`), then a family's material inputs,
        or each row's own ``material`` inputs (n, k) where given (a family's rollout windows;
        NumPy or torch alike)."""
        f = self.for_material(params)
        X = MesoHead.features(f, v)
        if not self.material_inputs:
            return X
        if material is None:
            material = material_features(self.material_inputs, f.params, n=len(X))
        return stack([*X.T, *material.T])

    def initial(self, params: Params, shape: tuple[int, ...] = ()) -> CellState:
        """Summary of unloaded cells: of the trained opening angle, a family's of the run's."""
        return MesoSummary.initial(self.for_material(params), params, shape)

    def fits(self, cell: str) -> bool:
        """Whether rows of cells of the solver ``cell`` are this formulation's: its own cells'."""
        return cell == self.cell

    # -- training -------------------------------------------------------------------------
    def inputs(self, c: dict[str, np.ndarray]) -> np.ndarray:
        c = self.augment(c)
        X = MesoHead.features(self, np.column_stack([c[k] for k in STATE_FIELDS]))
        if not self.material_inputs:
            return X
        return np.hstack([X, material_features(self.material_inputs, columns=c)])

    def targets(self, c: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """dz/m0 (n, len(learned)) and weights: 0 for the contact forces N1, N2, T1 on the rows
        where a closed hexagon contact opens. There they are cut to zero within the increment,
        which is not of the learned form (the kink does not pass through de = 0); the geometric
        gate of :meth:`advance` opens them instead. alpha and V sigma are fitted on every row."""
        c = self.augment(c)
        before = self._learned_values(np.column_stack([c[k] for k in STATE_FIELDS]))
        after = self._learned_values(np.column_stack([c[f"{k}_next"] for k in STATE_FIELDS]))
        Y = (after - before) / self._scales() / self.m0
        was_open = (c["N1"] <= 0) | (c["N2"] <= 0)
        opens = (np.asarray(c["open1"], bool) | np.asarray(c["open2"], bool)) & ~was_open
        W = np.ones_like(Y)
        W[opens, 1:4] = 0.0
        return Y, W

    def row_weights(self, Y: np.ndarray, W: np.ndarray, aux: np.ndarray | None, config: MesoTraining) -> np.ndarray:
        """``W``, each row's error weighed as one of the secant dz/|de| with ``secant_floor``,
        and 0 on the rows that :func:`~.meso_rollout.jumps` past ``max_secant``."""
        floor = config.strain_floor(self.m0)
        if config.max_secant:
            W = W * ~jumps(Y, aux, config.max_secant, floor)[:, None]
        if not config.secant_floor:
            return W
        return W * secant_weights(aux, floor)[:, None]

    def rollout_loss(self, columns, config: MesoTraining, rng, x_scaler, net) -> RolloutLoss | None:
        """The rollout error along the data's paths of a training with ``rollout`` steps."""
        if not config.rollout:
            return None
        return RolloutLoss(self, columns, config, rng, x_scaler, net, config.rollout, config.rollout_substeps,
                           config.rollout_weight, config.max_secant, config.strain_floor(self.m0))

    def decode(self, c: dict[str, np.ndarray], out: np.ndarray) -> dict[str, np.ndarray]:
        """Predicted summary after the increment (``*_next`` columns) from network outputs."""
        return self._decoded(c, lambda c: self.increment(out, c["deps1"], c["deps2"]))

    def ensemble_decode(self, c: dict[str, np.ndarray], outs: list[np.ndarray]) -> dict[str, np.ndarray]:
        """:meth:`decode` of an ensemble, as the solver makes it: the members' increments averaged."""
        return self._decoded(c, lambda c: np.mean([self.increment(o, c["deps1"], c["deps2"]) for o in outs], axis=0))

    def _decoded(self, c: dict[str, np.ndarray], increment) -> dict[str, np.ndarray]:
        """The ``*_next`` columns of rows ``c`` after the increment ``increment(c)`` = dz/m0."""
        c = self.augment(c)
        v = np.column_stack([c[k] for k in STATE_FIELDS])
        dl = np.column_stack([c["l1_next"] - c["l1"], c["l2_next"] - c["l2"]])
        Y = increment(c)
        new = np.empty_like(v)
        for rows, f in self._row_materials(c):  # each material's bound and cage
            new[rows] = f.advance(v[rows], Y[rows], dl[rows])[0]
        return {f"{k}_next": new[:, COLUMN[k]] for k in ("alpha", "N1", "N2", "T1") + MESO_FIELDS}

    # -- the way back ---------------------------------------------------------------------
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

    def _advanced(self, v, Y, dl, material: dict | None = None) -> list:
        """The columns of :meth:`advance` (V sigma only for richer cells), for NumPy arrays or
        torch tensors alike: the same way back in the REV and in rollout training. A family's
        rollout windows give each row's Coulomb bound and cage in ``material`` (``tan_phi``
        (n,), ``cage`` (n, 3)); else the formulation's material's."""
        where, minimum, maximum, sin, cos = array_ops(v)
        tan_phi = self.tan_phi if material is None else material["tan_phi"]
        cage = material["cage"] if material is not None else None
        reach, r_n, r_t = self._cage if cage is None else (cage[:, 0], cage[:, 1], cage[:, 2])
        u = self._learned_values(v) + Y * like(self._scales() * self.m0, Y)
        a = u[:, 0]
        l1, l2 = v[:, 6] + dl[:, 0], v[:, 7] + dl[:, 1]
        d1 = l2 / (2.0 * sin(a))  # eq. 1.2
        d2 = l1 - 2.0 * d1 * cos(a)
        apart = 2.0 * self.radius * (1.0 + self.gap_tol)
        n1 = where(d1 < apart, positive(u[:, 1]), 0.0 * u[:, 1])
        n2 = where(d2 < apart, positive(u[:, 2]), 0.0 * u[:, 2])
        t1 = minimum(maximum(u[:, 3], -tan_phi * n1), tan_phi * n1)  # eq. 1.3
        cols = [d1, d2, a, n1, n2, t1, l1, l2]
        if not self.richer:
            return cols
        vs = [positive(u[:, 4]), positive(u[:, 5])]
        if self._cage[0]:  # a cell with free grains (a family's: every material's, each its reach)
            # a loose cage: the inner grains carry nothing, V sigma is the hexagon's
            clearance = minimum(l1 / 2 - r_n, ((d2 / 2) ** 2 + (l2 / 2) ** 2) ** 0.5 - r_t)
            # weight of the learned inner part: 1 while the cage holds the grain, 0 once it is
            # loose by gap_tol, linear between (V sigma stays continuous in the strain)
            w = (reach * (1.0 + self.gap_tol) - clearance) / (reach * self.cage_ramp)
            w = minimum(maximum(w, 0.0 * w), 0.0 * w + 1.0)
            hexagon = contact_vsigma.py_func(d1, d2, cos(a), sin(a), n1, n2, t1)  # eq. 1.12
            vs = [h + w * (x - h) for h, x in zip(hexagon, vs)]
        return cols + vs

    # -- the cell solver's side ----------------------------------------------------------
    def max_increment(self, input_range: np.ndarray | None) -> float:
        """:attr:`cell_step`; without it any (the response is homogeneous in the increment)."""
        return math.inf if self.cell_step is None else self.cell_step

    def kernel_params(self, params: Params) -> np.ndarray | None:
        """The compiled increment's parameters: the learned responses of the states (one network
        evaluation per increment, :meth:`responses`), which every Newton trial applies in
        :func:`hmodel.cell.meso_kernel.meso_increment`. None with a :attr:`cell_step`: each
        sub-step needs the network at its own state, and the generic path takes them
        (:meth:`hmodel.surrogate.solver.SurrogateSolver.step`)."""
        if self.cell_step is not None:
            return None
        return meso_kernel_params(self.for_material(params), params)

    def step_cells(self, net: Networks, params: Params, v, e1, e2, dl) -> Increment:
        """One learned increment of summary states v (n, 11), in the compiled way back (the
        NumPy one, :meth:`advance`, in one pass; tested against it)."""
        outs, mask = net.outputs(v, params=params) if self.material_inputs else net.outputs(v)
        new, flags, _ = advance_cells(v, np.ascontiguousarray(dl, float),
                                      meso_kernel_params(self.for_material(params), params),
                                      self.responses(v, outs, mask))
        return Increment(new, flags, mask, self.describe(v), outs)

    def step_cells_sets(self, net: Networks, sets, row_set: np.ndarray, v, e1, e2, dl) -> Increment:
        """:meth:`step_cells` of cells of several materials (cell i of ``sets[row_set[i]]``, a
        family network's): one network call for them all (each cell with its set's material
        inputs), then each set's compiled way back with its own Coulomb bound and cage."""
        present = np.unique(row_set)
        groups = [(sets[k], np.flatnonzero(row_set == k)) for k in present]
        # each set's force and length units and material inputs, spread over its rows
        per_set = np.zeros((len(sets), 2 + len(self.material_inputs)))
        for k in present:
            f = self.for_material(sets[k])
            per_set[k] = [f.force_scale, 2 * f.radius, *material_features(self.material_inputs, sets[k], n=1)[0]]
        table = per_set[row_set]
        X = np.hstack([MesoHead.features(self, v, table[:, 0], table[:, 1]), table[:, 2:]])
        key = (*(sets[k] for k in present), row_set.tobytes())
        outs, mask = net.outputs(v, X=X, key=key)
        new, flags = np.empty_like(v), np.empty((len(v), 5), bool)
        for p, rows in groups:
            new[rows], flags[rows], _ = advance_cells(
                v[rows], np.ascontiguousarray(dl[rows], float), self._kernel_params(p),
                self.responses(v[rows], [o[rows] for o in outs], mask[rows]))
        return Increment(new, flags, mask, self.describe(v), outs)

    def responses(self, v: np.ndarray, outs: list[np.ndarray], mask: np.ndarray) -> np.ndarray:
        """The learned responses (an ensemble's mean, :meth:`mean_response`) of summary states
        v (n, 11), which every trial increment from these states applies, as the compiled
        trial's rows (:func:`~hmodel.cell.meso_kernel.pack_responses`; one network's outputs are
        those rows already, followed by cos and sin of alpha in its two spare columns)."""
        width = self.n_outputs
        if len(outs) == 1:
            wide = outs[0] if outs[0].shape[1] == width + self.spare_columns else None
            return pack_outputs(outs[0][:, :width], len(self.learned), v, wide)
        return pack_responses(self.mean_response([self.response(o[:, :width]) for o in outs]), v)

    def describe(self, v: np.ndarray):
        """Names the network inputs of cell i of ``v``, for the out-of-domain error."""
        return lambda i: ", ".join(f"{k}={x:.4g}" for k, x in zip(self.input_names, MesoHead.features(self, v[i:i + 1])[0]))

    def member_afters(self, v, strain, dl, outs):
        """Every member's summary states after cell strains ``strain`` and length increments
        ``dl``, its response applied."""
        e = strain / self.m0
        return [self.advance(v, self.head(o[:, :self.n_outputs], e), dl)[0] for o in outs]
