"""The one loop that fits a network (training and distillation): Adam, the learning rate halved
on a validation plateau, the best weights on the validation loss kept, a budget in epochs.

What differs between a training and a distillation is the loss of a batch and of the
validation set, which the caller passes as functions, and when to stop early: after
``stop_patience`` epochs without improvement (training), or once the halved learning rate
falls below ``min_lr`` (distillation).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from ..errors import InputError
from .torch_support import require_torch


@dataclass(frozen=True)
class FitConfig:
    """The settings every fit shares; :class:`~hmodel.surrogate.training.TrainConfig` and
    :class:`~hmodel.surrogate.distill.DistillConfig` add their own.

    ``epochs`` is the budget: a recipe in epochs rebuilds the same network on any machine.
    ``max_minutes`` also ends a fit on wall time, for exploring only: a run it cuts short
    depends on how busy the machine was, and cannot be rebuilt.
    """

    epochs: int = 300
    batch_size: int = 1024
    lr: float = 3e-3
    patience: int = 30
    val_fraction: float = 0.2
    seed: int = 0
    device: str = "auto"
    max_minutes: float | None = None

    def __post_init__(self) -> None:
        for name in ("epochs", "batch_size", "patience"):
            if getattr(self, name) < 1:
                raise InputError(f"{name} must be at least 1, got {getattr(self, name)}")
        if not self.lr > 0:
            raise InputError(f"lr must be positive, got {self.lr}")
        if not 0 < self.val_fraction < 1:
            raise InputError(f"val_fraction must lie in (0, 1), got {self.val_fraction}")


def device(name: str):
    """The torch device of a name (``auto``: a GPU when there is one)."""
    torch = require_torch()
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    try:
        return torch.device(name)
    except RuntimeError:
        raise InputError(f"unknown device {name!r}") from None


def fit(net, batches: Callable[[], Iterable[tuple[object, int]]], validation: Callable[[], float],
        n_rows: int, config: FitConfig, *, plateau_patience: int, stop_patience: int | None = None,
        min_lr: float | None = None, what: str = "training",
        progress: Callable[[float], None] | None = None) -> tuple[dict, float, list[dict]]:
    """Fit ``net``; returns its best state (on the validation loss), that loss, and the history.

    ``batches()`` yields, for one epoch, each batch's loss (a tensor to minimize) and its number
    of rows; ``validation()`` is the validation loss (evaluated without gradients). The learning
    rate is halved after ``plateau_patience`` epochs without improvement.
    """
    torch = require_torch()
    opt = torch.optim.Adam(net.parameters(), lr=config.lr)
    sched = torch.optim.lr_scheduler.ReduceLROnPlateau(opt, factor=0.5, patience=plateau_patience)
    best, best_state, stale, history = math.inf, None, 0, []
    t0 = time.perf_counter()
    for epoch in range(config.epochs):
        net.train()
        total = 0.0
        for loss, n in batches():
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            total += float(loss.detach()) * n
        net.eval()
        with torch.no_grad():
            v = validation()
        sched.step(v)
        history.append({"epoch": epoch + 1, "train_loss": total / n_rows, "val_loss": v,
                        "lr": opt.param_groups[0]["lr"], "seconds": time.perf_counter() - t0})
        if v < best:
            best, stale = v, 0
            best_state = {k: t.detach().clone() for k, t in net.state_dict().items()}
        else:
            stale += 1
        if progress is not None:
            progress((epoch + 1) / config.epochs)
        if not math.isfinite(v):
            raise InputError(f"{what} diverged at epoch {epoch + 1} (validation loss {v}); lower --lr")
        if stop_patience is not None and stale >= stop_patience:
            break
        if min_lr is not None and opt.param_groups[0]["lr"] < min_lr:
            break
        if config.max_minutes is not None and time.perf_counter() - t0 > 60 * config.max_minutes:
            break
    return best_state, best, history
