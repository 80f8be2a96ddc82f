"""The ``meso`` formulation's rollout training (the torch side) and its training options.

Single-increment errors pile up along a path, and a REV feeds each cell its own previous
output. :meth:`MesoRollout.windows` cuts the data's paths (consecutive start states of a
Dataset 2) into windows of a few steps, and :meth:`MesoRollout.rollout_error` steps the network
along them through the same way back as the REV (NumPy and torch alike), adding that error to
the loss (:class:`RolloutLoss`). :class:`MesoTraining` holds the options of a training that only
the ``meso`` formulation reads: its mechanisms, its largest network step, its rollouts and the
secant weighting of its loss (:func:`secant_weights`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...cell.state import initial_lengths
from ...errors import InputError
from ..torch_support import require_torch
from .base import material_features
from .meso_head import like, stack
from .meso_summary import STATE_FIELDS

#: A family's per-window material (:meth:`MesoRollout._window_materials`).
MATERIAL_KEYS = ("tan_phi", "cage", "material")
#: The options of :class:`MesoTraining` that shape the loss (a fine-tuning keeps them).
LOSS_OPTIONS = ("secant_floor", "max_secant", "rollout", "rollout_weight", "rollout_substeps")


@dataclass(frozen=True)
class MesoTraining:
    """The ``meso`` formulation's training options (:class:`hmodel.surrogate.training.TrainConfig`
    has them too); refused for another formulation by :meth:`check`."""

    #: Kinks of the incremental response (:mod:`hmodel.surrogate.formulations.meso_head`).
    mechanisms: int = 4
    #: Rollout training (a richer cell): windows of this many steps along the data's paths,
    #: each step fed the previous step's prediction, add ``rollout_weight`` times their error to
    #: the loss (0: single increments only). A learned state drifts in a REV where
    #: single-increment errors pile up; this charges the network for the pile-up.
    rollout: int = 0
    rollout_weight: float = 1.0
    #: Network steps per data step of a rollout window (a REV at a finer increment than the
    #: data's; 1: the data's steps): with ``cell_step``, the network learns steps of the size a
    #: REV will take (the shipped hexagon-center networks use 4).
    rollout_substeps: int = 1
    #: Weigh each row's error as an error of the secant dz/|de| instead of dz/m0, for
    #: increments down to this strain (smaller ones weigh as this): the loss on dz/m0 leaves the
    #: first increments of a loading to the large ones, whose sliding dominates it (0: off).
    secant_floor: float = 0.0
    #: Leave out of the loss the rows, and cut the rollout windows at the steps, whose secant
    #: |dz| / |de| of any learned field (over the field's unit, as :func:`jumps` takes it) is
    #: above this: jumps, not responses of the learned form (0: keep every row). The unloaded
    #: hexagon-center cell is a mechanism (no force fixes its alpha) and DEM snaps it to the
    #: next equilibrium in one increment; 0.09 % of a family's rows held 96 % of its loss
    #: (docs: DEM cells, the note of 2026-12-03).
    max_secant: float = 0.0
    #: Largest cell strain of one network step in a REV (None: any), stored with the model
    #: (:attr:`hmodel.surrogate.formulations.meso.MesoFormulation.cell_step`).
    cell_step: float | None = None

    def __post_init__(self) -> None:
        self.check()

    def strain_floor(self, m0: float) -> float:
        """The smallest increment |de|/m0 a secant is taken over: ``secant_floor``, or m0 without
        one (the secant weights' floor and the jumps' alike)."""
        return (self.secant_floor or m0) / m0

    def check(self, formulation: str = "meso") -> None:
        """Refuse options out of range, or set for a ``formulation`` other than ``meso``."""
        if self.rollout_substeps < 1:
            raise InputError(f"rollout_substeps must be at least 1, got {self.rollout_substeps}")
        if self.mechanisms < 0 or self.rollout < 0 or not self.rollout_weight >= 0:
            raise InputError("mechanisms, rollout and rollout_weight must be positive or zero")
        if self.rollout and formulation != "meso":
            raise InputError("rollout training needs --formulation meso")
        if not self.max_secant >= 0:
            raise InputError(f"max_secant must be positive or zero, got {self.max_secant}")
        if self.max_secant and formulation != "meso":
            raise InputError("--max-secant needs --formulation meso")
        if not self.secant_floor >= 0:
            raise InputError(f"secant_floor must be positive or zero, got {self.secant_floor}")
        if self.secant_floor and formulation != "meso":
            raise InputError("secant weighting needs --formulation meso")
        if self.cell_step is not None and formulation != "meso":
            raise InputError("--cell-step needs --formulation meso")


class MesoRollout:
    """The ``meso`` formulation's rollouts along the data's paths (torch for the network)."""

    material_inputs: tuple[str, ...]

    def windows(self, c: dict[str, np.ndarray], length: int, max_secant: float = 0.0,
                floor: float = 0.0) -> dict[str, np.ndarray]:
        """Stretches of ``length`` steps along the data's paths, for rollout training.

        The start states of a Dataset 2 (3) lie along paths (``path_id``: a proportional path
        of one cell, or a REV's cell along its loading), every ``start_every`` of strain:
        consecutive ones are the path's own steps, whose cell strain their lengths give. From
        every start state, a window holds the next ``length`` steps (fewer near a path's end,
        padded with zero steps of mask 0): summary states ``z0`` (W, 11), e = de/m0
        ``e`` (W, T, 2), length increments ``dl`` (W, T, 2), the learned fields after each step
        ``target`` (W, T, len(learned)) and ``mask`` (W, T). With ``max_secant``, a window ends
        before its first step that :func:`jumps` (strains taken as at least ``floor``)."""
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
            e = -(dl / l0) / self.m0  # cell strain on the initial lengths
            if max_secant:  # a jump ends it: the states after it are not the learned form's
                ok &= ~jumps((learned[nxt] - learned[prev]) / (self._scales() * self.m0), e, max_secant, floor)
            out["e"][ok, k] = e[ok]
            out["dl"][ok, k] = dl[ok]
            out["target"][ok, k] = learned[nxt][ok]
            out["mask"][ok, k] = 1.0
        out.update(self._window_materials(c, first))
        keep = out["mask"][:, 0] > 0
        return {k: a[keep] for k, a in out.items()}

    def _window_materials(self, c: dict[str, np.ndarray], first: np.ndarray) -> dict[str, np.ndarray]:
        """A family's windows (rows ``first`` of ``c`` start them): each window's material as
        the way back and the network read it, ``tan_phi`` (W,), ``cage`` (W, 3) and the material
        inputs ``material`` (W, n); {} for one material (the formulation's own are used)."""
        if not self.material_inputs or "kt_kn" not in c:
            return {}
        rows = {k: c[k][first] for k in ("kt_kn", "phi_g", "alpha0")}
        out = {"tan_phi": np.empty(len(first)), "cage": np.empty((len(first), 3)),
               "material": material_features(self.material_inputs, columns=rows)}
        for idx, f in self._row_materials(rows):
            out["tan_phi"][idx] = f.tan_phi
            out["cage"][idx] = f._cage
        return out

    def rollout(self, net, z0, e, dl, scale_inputs, substeps: int = 1, material: dict | None = None):
        """The learned fields (W, T, len(learned)) after each step of windows rolled out with the
        network ``net`` (torch, float64 states): each step's state is the previous step's
        output, as in a REV; each data step taken in ``substeps`` equal network steps (a REV at
        a finer increment than the data's, :attr:`MesoTraining.rollout_substeps`). A family's
        windows bring their ``material`` (:meth:`_window_materials`, as tensors): each window
        is stepped with its own inputs, Coulomb bound and cage, as the REV steps each material."""
        torch = require_torch()
        z = z0
        fields = []
        for k in range(e.shape[1]):
            for _ in range(substeps):
                X = self.features(z, material=None if material is None else material["material"])
                out = net(scale_inputs(X).float()).double()
                cols = self._advanced(z, self.head(out, e[:, k] / substeps), dl[:, k] / substeps, material)
                z = stack(cols + [0.0 * cols[0]] * (len(STATE_FIELDS) - len(cols)))
            fields.append(self._learned_values(z))
        return torch.stack(fields, 1)

    def rollout_error(self, net, z0, e, dl, target, mask, scale_inputs, substeps: int = 1,
                      material: dict | None = None):
        """Mean squared error (in units of dz/m0) of the learned fields along windows rolled out
        with ``net`` (:meth:`rollout`) against ``target`` (W, T, len(learned)), steps weighed
        by ``mask`` (W, T)."""
        scales = like(self._scales() * self.m0, z0)
        err = (self.rollout(net, z0, e, dl, scale_inputs, substeps, material) - target) / scales
        return ((err * err).mean(2) * mask).sum() / mask.sum().clamp(min=1.0)


class RolloutLoss:
    """Windows along the data's paths (:meth:`MesoRollout.windows`, cut before steps that jump
    past ``max_secant``), split like the rows, and their rollout errors times ``weight`` for a fit
    loop (:mod:`hmodel.surrogate.fit_loop`): ``train_batch(b, n_batches)`` and ``validation()``
    are added to the loss."""

    def __init__(self, form, columns, config, rng, xs, net, window: int, substeps: int = 1,
                 weight: float = 1.0, max_secant: float = 0.0, floor: float = 1.0):
        torch = require_torch()
        if not form.richer:
            raise InputError("rollout training needs the meso formulation of a richer cell (DEM data "
                             "whose V sigma is learned)")
        w = form.windows(columns, window, max_secant, floor)
        if len(w["z0"]) < 2:
            raise InputError("rollout training needs data along paths (a Dataset 2 sample with its "
                             "start states)")
        perm = rng.permutation(len(w["z0"]))
        n_val = max(1, int(round(config.val_fraction * len(perm))))
        dev = next(net.parameters()).device
        as64 = lambda a: torch.as_tensor(a, dtype=torch.float64, device=dev)
        self.val = {k: as64(a[perm[:n_val]]) for k, a in w.items()}
        self.train = {k: as64(a[perm[n_val:]]) for k, a in w.items()}
        off, scale = as64(xs.offset), as64(xs.scale)
        self.scale_inputs = lambda X: (X - off) / scale
        self.form, self.net, self.substeps, self.weight = form, net, substeps, weight
        self.gen = torch.Generator().manual_seed(config.seed)
        self.order = torch.randperm(len(perm) - n_val, generator=self.gen)

    def _error(self, part: dict, idx=None):
        a = part if idx is None else {k: t[idx] for k, t in part.items()}
        material = {k: a[k] for k in MATERIAL_KEYS} if "material" in a else None
        return self.form.rollout_error(self.net, a["z0"], a["e"], a["dl"], a["target"], a["mask"],
                                       self.scale_inputs, self.substeps, material)

    def train_batch(self, b: int, n_batches: int):
        """Weighted rollout error of the b-th of ``n_batches`` slices of the training windows."""
        torch = require_torch()
        if b == 0:  # a new epoch: new slices
            self.order = torch.randperm(len(self.order), generator=self.gen)
        size = math.ceil(len(self.order) / n_batches)
        return self.weight * self._error(self.train, self.order[b * size:(b + 1) * size])

    def validation(self) -> float:
        torch = require_torch()
        with torch.no_grad():
            return self.weight * float(self._error(self.val))


def jumps(Y: np.ndarray, e: np.ndarray, max_secant: float, floor: float) -> np.ndarray:
    """Rows whose increments Y = dz/m0 (n, L), over strains e = de/m0 (n, 2) taken as at least
    ``floor``, have a secant |Y| / |e| above ``max_secant`` in any field: a jump of the cell
    (a snap to another equilibrium) within the increment, which no incrementally multi-linear
    response gives."""
    size = np.maximum(np.linalg.norm(e, axis=1), floor)
    return (np.abs(Y) > max_secant * size[:, None]).any(axis=1)


def secant_weights(e, floor: float):
    """Row weights (m0/|de|)^2 = 1/|e|^2 for strains e = de/m0 (n, 2), |e| taken as at least
    ``floor``: they turn a squared error of dz/m0 into one of the secant dz/|de| (times m0).
    NumPy or torch."""
    if isinstance(e, np.ndarray):
        return 1.0 / np.maximum(np.linalg.norm(e, axis=1), floor) ** 2
    return 1.0 / e.norm(dim=1).clamp(min=floor) ** 2
