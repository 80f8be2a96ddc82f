"""Active learning of the richer cell with DEM rows: from 10 % of the recipe's rows, how many DEM
increments does ``hmodel surrogate refine --solver dem:hexagon-center`` need to reach the full
recipe's accuracy?

The recipe is the hexagon-center network's of ``benchmarks/dem/dem_ann.py`` as it is stepped now
(rollouts of 2 data steps in 4 network steps, ``cell_step`` 2.5e-4) on its first three datasets
(``WORK/data-0..2``, made by that script). The start: the same recipe on ``--fraction`` of each
dataset's sample rows (``WORK/small-K``), ``--members`` networks (seeds 0, 1, ...) whose
disagreement is the trust score. Each round runs the drained (100 kPa) and undrained (200 kPa)
paths to 2 % (nθ = 12, increments 10⁻³) with the gate to the DEM cell
(:mod:`hmodel.surrogate.shadow`), solves 24 DEM increments from each of at most ``--states``
gated cells (their DEM states caught up), fine-tunes every member on its rows and all new rows
(with its own rollouts and secant weighting) and measures the ensemble, ungated, against the
DEM-REV. The target is the full recipe's network (``--full``) on the same paths. The control
fine-tunes the start the same way on its own rows only: what the fine-tuning alone does.

Usage: ``python -m benchmarks.dem.refine_dem --work DIR --full FULL.safetensors [--gate 0.5]``;
prints a table, writes ``refine_dem.json``.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

from benchmarks.dem.dem_ann import HEX_SOLVER, HEX_TRAINING, PARAMS
from benchmarks.timing import provenance
from hmodel.compare import run_path, standard_paths
from hmodel.data.sampling import write_split
from hmodel.data.store import Dataset
from hmodel.studies.refine import RefineConfig, fine_tune, measure, refine
from hmodel.surrogate.modelfile import load, save
from hmodel.surrogate.training import train, union
from hmodel.surrogate.training_rows import params_of, read_sample
from hmodel.surrogate.trust import fit_ensemble_trust

#: The recipe as the shipped networks are stepped (see docs/dem.md, rate independence).
RECIPE = replace(HEX_TRAINING, rollout=2, rollout_substeps=4, cell_step=2.5e-4, max_minutes=10.0)


def start(work: Path, fraction: float, members: int) -> tuple[list, list[Path]]:
    """The small samples (``fraction`` of each full sample's rows) and the start's members."""
    samples = []
    for k in range(3):
        out = work / f"small-{k}"
        if not (out / "manifest.json").is_file():
            full = json.loads((work / f"sample-{k}" / "manifest.json").read_text())["files"]
            write_split(Dataset.open(work / f"data-{k}"), out, round(fraction * full["train"]["rows"]),
                        round(fraction * full["test"]["rows"]), seed=1)
        samples.append(out)
    models = []
    for seed in range(members):
        path = work / f"small-model-{seed}.safetensors"
        if not path.is_file():
            parts = [read_sample(f, "train") for f in samples]
            info = parts[0][1]
            m, _ = train(union([c for c, _ in parts]), params_of(info), replace(RECIPE, seed=seed),
                         cell=info["provenance"]["options"]["solver"])
            m.meta.update(params=info["params"])
            save(m, path)
        models.append(load(path))
    return models, samples


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", type=Path, required=True, help="dem_ann.py's work folder of the shipped network")
    ap.add_argument("--full", type=Path, required=True, help="the full recipe's network")
    ap.add_argument("--fraction", type=float, default=0.1)
    ap.add_argument("--members", type=int, default=2)
    ap.add_argument("--gate", type=float, default=0.5)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--states", type=int, default=300)
    ap.add_argument("--lr", type=float, default=3e-4)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("refine_dem.json"))
    args = ap.parse_args()
    members, samples = start(args.work, args.fraction, args.members)
    held = union([read_sample(f, "test")[0] for f in samples])
    members, ranking = fit_ensemble_trust(members, held)
    params = replace(PARAMS, n_theta=12)
    cfg = RefineConfig(exact=HEX_SOLVER, reference=HEX_SOLVER, paths=("drained", "undrained"),
                       rounds=args.rounds, gate=args.gate, states=args.states, increments=24,
                       magnitude=2e-3, epochs=100, patience=20, lr=args.lr, axial=0.02, step=1e-3,
                       iso_step=2e-4)
    specs = [s for s in standard_paths(cfg.axial) if s.name in cfg.paths]
    refs = {s.name: run_path(params, s, HEX_SOLVER, cfg.step, cfg.iso_step)[0] for s in specs}
    target = measure([load(args.full)], params, specs, refs, cfg)
    print(f"full recipe ({args.full.name}): max |dq| / peak q {100 * target['q_dev_max']:.2f} %")
    t = time.perf_counter()
    _, rounds = refine(members, samples, params, cfg, args.work / f"refine-g{args.gate:g}", log=print)
    seconds = time.perf_counter() - t
    # the control: the same fine-tuning, on the start's own rows only
    base = union([read_sample(f, "train")[0] for f in samples])
    control, tuned = [], members
    for r in range(1, args.rounds + 1):
        tuned, _ = fine_tune(tuned, base, params, cfg, r)
        control.append(measure(tuned, params, specs, refs, cfg)["q_dev_max"])
        print(f"control, round {r}: max |dq| / peak q {100 * control[-1]:.2f} %")
    print(f"{'round':>5}{'DEM rows in all':>17}{'gated states':>14}{'max |dq|/peak %':>17}{'control %':>11}")
    for r in rounds:
        c = control[r["round"] - 1] if r["round"] else rounds[0]["q_dev_max"]
        print(f"{r['round']:>5}{r['exact_rows']:>17,}{r.get('gated_states', 0):>14,}{100 * r['q_dev_max']:>17.2f}"
              f"{100 * c:>11.2f}")
    args.out.write_text(json.dumps({**provenance(__file__, args),
        "solver": HEX_SOLVER, "fraction": args.fraction, "members": args.members, "gate": args.gate,
        "start_train_rows": len(base["deps1"]), "trust_ranking": ranking, "full_recipe": str(args.full),
        "full_recipe_q_dev_max": target["q_dev_max"], "rounds": rounds, "control_q_dev_max": control,
        "seconds": seconds}, indent=1, default=float))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
