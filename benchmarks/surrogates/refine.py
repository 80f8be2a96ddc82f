"""Active learning (``hmodel surrogate refine``) from a deliberately small dataset: how many
exact rows does it need to reach the accuracy of the full recipe?

The full recipe is the shipped ANN-based H-model (``compliance``, 64×3 SiLU, 600,000 training
rows of the REV dataset; the commands are in ``src/hmodel/surrogate/models/README.md``). The
start is the same recipe trained on a ``--fraction`` of those rows (default 1 %: 6,000), given
a trust reference. Active learning then runs the six comparison paths (nθ = 360, increments
10⁻³) with the gate on, solves the gated states' increments with the exact cell (the closed
form), fine-tunes and measures, ``--rounds`` times, at each gate level of ``--gate``. The
target is the shipped model's own largest deviation on the same paths. Controls measure the
noise of that measure at this data size: the start model trained on without new rows, and the
recipe retrained on the same rows with other seeds.

With ``--members K``, the start is an ensemble of K networks of that recipe (seeds 0…K−1) whose
trust score is their disagreement, and every member is fine-tuned.

Usage: ``python -m benchmarks.surrogates.refine [--work DIR] [--members 4]``; prints a table, writes
``refine.json`` (``refine_ensemble.json``) and ``docs/figures/refine.png`` (``refine_ensemble.png``).
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import time
from pathlib import Path

from benchmarks.timing import FIGURES, record, write_table

DATA = ["hmodel", "data", "generate", "2", "--directions", "71", "--theta", "-60:150", "--alpha0",
        "32:88:4", "--max-strain", "0.2", "--step", "0.001", "--start-every", "0.002", "--magnitude",
        "0.002", "--magnitude-min", "0", "--increments", "24", "--substeps", "1"]
RECIPE = ["--formulation", "compliance", "--width", "64", "--depth", "3", "--activation", "silu",
          "--epochs", "614", "--patience", "60", "--seed", "0"]
PATHS = "isotropic,drained,undrained,unload-reload,oedometric,rotation"


def sh(*args: str) -> None:
    subprocess.run(list(args), check=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", type=Path, required=True, help="folder of the rounds (reused when there)")
    ap.add_argument("--fraction", type=float, default=0.01)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--states", type=int, default=250)
    ap.add_argument("--gate", type=float, nargs="+", default=[0.99, 0.5])
    ap.add_argument("--members", type=int, default=1,
                    help="an ensemble of this many networks (the recipe, seeds 0, 1, ...), gated on "
                         "their disagreement")
    ap.add_argument("--epochs", type=int, default=614,
                    help="training epochs of the start networks (the recipe's 614 are tuned for 600,000 rows)")
    ap.add_argument("--patience", type=int, default=60)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    if args.out is None:
        args.out = Path(__file__).with_name("refine.json" if args.members == 1 else "refine_ensemble.json")
    w = args.work
    w.mkdir(parents=True, exist_ok=True)
    n = int(round(600_000 * args.fraction))
    if not (w / "rev" / "manifest.json").is_file():
        sh(*DATA, "--out", str(w / "rev"))
    tag = "" if (args.epochs, args.patience) == (614, 60) else f"-e{args.epochs}p{args.patience}"
    recipe = [*RECIPE[:-6], "--epochs", str(args.epochs), "--patience", str(args.patience), "--seed", "0"]
    sample, model = w / f"rev-s{n}", w / f"start-{n}{tag}.safetensors"
    if not model.is_file():
        t = time.perf_counter()
        if not (sample / "manifest.json").is_file():
            sh("hmodel", "data", "sample", str(w / "rev"), "--train", str(n), "--test", "100000", "--seed", "0",
               "--out", str(sample))
        sh("hmodel", "surrogate", "train", str(sample), "--out", str(model), *recipe)
        sh("hmodel", "surrogate", "trust", str(model), str(sample), "--out", str(model),
           "--reference", str(min(4096, int(0.8 * n))))
        print(f"start model trained in {time.perf_counter() - t:.0f} s")
    spec, trust = str(model), None
    if args.members > 1:
        paths = [model]
        for seed in range(1, args.members):
            paths.append(w / f"start-{n}{tag}-seed{seed}.safetensors")
            if not paths[-1].is_file():
                sh("hmodel", "surrogate", "train", str(sample), "--out", str(paths[-1]),
                   *recipe[:-1], str(seed))  # the recipe, another seed
        first = w / f"ensemble-{n}{tag}-{args.members}.safetensors"
        sh("hmodel", "surrogate", "trust", "+".join(map(str, paths)), str(sample), "--out", str(first))
        spec = "+".join(map(str, [first, *paths[1:]]))
        from hmodel.surrogate import modelfile
        trust = modelfile.load(first).meta["trust"]["ranking"]
    target = w / "shipped-compare"
    sh("hmodel", "compare", "--solver", "surrogate", "--paths", PATHS, "--out", str(target))
    with open(target / "deviations.csv") as f:
        full = max(float(r["q_max_dev_rel"]) for r in csv.DictReader(f))
    rows = [("full recipe (shipped, 600,000 rows): max |dq| / peak q over the paths [%]", 100 * full, "target")]
    runs, reached = {}, {}
    for gate in args.gate:
        out = w / (f"refine-gate{gate:g}" + (f"-ensemble{args.members}" if args.members > 1 else "") + tag)
        t = time.perf_counter()
        sh("hmodel", "surrogate", "refine", spec, "--data", str(sample), "--out", str(out),
           "--paths", PATHS, "--rounds", str(args.rounds), "--states", str(args.states), "--gate", str(gate))
        with open(out / "rounds.csv") as f:
            runs[gate] = list(csv.DictReader(f))
        for r in runs[gate]:
            k, q = int(r["round"]), float(r["q_dev_max"])
            extra = "" if k == 0 else f", {100 * float(r['gated_fraction']):.2g} % of cell states gated"
            rows.append((f"gate {gate:g}, round {k}: {int(r['exact_rows']):,} exact rows{extra}: "
                         f"max |dq| / peak q [%]", 100 * q, "<= target"))
            if gate not in reached and q <= full:
                reached[gate] = int(r["exact_rows"])
        rows.append((f"gate {gate:g}: exact rows added when the target was reached (NaN: not reached)",
                     float(reached.get(gate, "nan")), f"< {600_000 - n:,}"))
        rows.append((f"gate {gate:g}: wall time of all rounds [s]", time.perf_counter() - t, "-"))
    if len(runs[args.gate[-1]]) > 1:
        FIGURES.mkdir(exist_ok=True)
        (FIGURES / args.out.with_suffix(".png").name).write_bytes((out / "rounds.png").read_bytes())
    controls = spread(model, sample, n) if args.members == 1 else tuned_only(spec, sample, args.rounds)
    for name, q in controls.items():
        rows.append((f"control: {name}: max |dq| / peak q [%]", 100 * q, "the noise floor"))
    for r in trust or []:
        f = 100 * r["top_fraction"]
        rows.append((f"ensemble disagreement: least trusted {f:g} % of held-out rows: share of the squared "
                     f"error [%]", 100 * r["share_of_squared_error"], "most"))
    if trust:
        rows.append(("ensemble disagreement: Spearman correlation with the error", trust[0]["spearman"], "-"))
    write_table(rows, args.out, record(__file__, args, 1, rows, start_rows=n, members=args.members,
                                       start_epochs=args.epochs, start_patience=args.patience,
                                       rounds={f"gate {g:g}": r for g, r in runs.items()},
                                       full_recipe_q_dev_max=full, controls=controls, trust_ranking=trust))


def references():
    """The refine runs' material, settings, paths and closed-form results, for the controls."""
    from hmodel import Params
    from hmodel.compare import run_path
    from hmodel.loading import standard_paths
    from hmodel.studies.refine import RefineConfig

    params, cfg = Params(), RefineConfig(paths=tuple(PATHS.split(",")))
    specs = [s for s in standard_paths(cfg.axial) if s.name in cfg.paths]
    return params, cfg, specs, {s.name: run_path(params, s, "closed-form", cfg.step, cfg.iso_step)[0]
                                for s in specs}


