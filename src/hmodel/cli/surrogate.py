"""``hmodel surrogate train | distill | evaluate | sweep``: neural surrogates of the H-cell (report §2.4-2.5)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Optional

import typer

from ..errors import InputError
from ..io import write_outputs, write_rows
from .progress import LazyProgress

app = typer.Typer(no_args_is_help=True, help="Train, evaluate and compare neural surrogates of the H-cell.")

Formulation = Annotated[str, typer.Option(help="compliance (learned compliances of eq. 1.7, exact contact law), "
                                               "report (the report's inputs/outputs), increment "
                                               "(dimensionless increments, Coulomb bound by construction) "
                                               "or meso (any cell, richer DEM cells too: summary state "
                                               "with the Love-Weber meso-stress).")]
Normalization = Annotated[str, typer.Option(help="minmax, zscore, robust, maxabs or unit.")]
Width = Annotated[int, typer.Option(help="Nodes per hidden layer.")]
Depth = Annotated[int, typer.Option(help="Hidden layers.")]
Activation = Annotated[str, typer.Option(help="tanh, relu, silu, gelu or elu.")]
Loss = Annotated[str, typer.Option(help="mse or mae.")]
Epochs = Annotated[int, typer.Option(help="Largest number of epochs (early stopping may end sooner).")]
BatchSize = Annotated[int, typer.Option(help="Rows per optimizer step.")]
Lr = Annotated[float, typer.Option(help="Initial learning rate (Adam; halved on plateaus).")]
Patience = Annotated[int, typer.Option(help="Epochs without validation improvement before stopping.")]
Seed = Annotated[int, typer.Option(help="Seed of the split, the initialization and the batches.")]
Device = Annotated[str, typer.Option(help="auto (a GPU when there is one), cpu or cuda.")]
MaxMinutes = Annotated[Optional[float], typer.Option(help="Stop training after this wall time.")]
Mechanisms = Annotated[int, typer.Option(help="meso: kinks of the learned incremental response.")]
Rollout = Annotated[int, typer.Option(help="meso of a richer cell: also train on rollouts of this many "
                                           "steps along the data's paths (0: single increments only).")]
RolloutWeight = Annotated[float, typer.Option(help="Weight of the rollout error in the loss.")]
RolloutSubsteps = Annotated[int, typer.Option(help="Experimental, tried and not kept (docs/notes): network "
                                                   "steps per data step of a rollout (a REV at a finer "
                                                   "increment than the data's).")]
SecantFloor = Annotated[float, typer.Option(help="meso: weigh errors as errors of the secant dz/|de|, "
                                                 "increments below this strain as this (0: of dz/m0).")]


def _config(**kw):
    from ..surrogate.training import TrainConfig
    return TrainConfig(**kw)


@app.command("train")
def train_cmd(
    data: Annotated[list[Path], typer.Argument(help="Sample folder(s) (hmodel data sample): trains on "
                                                    "train.parquet (of all of them together).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Model file to write (.safetensors).")],
    formulation: Formulation = "increment", normalization: Normalization = "zscore",
    width: Width = 8, depth: Depth = 3, activation: Activation = "tanh", loss: Loss = "mse",
    epochs: Epochs = 300, batch_size: BatchSize = 1024, lr: Lr = 3e-3, patience: Patience = 30,
    seed: Seed = 0, device: Device = "auto", max_minutes: MaxMinutes = None,
    mechanisms: Mechanisms = 4, rollout: Rollout = 0, rollout_weight: RolloutWeight = 1.0,
    rollout_substeps: RolloutSubsteps = 1, secant_floor: SecantFloor = 0.0,
) -> None:
    """Train a surrogate on a sample's training rows (20 % held out for early stopping),
    evaluate it on the sample's test rows, and save it with its metrics."""
    from ..surrogate import modelfile
    from ..surrogate.torch_support import require_torch
    from ..surrogate.training import train_on_sample

    require_torch()
    if out.suffix != ".safetensors":
        raise InputError(f"--out must end in .safetensors, got {str(out)!r}")
    cfg = _config(formulation=formulation, normalization=normalization, width=width, depth=depth,
                  activation=activation, loss=loss, epochs=epochs, batch_size=batch_size, lr=lr,
                  patience=patience, seed=seed, device=device, max_minutes=max_minutes,
                  mechanisms=mechanisms, rollout=rollout, rollout_weight=rollout_weight,
                  rollout_substeps=rollout_substeps, secant_floor=secant_floor)
    with LazyProgress("training") as progress:
        s, history = train_on_sample(data if len(data) > 1 else data[0], cfg, progress)
    modelfile.save(s, out)
    r2 = {m["output"]: m["r2"] for m in s.meta["metrics"] if m["quantity"] == "state after"}
    typer.echo(f"wrote {out}: {len(history)} epochs in {s.meta['seconds']:.0f} s; test R² "
               + ", ".join(f"{k} {v:.6f}" for k, v in r2.items()))


