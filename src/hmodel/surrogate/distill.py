"""Distilling a meso surrogate into a narrower network (a cheaper ANN-based H-model).

A REV evaluates its network once per increment for every cell of every material point, so the
network's width sets most of an ANN-REV's cost. A narrower network trained on the data alone
reached a lower validation loss than the recipe's wider one and was still less accurate along
REV paths (see the documentation's DEM cells page). Here the narrower network (the student)
learns the trained one (the teacher) instead: on the teacher's training states, and for each of
them its own strain and ``strains`` random ones (directions uniform, magnitudes drawn from the
data's), the student's increment dz/m0 = A e + sum_k <n_k . e - c_k^2> B_k is fitted to the
teacher's, each error weighed as one of the secant dz/|de| (the teacher's ``secant_floor``).
``raw_weight`` adds the squared difference of the raw outputs (each scaled by the teacher's
spread over the states), which holds the student to the teacher's mechanisms, not just to their
sum (a richer target than the increment alone, so the validation loss falls faster). For a
richer cell ``rollout_weight`` adds the difference of the two networks' rollouts of ``rollout``
steps from the data's path states: without it, a 64x3 student as good on single increments was
2.58 % of peak q off a DEM-REV path, with it 1.55 % (see the documentation's DEM cells page).
The student keeps the teacher's formulation, scalers and training domain; its metadata names the
teacher and the distillation's settings.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np

from ..errors import InputError
from ..limits import check_memory
from .fit_loop import FitConfig, device, fit
from .formulations.meso_rollout import RolloutLoss, secant_weights
from .model import Architecture, Surrogate
from .torch_support import require_torch
from .training import best_weights, build_network, torch_network, training_bytes


@dataclass(frozen=True)
class DistillConfig(FitConfig):
    """A distillation's settings: the fit's (:class:`~hmodel.surrogate.fit_loop.FitConfig`;
    the learning rate halved after ``patience`` epochs without improvement, the fit ended once
    it falls below ``min_lr``), the student's network and the loss's terms."""

    width: int = 64
    depth: int = 3
    #: the teacher's activation when None
    activation: str | None = None
    #: random strains per state, besides the state's own
    strains: int = 3
    raw_weight: float = 0.01
    #: richer cells: windows of this many steps along the data's paths, rolled out by the
    #: teacher and the student from the same states; ``rollout_weight`` times the squared
    #: difference of their learned fields joins the loss (0: single increments only)
    rollout: int = 4
    rollout_weight: float = 0.5
    epochs: int = 3000
    #: training ends once the learning rate falls below this
    min_lr: float = 1e-5
    val_fraction: float = 0.1
    device: str = "cpu"

    def __post_init__(self) -> None:
        if self.activation is not None:
            Architecture(self.width, self.depth, self.activation)
        for name in ("width", "depth"):
            if getattr(self, name) < 1:
                raise InputError(f"{name} must be at least 1, got {getattr(self, name)}")
        super().__post_init__()
        if self.strains < 0 or not self.raw_weight >= 0 or self.rollout < 0 or not self.rollout_weight >= 0:
            raise InputError("strains, raw_weight, rollout and rollout_weight must be positive or zero")
        if not self.min_lr > 0:
            raise InputError(f"min_lr must be positive, got {self.min_lr}")


def distill(teacher: Surrogate, columns: dict[str, np.ndarray], config: DistillConfig = DistillConfig(),
            progress: Callable[[float], None] | None = None) -> tuple[Surrogate, list[dict]]:
    """A ``config.width`` x ``config.depth`` student of the meso surrogate ``teacher``, on the
    states of database rows ``columns`` (the teacher's training rows); and its history."""
    torch = require_torch("distillation")

    form = teacher.formulation
    if not form.distils:
        raise InputError(f"distillation needs a meso-formulation teacher, got {form.name!r}")
    arch = Architecture(config.width, config.depth, config.activation or teacher.architecture.activation)
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    gen = torch.Generator().manual_seed(config.seed)
    X, E = form.inputs(columns), form.aux(columns)
    n = len(X)
    if n < 10:
        raise InputError(f"need at least 10 rows to distil on, got {n}")
    dev = device(config.device)
    as64 = lambda a: torch.as_tensor(a, dtype=torch.float64, device=dev)  # noqa: E731
    Z = torch.as_tensor(teacher.x_scaler.transform(X), dtype=torch.float32, device=dev)
    T = as64(teacher.forward(X))  # the teacher's outputs in float64
    spread = T.std(0).clamp(min=1e-12)
    magnitude = np.linalg.norm(E, axis=1)
    E = as64(E)
    floor = teacher.meta.get("config", {}).get("secant_floor") or 2.5e-4

    def strains(rows):
        """Each state's own strain, then ``strains`` random ones: (e, state row) pairs."""
        k = len(rows) * config.strains
        m = as64(magnitude[rng.integers(0, n, k)])
        a = torch.rand(k, generator=gen, dtype=torch.float64).to(dev) * (2 * math.pi)
        e = torch.cat([E[rows], torch.stack([m * torch.cos(a), m * torch.sin(a)], 1)])
        return e, torch.cat([rows] * (1 + config.strains))

    def loss(rows, e, at, raw: bool):
        out = net(Z[at]).double()
        d = form.head(out, e) - form.head(T[at], e)
        total = ((d * d).sum(1) * secant_weights(e, floor / form.m0)).mean()
        if raw and config.raw_weight:
            r = (out[:len(rows)] - T[rows]) / spread
            total = total + config.raw_weight * (r * r).mean()
        return total

    perm = torch.as_tensor(rng.permutation(n), device=dev)
    n_val = max(1, int(round(config.val_fraction * n)))
    val, tr = perm[:n_val], perm[n_val:]
    val_e, val_at = strains(val)
    check_memory(training_bytes(arch, X.shape[1], form.n_outputs, config.batch_size * (1 + config.strains)),
                 f"a {arch.depth} x {arch.width} student")
    net = build_network(arch, X.shape[1], form.n_outputs).to(dev)
    roll = (_TeacherRollouts(teacher, columns, config, rng, net)
            if config.rollout and config.rollout_weight and form.richer else None)
    n_batches = math.ceil(len(tr) / config.batch_size)

    def batches():
        order = tr[torch.randperm(len(tr), generator=gen).to(dev)]
        for i in range(0, len(order), config.batch_size):
            rows = order[i:i + config.batch_size]
            e, at = strains(rows)
            batch = loss(rows, e, at, raw=True)
            if roll is not None:
                batch = batch + roll.train_batch(i // config.batch_size, n_batches)
            yield batch, len(rows)

    def validation() -> float:  # increments and rollouts, not the raw outputs
        v = float(loss(val, val_e, val_at, raw=False))
        return v + roll.validation() if roll is not None else v

    best_state, best, history = fit(net, batches, validation, len(tr), config, progress=progress,
                                    plateau_patience=config.patience, min_lr=config.min_lr,
                                    what="distillation")
    weights = best_weights(net, best_state)
    meta = {k: v for k, v in teacher.meta.items() if k in ("params", "training_data")}
    meta.update(distilled={"teacher": {k: teacher.meta.get(k) for k in
                                       ("architecture", "config", "best_val_loss", "epochs_run")},
                           "config": asdict(config)},
                epochs_run=len(history), best_val_loss=best, seconds=history[-1]["seconds"],
                device=str(dev))
    return Surrogate(form, arch, teacher.x_scaler, teacher.y_scaler, weights, meta,
                     teacher.input_range), history


def distill_on_sample(teacher: Surrogate, folder, config: DistillConfig = DistillConfig(),
                      progress: Callable[[float], None] | None = None) -> tuple[Surrogate, list[dict]]:
    """:func:`distill` on a sample folder's train rows (or several folders' together: the
    teacher's training samples), with the test metrics of the folders' test rows in the
    student's metadata (as ``train_on_sample``)."""
    from .evaluation import evaluate
    from .training import union
    from .training_rows import read_sample

    require_torch("distillation")  # before reading the data
    folders = list(folder) if isinstance(folder, (list, tuple)) else [folder]
    train = union([read_sample(f, "train")[0] for f in folders])
    test = union([read_sample(f, "test")[0] for f in folders])
    s, history = distill(teacher, train, config, progress)
    s.meta.update(metrics=evaluate(s, test, "sample test rows"), history_tail=history[-3:])
    return s, history


class _TeacherRollouts(RolloutLoss):
    """Rollout windows of the data (as in training), with the teacher's own rollouts from the
    same start states as their targets: the student learns the teacher's paths, not the data's."""

    def __init__(self, teacher: Surrogate, columns, config: DistillConfig, rng, net):
        torch = require_torch("distillation")
        super().__init__(teacher.formulation, columns, config, rng, teacher.x_scaler, net, config.rollout,
                         weight=config.rollout_weight)
        t_net = torch_network(teacher)
        with torch.no_grad():
            for part in (self.train, self.val):
                part["target"] = self.form.rollout(t_net, part["z0"], part["e"], part["dl"], self.scale_inputs)
