"""Training an MLP surrogate with PyTorch (report §2.4): validation split, early stopping,
learning-rate schedule, fixed seeds; CPU by default, a GPU when one is there."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace

import numpy as np

from ..errors import InputError
from ..limits import check_memory
from ..params import Params
from .fit_loop import FitConfig, device, fit
from .formulations.meso_rollout import MesoTraining
from .formulations.registry import make_formulation
from .model import Architecture, Surrogate
from .scalers import Affine, fit_scaler
from .torch_support import require_torch

LOSSES = ("mse", "mae")


@dataclass(frozen=True)
class TrainConfig(FitConfig, MesoTraining):
    """A training's settings: the fit's (:class:`~hmodel.surrogate.fit_loop.FitConfig`; early
    stopping after ``patience`` epochs without improvement), the formulation and network, and
    the ``meso`` formulation's own
    (:class:`~hmodel.surrogate.formulations.meso_rollout.MesoTraining`: its mechanisms, cell
    step, rollouts and secant weighting; refused for another formulation)."""

    formulation: str = "increment"
    normalization: str = "zscore"
    width: int = 8
    depth: int = 3
    activation: str = "tanh"
    loss: str = "mse"

    def __post_init__(self) -> None:
        Architecture(self.width, self.depth, self.activation)
        if self.loss not in LOSSES:
            raise InputError(f"unknown loss {self.loss!r} (known: {', '.join(LOSSES)})")
        FitConfig.__post_init__(self)
        self.check(self.formulation)


def train(columns: dict[str, np.ndarray], params: Params, config: TrainConfig = TrainConfig(),
          progress: Callable[[float], None] | None = None, cell: str = "closed-form",
          init: Surrogate | None = None) -> tuple[Surrogate, list[dict]]:
    """Fit a surrogate on database rows ``columns`` of cells of the solver ``cell``; returns it
    and the per-epoch history.

    20 % (``val_fraction``) of the rows are held out for early stopping; scalers are fitted on
    the remaining training rows only. The best weights on the validation loss are kept.
    ``init``: fine-tune that model instead (its formulation, architecture, scalers and weights
    are the start; ``config``'s own are ignored), as active learning does; the rows must be of
    its material and cells.
    """
    torch = require_torch()

    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    if init is None:  # rows that draw a material per path make a family network
        form = make_formulation(config.formulation, params, cell, config.mechanisms, config.cell_step,
                                family="kt_kn" in columns)
    else:  # the caller checks that the rows are of the model's material and cells
        form = init.formulation
        config = replace(config, formulation=form.name, width=init.architecture.width,
                         depth=init.architecture.depth, activation=init.architecture.activation,
                         normalization=init.x_scaler.method)
    X, (Y, W), A = form.inputs(columns), form.targets(columns), form.aux(columns)
    W = form.row_weights(Y, W, A, config)
    n = len(X)
    if n < 10:
        raise InputError(f"need at least 10 training rows, got {n}")
    perm = rng.permutation(n)
    n_val = max(1, int(round(config.val_fraction * n)))
    val, tr = perm[:n_val], perm[n_val:]
    xs = fit_scaler(config.normalization, X[tr]) if init is None else init.x_scaler
    dev = device(config.device)
    to = lambda a: torch.as_tensor(a, dtype=torch.float32, device=dev)  # noqa: E731
    if A is None:
        ys = (fit_target_scaler(config.normalization, Y[tr], W[tr], form.logit_column)
              if init is None else init.y_scaler)
        Y, n_out = ys.transform(Y), Y.shape[1]
        At = Av = None
    else:  # structured head: the network's outputs are not the targets and pass unscaled
        n_out = form.n_outputs
        ys = Affine(config.normalization, np.zeros(n_out), np.ones(n_out))
        At, Av = to(A[tr]), to(A[val])
    Xt, Yt, Wt = to(xs.transform(X[tr])), to(Y[tr]), to(W[tr])
    Xv, Yv, Wv = to(xs.transform(X[val])), to(Y[val]), to(W[val])

    arch = Architecture(config.width, config.depth, config.activation)
    check_memory(training_bytes(arch, X.shape[1], n_out, config.batch_size),
                 f"a {config.depth} x {config.width} network")
    net = (build_network(arch, X.shape[1], n_out) if init is None else torch_network(init)).to(dev)
    loss_fn = _loss(config.loss, form.logit_column)
    roll = form.rollout_loss(columns, config, rng, xs, net)  # the meso formulation's rollouts
    n_batches = math.ceil(len(Xt) / config.batch_size)
    gen = torch.Generator(device="cpu").manual_seed(config.seed)

    def batches():
        order = torch.randperm(len(Xt), generator=gen).to(dev)
        for i in range(0, len(Xt), config.batch_size):
            idx = order[i:i + config.batch_size]
            loss = loss_fn(form.head(net(Xt[idx]), None if At is None else At[idx], Yt[idx]), Yt[idx], Wt[idx])
            if roll is not None:
                loss = loss + roll.train_batch(i // config.batch_size, n_batches)
            yield loss, len(idx)

    def validation() -> float:
        v = float(loss_fn(form.head(net(Xv), Av, Yv), Yv, Wv))
        return v + roll.validation() if roll is not None else v

    best_state, best, history = fit(net, batches, validation, len(Xt), config, progress=progress,
                                    plateau_patience=max(1, config.patience // 3),
                                    stop_patience=config.patience)
    weights = best_weights(net, best_state)
    meta = {"config": asdict(config), "epochs_run": len(history), "best_val_loss": best,
            "train_rows": int(len(tr)), "val_rows": int(len(val)),
            "seconds": history[-1]["seconds"] if history else 0.0, "device": str(dev)}
    domain = np.stack([X[tr].min(axis=0), X[tr].max(axis=0)])
    return Surrogate(form, arch, xs, ys, weights, meta, domain), history


def train_on_sample(folder, config: TrainConfig, progress: Callable[[float], None] | None = None,
                    init: Surrogate | None = None) -> tuple[Surrogate, list[dict]]:
    """Train on a sample folder's train rows (or the union of several folders': a list), evaluate
    on its (their) test rows, and record the data's provenance, the material and the test
    metrics in the model's metadata. Several folders must share the material and the cells.
    ``init``: fine-tune that model (see :func:`train`); its material and cells must be the rows'."""
    from .evaluation import evaluate
    from .training_rows import params_of, read_sample

    require_torch()  # before reading the data
    folders = list(folder) if isinstance(folder, (list, tuple)) else [folder]
    parts = [(read_sample(f, "train"), read_sample(f, "test")[0]) for f in folders]
    (cols, info), test = parts[0]
    cell = info["provenance"]["options"].get("solver", "closed-form")
    for (_, other), _ in parts[1:]:
        if other["params"] != info["params"] or other["provenance"]["options"].get("solver", "closed-form") != cell:
            raise InputError("samples to train on together must share the material parameters and the cell solver")
    if len(parts) > 1:
        cols = union([p[0][0] for p in parts])
        test = union([p[1] for p in parts])
    if init is not None and (init.meta.get("params", info["params"]) != info["params"]
                             or not init.formulation.fits(cell)):
        raise InputError("the model to fine-tune was trained on other material parameters or cells "
                         "than these samples'")
    s, history = train(cols, params_of(info), config, progress, cell, init=init)
    prov = info["provenance"] if len(parts) == 1 else [p[0][1]["provenance"] for p in parts]
    s.meta.update(training_data=prov, params=info["params"],
                  metrics=evaluate(s, test, "sample test rows"), history_tail=history[-3:])
    if s.formulation.material_inputs:
        s.meta["domain"] = training_domain([p[0][1]["provenance"]["options"] for p in parts])
    return s, history