def spread(model_path: Path, sample: Path, n: int) -> dict[str, float]:
    """What the same measure gives without active learning: the start model trained on, on its
    own rows only, and the recipe retrained on the same rows with other seeds."""
    from hmodel.studies.refine import measure
    from hmodel.surrogate import modelfile
    from hmodel.surrogate.training import TrainConfig, train
    from hmodel.surrogate.training_rows import read_sample

    m0 = modelfile.load(model_path)
    cols, _ = read_sample(sample, "train")
    params, cfg, specs, refs = references()
    out = {"start model (seed 0)": measure(m0, params, specs, refs, cfg)["q_dev_max"]}
    for lr in (1e-3, 1e-4):
        m, _ = train(cols, params, TrainConfig(formulation="compliance", epochs=100, patience=20, lr=lr, seed=1),
                     init=m0)
        out[f"start model fine-tuned on its own {n:,} rows only (100 epochs, lr {lr:g})"] = measure(
            m, params, specs, refs, cfg)["q_dev_max"]
    for seed in (1, 2):
        m, _ = train(cols, params, TrainConfig(formulation="compliance", width=64, depth=3, activation="silu",
                                               epochs=614, patience=60, seed=seed))
        out[f"recipe retrained on the {n:,} rows, seed {seed}"] = measure(m, params, specs, refs, cfg)["q_dev_max"]
    return out


def tuned_only(spec: str, sample: Path, rounds: int) -> dict[str, float]:
    """The ensemble fine-tuned as the rounds do (same epochs, learning rate and seeds) on its own
    training rows only, without any new row: how much of a round's change the fine-tuning
    alone makes."""
    from hmodel.studies.refine import fine_tune, measure
    from hmodel.surrogate import modelfile
    from hmodel.surrogate.training_rows import read_sample

    members = [modelfile.load(p) for p in spec.split("+")]
    cols, _ = read_sample(sample, "train")
    params, cfg, specs, refs = references()
    out = {}
    for r in range(1, rounds + 1):
        members, _ = fine_tune(members, cols, params, cfg, r)
        m = measure(members, params, specs, refs, cfg)
        out[f"ensemble fine-tuned {r} time(s) on its own rows only, no new row"] = m["q_dev_max"]
        for name in cfg.paths:
            out[f"  same, {r} time(s), {name}"] = m[f"q_dev_{name}"]
    return out


if __name__ == "__main__":
    main()