@app.command("distill")
def distill_cmd(
    teacher: Annotated[Path, typer.Argument(help="The meso model file to distil (the teacher).")],
    data: Annotated[list[Path], typer.Argument(help="The teacher's sample folder(s): their train rows' "
                                                    "states, their test rows for the metrics.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Model file to write (.safetensors).")],
    width: Width = 64, depth: Depth = 3,
    activation: Annotated[Optional[str], typer.Option(help="tanh, relu, silu, gelu or elu (default: "
                                                           "the teacher's).")] = None,
    strains: Annotated[int, typer.Option(help="Random strains per state, besides its own.")] = 3,
    raw_weight: Annotated[float, typer.Option(help="Weight of the raw outputs' difference in the loss.")] = 0.01,
    rollout: Annotated[int, typer.Option(help="Richer cells: steps of the windows along the data's paths "
                                              "that the student rolls out beside the teacher (0: none).")] = 4,
    rollout_weight: Annotated[float, typer.Option(help="Weight of the rollouts' difference in the loss.")] = 0.5,
    epochs: Epochs = 3000, batch_size: BatchSize = 1024, lr: Lr = 3e-3,
    patience: Annotated[int, typer.Option(help="Epochs without validation improvement before the "
                                               "learning rate is halved.")] = 30,
    min_lr: Annotated[float, typer.Option(help="Stop once the learning rate is below this.")] = 1e-5,
    seed: Seed = 0, device: Device = "cpu", max_minutes: MaxMinutes = None,
) -> None:
    """Distil a meso surrogate into a narrower network: the student learns the teacher's
    increments on the teacher's training states (a cheaper ANN-based H-model)."""
    from ..surrogate import modelfile
    from ..surrogate.distill import DistillConfig, distill_on_sample
    from ..surrogate.torch_support import require_torch

    require_torch("distillation")
    if out.suffix != ".safetensors":
        raise InputError(f"--out must end in .safetensors, got {str(out)!r}")
    cfg = DistillConfig(width=width, depth=depth, activation=activation, strains=strains,
                        raw_weight=raw_weight, rollout=rollout, rollout_weight=rollout_weight,
                        epochs=epochs, batch_size=batch_size, lr=lr, patience=patience, min_lr=min_lr,
                        seed=seed, device=device, max_minutes=max_minutes)
    model = modelfile.load(teacher)
    with LazyProgress("distilling") as progress:
        s, history = distill_on_sample(model, data if len(data) > 1 else data[0], cfg, progress)
    modelfile.save(s, out)
    typer.echo(f"wrote {out}: {s.architecture.width}x{s.architecture.depth} student of {teacher}, "
               f"{len(history)} epochs in {s.meta['seconds']:.0f} s, validation loss {s.meta['best_val_loss']:.3g}")


@app.command("evaluate")
def evaluate_cmd(
    model: Annotated[str, typer.Argument(help="Model file, or a shipped model: shipped (the default), "
                                              "increment.")],
    data: Annotated[list[Path], typer.Option("--data", help="Sample folder (its test rows) or dataset "
                                                            "folder; repeatable.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Folder for metrics.csv and parity plots.")],
    rows: Annotated[Optional[int], typer.Option(help="Rows drawn from a dataset folder (default 100000).")] = 100_000,
    seed: Seed = 0,
) -> None:
    """Metrics (MAE, RMSE, R², max |error|) on the state after and on the increments, and
    parity plots (report Figs. 2.4-2.6), for every --data."""
    from ..surrogate import modelfile
    from ..surrogate.evaluation import evaluate, parity_plot
    from ..surrogate.rows import read_rows
    from ..surrogate.shipped import model_path

    s = modelfile.load(model_path(model))
    table, writers = [], {}
    for i, d in enumerate(data):
        cols, info = read_rows(d, "test", rows, seed)
        label = f"{d.name} (dataset {info['provenance']['kind']})"
        table += evaluate(s, cols, label)
        writers[f"parity-{i}-{d.name}.png"] = (lambda c, lab: lambda p: parity_plot(
            s, c, p, f"{Path(model).name}: {lab}, {len(c['deps1']):,} rows"))(cols, label)
    write_outputs(out, {"metrics.csv": lambda p: write_rows(table, p), **writers})
    for r in table:
        if r["quantity"] == "state after":
            typer.echo(f"{r['data']:<40} {r['output']:<11} R² {r['r2']:.6f}  MAE {r['mae']:.4g}  "
                       f"max {r['max_abs']:.4g}")
    typer.echo(f"wrote {out / 'metrics.csv'} and {len(writers)} parity plot(s)")