def training_domain(options: list[dict]) -> dict[str, list[float]]:
    """A family network's training domain from the options of its datasets
    (:class:`~hmodel.data.generator.DatasetSpec` as dicts): the ranges of kt/kn, φg and α0
    [deg] every dataset covers (their intersection)."""
    from ..data import DatasetSpec

    domain: dict[str, list[float]] = {}
    for o in options:
        spec = DatasetSpec.from_dict(o)
        ranges = {**spec.material_ranges, "alpha0": (spec.alpha0_min, spec.alpha0_max)}
        for k, (lo, hi) in ranges.items():
            old = domain.get(k, [lo, hi])
            domain[k] = [max(old[0], lo), min(old[1], hi)]
    bad = [k for k, (lo, hi) in domain.items() if lo > hi]
    if bad:
        raise InputError(f"the samples' material ranges do not overlap in {', '.join(bad)}")
    return domain


def training_bytes(arch: Architecture, n_in: int, n_out: int, batch_size: int) -> float:
    """Memory a training of ``arch`` holds [bytes], float32: the weights four times (the weights,
    their gradients, Adam's two moments) and a batch's activations, kept for the backward pass."""
    w = float(arch.width)
    n_params = (n_in + 1) * w + (arch.depth - 1) * (w + 1) * w + (w + 1) * n_out
    return 4.0 * (4 * n_params + 2 * batch_size * w * arch.depth)


