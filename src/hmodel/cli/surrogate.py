"""``hmodel surrogate train | distill | evaluate | trust | sweep | refine``: neural surrogates of the H-cell (report §2.4-2.5)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Optional

import typer

from ..errors import InputError
from ..io import write_outputs, write_rows
from .options import ParamOpt, out_file, out_folder, strain_help
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
MaxMinutes = Annotated[Optional[float], typer.Option(help="Also stop after this wall time, for exploring: a run it cuts short "
                                                          "depends on the machine's load and cannot be rebuilt; budget recipes in --epochs.")]
Mechanisms = Annotated[int, typer.Option(help="meso: kinks of the learned incremental response.")]
Rollout = Annotated[int, typer.Option(help="meso of a richer cell: also train on rollouts of this many "
                                           "steps along the data's paths (0: single increments only).")]
RolloutWeight = Annotated[float, typer.Option(help="Weight of the rollout error in the loss.")]
RolloutSubsteps = Annotated[int, typer.Option(help="meso: network steps per data step of a rollout (a REV "
                                                   "at a finer increment than the data's; the shipped "
                                                   "hexagon-center networks: 4, with --cell-step).")]
SecantFloor = Annotated[float, typer.Option(help="meso: weigh errors as errors of the secant dz/|de|, "
                                                 "increments below this strain as this (0: of dz/m0).")]
MaxSecant = Annotated[float, typer.Option(help="meso: leave out rows (and cut rollout windows at steps) "
                                               "whose secant |dz|/|de| in the fields' units exceeds "
                                               "this: jumps of the cell (0: keep all).")]
CellStep = Annotated[Optional[float], typer.Option(help="meso: largest cell strain of one network step in a "
                                                        "REV (larger increments in equal sub-steps; default: "
                                                        "any), e.g. the rollout sub-steps' size.")]


def _config(**kw):
    from ..surrogate.training import TrainConfig
    return TrainConfig(**kw)


@app.command("train")
def train_cmd(
    data: Annotated[list[Path], typer.Argument(help="Sample folder(s) (hmodel data sample): trains on "
                                                    "train.parquet (of all of them together).")],
    out: out_file("Model file to write (.safetensors)."),
    formulation: Formulation = "increment", normalization: Normalization = "zscore",
    width: Width = 8, depth: Depth = 3, activation: Activation = "tanh", loss: Loss = "mse",
    epochs: Epochs = 300, batch_size: BatchSize = 1024, lr: Lr = 3e-3, patience: Patience = 30,
    seed: Seed = 0, device: Device = "auto", max_minutes: MaxMinutes = None,
    mechanisms: Mechanisms = 4, rollout: Rollout = 0, rollout_weight: RolloutWeight = 1.0,
    rollout_substeps: RolloutSubsteps = 1, secant_floor: SecantFloor = 0.0, max_secant: MaxSecant = 0.0,
    cell_step: CellStep = None,
    init: Annotated[Optional[Path], typer.Option(help="Fine-tune this model file instead (its formulation, "
                                                      "architecture, scalers and weights; the options "
                                                      "of those are ignored).")] = None,
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
                  rollout_substeps=rollout_substeps, secant_floor=secant_floor, max_secant=max_secant,
                  cell_step=cell_step)
    with LazyProgress("training") as progress:
        s, history = train_on_sample(data if len(data) > 1 else data[0], cfg, progress,
                                     init=None if init is None else modelfile.load(init))
    modelfile.save(s, out)
    r2 = {m["output"]: m["r2"] for m in s.meta["metrics"] if m["quantity"] == "state after"}
    typer.echo(f"wrote {out}: {len(history)} epochs in {s.meta['seconds']:.0f} s; test R² "
               + ", ".join(f"{k} {v:.6f}" for k, v in r2.items()))
    if s.meta.get("domain"):  # a family network (rows with a material per path)
        typer.echo("over materials " + ", ".join(f"{k} {lo:g}–{hi:g}" for k, (lo, hi) in s.meta["domain"].items())
                   + f" (inputs {', '.join(s.formulation.material_inputs)})")


@app.command("distill")
def distill_cmd(
    teacher: Annotated[Path, typer.Argument(help="The meso model file to distil (the teacher).")],
    data: Annotated[list[Path], typer.Argument(help="The teacher's sample folder(s): their train rows' "
                                                    "states, their test rows for the metrics.")],
    out: out_file("Model file to write (.safetensors)."),
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
    out: out_folder("Folder for metrics.csv and parity plots."),
    rows: Annotated[Optional[int], typer.Option(min=1, help="Rows drawn from a dataset folder (default 100000).")] = 100_000,
    seed: Seed = 0,
) -> None:
    """Metrics (MAE, RMSE, R², max |error|) on the state after and on the increments, and
    parity plots (report Figs. 2.4-2.6), for every --data."""
    from ..surrogate import modelfile
    from ..surrogate.folder_evaluation import evaluate_folder
    from ..surrogate.shipped import model_path

    s = modelfile.load(model_path(model))
    table, writers = [], {}
    for i, d in enumerate(data):
        metrics, parity = evaluate_folder(s, d, rows, seed)
        table += metrics
        if parity is not None:  # bi-hexagon rows have none
            writers[f"parity-{i}-{d.name}.png"] = (lambda w: lambda p: w(p, Path(model).name))(parity)
    write_outputs(out, {"metrics.csv": lambda p: write_rows(table, p), **writers})
    for r in table:
        if r["quantity"] in ("state after", "meso-stress"):
            typer.echo(f"{r['data']:<40} {r['output']:<11} R² {r['r2']:.6f}  MAE {r['mae']:.4g}  "
                       f"max {r['max_abs']:.4g}")
    typer.echo(f"wrote {out / 'metrics.csv'} and {len(writers)} parity plot(s)")


@app.command("trust")
def trust_cmd(
    model: Annotated[str, typer.Argument(help="Model file, or a shipped model: shipped (the default), "
                                              "increment; or an ensemble A+B+..., whose trust score is "
                                              "then the members' disagreement (stored with A).")],
    sample: Annotated[str, typer.Argument(help="Sample folder of the model's training rows (its train "
                                               "rows give the reference, its test rows the measure); "
                                               "several, comma-separated, for a model trained on several.")],
    out: out_file("Model file written with its trust reference."),
    reference: Annotated[int, typer.Option(min=1, help="Training rows kept as the reference.")] = 4096,
    k: Annotated[int, typer.Option("--k", min=1, help="Nearest reference rows the score averages over.")] = 8,
    rows: Annotated[Optional[int], typer.Option(min=1, help="Held-out rows measured (default: all).")] = None,
    seed: Seed = 0,
) -> None:
    """Add a trust score to a model (distance of a cell's inputs to its training rows, for
    --gate): measures on held-out rows which share of the error the least trusted rows hold."""
    import numpy as np

    from ..surrogate import modelfile
    from ..surrogate.shipped import model_paths
    from ..surrogate.training import union
    from ..surrogate.training_rows import read_rows
    from ..surrogate.trust import fit_ensemble_trust, fit_trust

    if out.suffix != ".safetensors":
        raise InputError(f"--out must name a .safetensors file, got {str(out)!r}")
    paths = model_paths(model)
    members = [modelfile.load(p) for p in paths]
    folders = [Path(f) for f in sample.split(",") if f.strip()]
    if not folders:
        raise InputError("give the sample folder of the model's training rows (SAMPLE is empty)")
    held = union([read_rows(f, "test")[0] for f in folders])
    if rows is not None and rows < len(held["deps1"]):
        keep = np.sort(np.random.default_rng(seed).choice(len(held["deps1"]), rows, replace=False))
        held = {c: v[keep] for c, v in held.items()}
    if len(members) > 1:  # an ensemble: its disagreement, stored with the first member
        trusted, table = fit_ensemble_trust(members, held)
        trusted = trusted[0]
    else:
        train = union([read_rows(f, "train")[0] for f in folders])
        trusted, table = fit_trust(members[0], train, held, reference=reference, k=k, seed=seed)
    modelfile.save(trusted, out)
    for r in table:
        typer.echo(f"least trusted {100 * r['top_fraction']:g} % of {len(held['deps1']):,} held-out rows: "
                   f"{100 * r['share_of_error']:.1f} % of the error, "
                   f"{100 * r['share_of_squared_error']:.1f} % of the squared error")
    typer.echo(f"Spearman correlation of score and error {table[0]['spearman']:.3f}; wrote {out}")
    if len(members) > 1:
        rest = "+".join(map(str, paths[1:]))
        typer.echo(f"gate the ensemble as --solver surrogate:{out}+{rest} (members in this order)")


@app.command("sweep")
def sweep_cmd(
    data: Annotated[Path, typer.Argument(help="Dataset 2 folder.")],
    out: out_folder("Folder for sweep.csv and sweep.png; an interrupted sweep into it resumes."),
    depths: Annotated[str, typer.Option(help="Hidden layers, comma-separated.")] = "3,5,7,9,11,13,15,17",
    losses: Annotated[str, typer.Option(help="Losses, comma-separated.")] = "mae,mse",
    sizes: Annotated[str, typer.Option(help="Training-set sizes, comma-separated.")] = "6000,60000,600000",
    test: Annotated[int, typer.Option(min=1, help="Held-out test rows shared by all runs.")] = 100_000,
    formulation: Formulation = "report",
    normalization: Annotated[str, typer.Option(help="minmax, zscore, robust, maxabs or unit; "
                                                    "comma-separated for several.")] = "minmax",
    inputs: Annotated[str, typer.Option(help="Input conventions, comma-separated: before (the forces "
                                             "before the increment) and after (the report's published "
                                             "code: forces after the increment, the answer leak).")] = "before",
    dataset1: Annotated[Optional[Path], typer.Option("--dataset1", help="Dataset 1 folder: --test of "
                                                     "its rows are scored too, as the report did.")] = None,
    width: Width = 8, activation: Activation = "tanh", epochs: Epochs = 200,
    batch_size: BatchSize = 1024, lr: Lr = 3e-3, patience: Patience = 20, seed: Seed = 0,
    device: Device = "auto", max_minutes: MaxMinutes = None,
) -> None:
    """Report Table 2.1: every depth × loss × training-set size (× normalization × input
    convention), one results table and plot, with the report's pooled scores (§2.5)."""
    from ..data import Dataset
    from ..studies.sweep import KEYS, plot_sweep, run_sweep
    from ..surrogate.torch_support import require_torch
    from ..surrogate.training_rows import read_rows

    require_torch()

    def ints(text: str, name: str) -> list[int]:
        try:
            return [int(t) for t in text.split(",") if t.strip()]
        except ValueError:
            raise InputError(f"--{name} expects comma-separated integers, got {text!r}") from None

    def names(text: str) -> list[str]:
        return [t.strip() for t in text.split(",") if t.strip()]

    base = _config(formulation=formulation, normalization=names(normalization)[0] if names(normalization) else "",
                   width=width, activation=activation, epochs=epochs, batch_size=batch_size, lr=lr,
                   patience=patience, seed=seed, device=device, max_minutes=max_minutes)
    loss_list = names(losses)
    for name in loss_list:
        _config(loss=name)
    for name in names(normalization):
        _config(normalization=name)
    depth_list, size_list = ints(depths, "depths"), ints(sizes, "sizes")
    ds = Dataset.open(data)
    tests = {"d1": read_rows(dataset1, "test", test, seed)[0]} if dataset1 is not None else {}
    config = {"data": str(data), "dataset1": str(dataset1) if dataset1 else None, "base": base.__dict__,
              "depths": depths, "losses": losses, "sizes": sizes, "test": test,
              "normalization": normalization, "inputs": inputs}
    # Finished runs are kept beside the output folder until the sweep ends, so that re-running
    # the same command after an interruption trains only the missing ones.
    partial = out.parent / f".{out.name}.partial.jsonl"
    done = []
    if partial.exists():
        lines = [json.loads(x) for x in partial.read_text().splitlines() if x.strip()]
        if lines and lines[0] == config:
            done = lines[1:]
    if not done:
        out.parent.mkdir(parents=True, exist_ok=True)
        partial.write_text(json.dumps(config) + "\n")

    def keep(row: dict) -> None:
        with partial.open("a") as f:
            f.write(json.dumps(row) + "\n")

    if done:
        typer.echo(f"resuming: {len(done)} finished run(s) of {partial}")
    try:
        with LazyProgress("sweep") as progress:
            rows = run_sweep(ds, base, depth_list, loss_list, size_list, test, seed, progress,
                             normalizations=names(normalization), inputs=names(inputs), tests=tests,
                             done=[r for r in done if all(k in r for k in KEYS)], on_row=keep)
    except BaseException:
        if len(partial.read_text().splitlines()) <= 1:  # no run finished: nothing to resume
            partial.unlink(missing_ok=True)
        raise
    write_outputs(out, {"sweep.csv": lambda p: write_rows(rows, p),
                        "sweep.png": lambda p: plot_sweep(rows, p),
                        "config.json": lambda p: p.write_text(json.dumps(config, indent=1))})
    partial.unlink(missing_ok=True)
    typer.echo(f"wrote {out / 'sweep.csv'} ({len(rows)} runs) and {out / 'sweep.png'}")