@app.command("trust")
def trust_cmd(
    model: Annotated[str, typer.Argument(help="Model file, or a shipped model: shipped (the default), "
                                              "increment.")],
    sample: Annotated[Path, typer.Argument(help="Sample folder of the model's training rows (its train "
                                                "rows give the reference, its test rows the measure).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Model file written with its trust reference.")],
    reference: Annotated[int, typer.Option(help="Training rows kept as the reference.")] = 4096,
    k: Annotated[int, typer.Option("--k", help="Nearest reference rows the score averages over.")] = 8,
    rows: Annotated[Optional[int], typer.Option(help="Held-out rows measured (default: all).")] = None,
    seed: Seed = 0,
) -> None:
    """Add a trust score to a model (distance of a cell's inputs to its training rows, for
    --gate): measures on held-out rows which share of the error the least trusted rows hold."""
    from ..surrogate import modelfile
    from ..surrogate.rows import read_rows
    from ..surrogate.shipped import model_path
    from ..surrogate.trust import fit_trust

    if out.suffix != ".safetensors":
        raise InputError(f"--out must name a .safetensors file, got {str(out)!r}")
    s = modelfile.load(model_path(model))
    train, _ = read_rows(sample, "train")
    held, _ = read_rows(sample, "test", rows, seed)
    trusted, table = fit_trust(s, train, held, reference=reference, k=k, seed=seed)
    modelfile.save(trusted, out)
    for r in table:
        typer.echo(f"least trusted {100 * r['top_fraction']:g} % of {len(held['deps1']):,} held-out rows: "
                   f"{100 * r['share_of_error']:.1f} % of the error, "
                   f"{100 * r['share_of_squared_error']:.1f} % of the squared error")
    typer.echo(f"Spearman correlation of score and error {table[0]['spearman']:.3f}; wrote {out}")


@app.command("sweep")
def sweep_cmd(
    data: Annotated[Path, typer.Argument(help="Dataset 2 folder.")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Folder for sweep.csv and sweep.png.")],
    depths: Annotated[str, typer.Option(help="Hidden layers, comma-separated.")] = "3,5,7,9,11,13,15,17",
    losses: Annotated[str, typer.Option(help="Losses, comma-separated.")] = "mae,mse",
    sizes: Annotated[str, typer.Option(help="Training-set sizes, comma-separated.")] = "6000,60000,600000",
    test: Annotated[int, typer.Option(help="Held-out test rows shared by all runs.")] = 100_000,
    formulation: Formulation = "report", normalization: Normalization = "minmax",
    width: Width = 8, activation: Activation = "tanh", epochs: Epochs = 200,
    batch_size: BatchSize = 1024, lr: Lr = 3e-3, patience: Patience = 20, seed: Seed = 0,
    device: Device = "auto", max_minutes: MaxMinutes = None,
) -> None:
    """Report Table 2.1: every depth × loss × training-set size, one results table and plot."""
    from ..data import Dataset
    from ..surrogate.sweep import plot_sweep, run_sweep
    from ..surrogate.torch_support import require_torch

    require_torch()

    def ints(text: str, name: str) -> list[int]:
        try:
            return [int(t) for t in text.split(",") if t.strip()]
        except ValueError:
            raise InputError(f"--{name} expects comma-separated integers, got {text!r}") from None

    base = _config(formulation=formulation, normalization=normalization, width=width,
                   activation=activation, epochs=epochs, batch_size=batch_size, lr=lr,
                   patience=patience, seed=seed, device=device, max_minutes=max_minutes)
    loss_list = [t.strip() for t in losses.split(",") if t.strip()]
    for name in loss_list:
        _config(loss=name)
    ds = Dataset.open(data)
    with LazyProgress("sweep") as progress:
        rows = run_sweep(ds, base, ints(depths, "depths"), loss_list, ints(sizes, "sizes"), test,
                         seed, progress)
    write_outputs(out, {"sweep.csv": lambda p: write_rows(rows, p),
                        "sweep.png": lambda p: plot_sweep(rows, p),
                        "config.json": lambda p: p.write_text(json.dumps(
                            {"data": str(data), "base": base.__dict__}, indent=1))})
    typer.echo(f"wrote {out / 'sweep.csv'} ({len(rows)} runs) and {out / 'sweep.png'}")