def union(parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """The rows of several samples as one; path ids count from 0 in every dataset, so each
    sample's are shifted past the previous ones' (a path stays one path, for rollout windows).
    Columns that not every part has (a sample's source ``row``) are left out."""
    shift, out = 0, {k: [] for k in parts[0] if all(k in p for p in parts)}
    for cols in parts:
        for k in out:
            out[k].append(cols[k] + shift if k == "path_id" else cols[k])
        if "path_id" in cols and len(cols["path_id"]):
            shift += int(cols["path_id"].max()) + 1
    return {k: np.concatenate(v) for k, v in out.items()}


def _loss(kind: str, logit: int | None):
    """Weighted mean regression loss (MSE or MAE) over the regression outputs, plus binary
    cross-entropy on the logit output when the formulation has one."""
    torch = require_torch()

    def loss(pred, y, w):
        reg = slice(None, logit)
        err = pred[:, reg] - y[:, reg]
        e = err * err if kind == "mse" else err.abs()
        out = (e * w[:, reg]).sum() / w[:, reg].sum().clamp(min=1.0)
        if logit is not None:
            out = out + torch.nn.functional.binary_cross_entropy_with_logits(pred[:, logit], y[:, logit])
        return out
    return loss


def fit_target_scaler(method: str, Y: np.ndarray, W: np.ndarray, logit: int | None):
    """Scaler of the targets, each fitted on the rows where it is regressed; a logit stays as is."""

    offset, scale = np.zeros(Y.shape[1]), np.ones(Y.shape[1])
    for j in range(Y.shape[1]):
        if j == logit:
            continue
        rows = W[:, j] > 0
        a = fit_scaler(method, Y[rows, j:j + 1] if rows.any() else Y[:, j:j + 1])
        offset[j], scale[j] = a.offset[0], a.scale[0]
    return Affine(method, offset, scale)


def best_weights(net, state: dict) -> list[tuple[np.ndarray, np.ndarray]]:
    """(W, b) per linear layer in float64 of ``net`` with the kept (best) ``state`` loaded."""
    torch = require_torch()
    net.load_state_dict(state)
    return [(m.weight.detach().cpu().double().numpy(), m.bias.detach().cpu().double().numpy())
            for m in net if isinstance(m, torch.nn.Linear)]


def torch_network(model: Surrogate):
    """The torch MLP of a trained surrogate, its weights loaded (float32, as trained)."""
    torch = require_torch()
    net = build_network(model.architecture, len(model.x_scaler.offset), len(model.weights[-1][1]))
    with torch.no_grad():
        for layer, (W, b) in zip([m for m in net if isinstance(m, torch.nn.Linear)], model.weights):
            layer.weight.copy_(torch.as_tensor(W))
            layer.bias.copy_(torch.as_tensor(b))
    return net


def build_network(arch: Architecture, n_in: int, n_out: int):
    """The torch MLP of an architecture (Linear layers with activations in between)."""
    torch = require_torch()

    act = {"tanh": torch.nn.Tanh, "relu": torch.nn.ReLU, "silu": torch.nn.SiLU,
           "gelu": torch.nn.GELU, "elu": torch.nn.ELU}[arch.activation]
    layers, width = [], n_in
    for _ in range(arch.depth):
        layers += [torch.nn.Linear(width, arch.width), act()]
        width = arch.width
    layers.append(torch.nn.Linear(width, n_out))
    return torch.nn.Sequential(*layers)