@app.command("refine")
def refine_cmd(
    model: Annotated[str, typer.Argument(help="Model file with a trust score, a shipped model (shipped: "
                                              "the default model), or an ensemble A+B+... whose trust is "
                                              "its disagreement (hmodel surrogate trust A+B+...).")],
    data: Annotated[str, typer.Option("--data", help="Sample folder of the model's training rows "
                                                     "(fine-tuning keeps them); several, comma-separated.")],
    out: out_folder("Folder for the rounds (rows, models), rounds.csv, rounds.png and "
                    "model.safetensors; an interrupted run into it resumes."),
    solver: Annotated[str, typer.Option("--solver", help="Exact cell solver of the new rows: "
                                                         "closed-form or dem:standard (H-cell networks), "
                                                         "or a richer cell's dem:MESO (its meso network).")] = "closed-form",
    reference: Annotated[str, typer.Option(help="Solver the rounds' errors are measured against.")] = "closed-form",
    paths: Annotated[str, typer.Option(help="REV paths (hmodel compare's names), comma-separated.")] = "drained,undrained,unload-reload",
    rounds: Annotated[int, typer.Option(help="Rounds of gate, exact rows and fine-tuning.")] = 3,
    gate: Annotated[float, typer.Option(help="Trust quantile above which a cell is gated.")] = 0.99,
    states: Annotated[int, typer.Option(help="Most gated states solved per round.")] = 2000,
    increments: Annotated[int, typer.Option(help="Increment directions per gated state.")] = 24,
    magnitude: Annotated[float, typer.Option(help="Largest cell strain increment of the new rows.")] = 2e-3,
    epochs: Annotated[int, typer.Option(help="Fine-tuning epochs per round (early stopping may end sooner).")] = 100,
    patience: Patience = 20, lr: Annotated[float, typer.Option(help="Fine-tuning learning rate.")] = 1e-3,
    axial_strain: Annotated[float, typer.Option(help=strain_help("Axial strain of the biaxial paths."))] = 0.1,
    step: Annotated[float, typer.Option(help=strain_help("Strain increment of the REV paths."))] = 1e-3,
    iso_step: Annotated[float, typer.Option(help=strain_help("Strain increment of the consolidations."))] = 1e-4,
    param: ParamOpt = None,
    seed: Seed = 0,
) -> None:
    """Active learning: run REV paths with the gate on, solve the gated cells' increments with
    the exact solver, fine-tune, repeat; error and exact rows per round."""
    from ..params import Params
    from ..studies.refine import RefineConfig, plot_rounds, refine
    from ..surrogate import modelfile
    from ..surrogate.shipped import model_paths
    from ..surrogate.torch_support import require_torch

    require_torch()
    params = Params.parse_assignments(param)
    cfg = RefineConfig(exact=solver, reference=reference, paths=tuple(p.strip() for p in paths.split(",") if p.strip()),
                       rounds=rounds, gate=gate, states=states, increments=increments, magnitude=magnitude,
                       epochs=epochs, patience=patience, lr=lr, axial=axial_strain, step=step,
                       iso_step=iso_step, seed=seed)
    members = [modelfile.load(p) for p in model_paths(model)]
    with LazyProgress("refining") as progress:
        final, rows = refine(members, [Path(f) for f in data.split(",") if f], params, cfg, out, progress,
                             typer.echo)
    names = ["model.safetensors"] + [f"model-{k}.safetensors" for k in range(1, len(final))]
    write_outputs(out, {"rounds.csv": lambda p: write_rows(rows, p),
                        "rounds.png": lambda p: plot_rounds(rows, p),
                        **{n: (lambda m: lambda p: modelfile.save(m, p))(m) for n, m in zip(names, final)}})
    typer.echo(f"wrote {out / 'rounds.csv'}, {out / 'rounds.png'} and " + "+".join(str(out / n) for n in names))
