"""The richer cell over a range of materials: a hexagon-center family network against the DEM-REV (issue 36).

Data (``--generate``, or the folders of an earlier run): Dataset 3 of the hexagon-center cell in
YADE with a material drawn per REV loading (``hmodel data generate 3 ... --kt-kn 0.2:1 --phi-g
10:45 --alpha0 35:60:1``): ``START`` (the start of shear, dense in increment size, as the
shipped network's ``HEX_START``) and ``HISTORY`` (every 0.1 % to 4 %, as ``HEX_REV``), 48
loadings each (a material each), drained and undrained at 24 pressures from 50 to 400 kPa; and
``CELLS``, Dataset 2 of the cell alone along proportional paths, a material per path. α0 stops
at 60°: the free grain's touching radius √(1 + 4 sin²α0) − 1 exceeds 2 cos α0 beyond it, and
the centre grain would overlap grains 1 and 4 (the cell cannot be built at the touching ratio).
``CORNER`` (``--datasets ...,corner``; not in the shipped recipe) adds ``HISTORY`` loadings in the
corner of large α0 and small φg that the others leave empty.
The ratio is the touching one throughout: α0 fixes it.

Training (``--train``): the meso formulation with the material inputs (kt/kn, tan φg, α0) on
the rows of every finished shard of those datasets (a dataset still being generated gives its
finished shards, checksums verified, listed in the JSON), 5 % of them held out as test rows;
the shipped network's recipe, its rollout windows each stepped with their own material,
``--epochs`` budget; ``--init`` continues an earlier network, ``--rollout`` / ``--rollout-weight``
set its rollout windows (data steps, weight in the loss).

Comparison: ``--sets`` parameter sets drawn with ``--seed`` uniformly over the domain (none is a
training REV's material: those are continuous draws too), drained 100 kPa and undrained 200 kPa
to ``--axial-strain``, nθ = ``--n-theta``, REV increments ``--step``: the ANN-REV against the
DEM-REV (max and RMS |Δq| / peak q, max |Δεv|); the same at the materials of
``--training-materials`` (loadings it was trained on: whether it fits its own data); with
``--draw-in DATASET`` the sets are drawn over that dataset's ranges instead (``corner``); and the
ANN-REV at half its cell step against itself (whether the answer depends on how finely the
REV's increments are cut for the network). Speed: the REV at the shipped network's
material (α0 = 45°) with the family network and with the shipped single-material network
``hexagon-center-1`` (one network each, same cell step), same increments.

Usage: ``python -m benchmarks.dem.dem_ann_family --work W [--generate] [--train --epochs 60]``;
writes ``dem_ann_family.json`` and the compared curves, ``dem_ann_family_curves.csv``.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from benchmarks.timing import record
from hmodel import Params
from hmodel.compare import deviations, run_path, standard_paths
from hmodel.data import DatasetSpec
from hmodel.data.schema import column_array
from hmodel.data.store import generate, sha256
from hmodel.errors import SolverError
from hmodel.surrogate.evaluation import evaluate
from hmodel.surrogate.formulations.meso_rollout import jumps
from hmodel.surrogate.modelfile import load, save
from hmodel.surrogate.shipped import load_shipped
from hmodel.surrogate.solver import SurrogateSolver, domain_in_params_units
from hmodel.surrogate.training import TrainConfig, train, training_domain, union

PARAMS = Params(sliding_rhs="equilibrium")
SOLVER = "dem:hexagon-center:tol=1e-7,max_iter=100000"
#: 24 confining pressures from 50 to 400 kPa, geometric, drained and undrained: 48 REV loadings,
#: each with its own material, so that a dataset spans 48 materials (the first design's 16 per
#: dataset, with 4x the increments per state, left the material space too sparse; see the note
#: of 2026-12-03).
PRESSURES_KPA = [round(float(p)) for p in np.geomspace(50, 400, 24)]
#: Interleaved, so that the finished shards of a dataset still being generated hold both kinds.
LOADINGS = ",".join(f"{kind}:{p}e3" for p in PRESSURES_KPA for kind in ("drained", "undrained"))
START = DatasetSpec(kind=3, solver=SOLVER, rev_paths=LOADINGS, n_directions=16, theta_min=0.0, theta_max=90.0,
                    alpha0_min=35.0, alpha0_max=60.0, alpha0_step=1.0, max_strain=0.006, step=5e-4,
                    start_every=5e-4, n_increments=21, magnitude=2.5e-3, magnitude_min=1e-4, substeps=1,
                    from_unloaded=True, shard_rows=4000, kt_kn_range="0.2:1", phi_g_range="10:45",
                    material_seed=1)
HISTORY = replace(START, max_strain=0.04, step=1e-3, start_every=1e-3, n_increments=8, magnitude=2e-3,
                  magnitude_min=0.0, material_seed=2)
#: Dataset 2 of the cell alone (no REV, hence cheap): proportional paths to 4 % in 12 directions
#: over -60:150 deg at alpha0 35, 40, ... 60 deg, a material each (72 materials), a start state
#: every 0.1 % and the unloaded cell, 16 increments each (the shipped network's HEX_DATASET with a
#: material per path): 47,232 rows.
CELLS = DatasetSpec(kind=2, solver=SOLVER, n_directions=12, theta_min=-60.0, theta_max=150.0, alpha0_min=35.0,
                    alpha0_max=60.0, alpha0_step=5.0, max_strain=0.04, step=1e-3, start_every=1e-3,
                    n_increments=16, magnitude=2e-3, magnitude_min=0.0, substeps=1, from_unloaded=True,
                    shard_rows=4000, kt_kn_range="0.2:1", phi_g_range="10:45", material_seed=3)
#: ``HISTORY`` in the corner of the domain that its 96 REV loadings left empty (none of the 16
#: with alpha0 above 55 deg had phi_g below 20.4 deg; two sets drawn there missed by 18 and 38 %):
#: alpha0 48-60 deg with phi_g 10-22 deg, 32 loadings at 16 pressures from 50 to 400 kPa.
CORNER = replace(HISTORY, alpha0_min=48.0, phi_g_range="10:22", material_seed=4,
                 rev_paths=",".join(f"{kind}:{round(float(p))}e3" for p in np.geomspace(50, 400, 16)
                                    for kind in ("drained", "undrained")))
SPECS = {"start": START, "history": HISTORY, "cells": CELLS, "corner": CORNER}
#: Datasets inside the others' material ranges: they densify the stored domain, not bound it
#: (``training_domain`` intersects, and would shrink the domain to the corner).
DENSIFYING = {"corner"}
#: The shipped single-material network's recipe (benchmarks/dem/refine_dem.py: rollouts of 2 data
#: steps in 4 network steps of at most 2.5e-4 of cell strain, secant weighting), each rollout
#: window stepped with its own material's inputs, Coulomb bound and cage; the rows and windows
#: that jump (secant above 10 in the fields' units, above the 99.9th percentile of every field's
#: secants, 0.9-6.9: the unloaded cell's snaps in ``CELLS``) left out of the loss.
CONFIG = TrainConfig(formulation="meso", width=96, depth=3, activation="silu", epochs=60, patience=30,
                     seed=0, device="cpu", mechanisms=4, secant_floor=2.5e-4, cell_step=2.5e-4,
                     rollout=2, rollout_substeps=4, rollout_weight=0.5, max_secant=10.0)


def finished_rows(folder: Path) -> tuple[dict[str, np.ndarray], list[dict]]:
    """The rows of a dataset folder's finished shards (checksums verified) and their entries."""
    m = json.loads((folder / "manifest.json").read_text())
    parts, used = [], []
    for e in m["shards"]:
        path = folder / e["file"]
        if not path.is_file() or sha256(path) != e["sha256"]:
            continue
        t = pq.read_table(path)
        parts.append({c: column_array(t, c) for c in t.column_names})
        used.append({"folder": str(folder), **e})
    cols = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    return cols, used


def draw_sets(domain: dict, n: int, seed: int) -> list[Params]:
    rng = np.random.default_rng(seed)
    return [PARAMS.with_(**{k: rng.uniform(*domain[k]) for k in sorted(domain)}) for _ in range(n)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", type=Path, required=True)
    ap.add_argument("--generate", action="store_true", help="generate (or resume) the datasets")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--datasets", default="start,history,cells", help="which of start, history, cells to train on")
    ap.add_argument("--train", action="store_true", help="train the network (else: WORK/family.safetensors)")
    ap.add_argument("--epochs", type=int, default=CONFIG.epochs)
    ap.add_argument("--init", type=Path, default=None,
                    help="continue the training of this model file (its network, scalers and formulation)")
    ap.add_argument("--lr", type=float, default=CONFIG.lr)
    ap.add_argument("--width", type=int, default=CONFIG.width, help="hidden layer width (a new training)")
    ap.add_argument("--max-secant", type=float, default=CONFIG.max_secant,
                    help="leave out rows and window steps that jump past this secant (0: none)")
    ap.add_argument("--rollout", type=int, default=CONFIG.rollout, help="data steps of the rollout windows")
    ap.add_argument("--rollout-weight", type=float, default=CONFIG.rollout_weight)
    ap.add_argument("--sets", type=int, default=3)
    ap.add_argument("--seed", type=int, default=36)
    ap.add_argument("--draw-in", choices=sorted(SPECS), default=None,
                    help="draw the sets over this dataset's material ranges (default: the model's domain)")
    ap.add_argument("--training-materials", default="start:0,start:3,history:1",
                    help="also compare at these training loadings' materials (DATASET:LOADING,...)")
    ap.add_argument("--n-theta", type=int, default=12)
    ap.add_argument("--axial-strain", type=float, default=0.02)
    ap.add_argument("--step", type=float, default=1e-3)
    ap.add_argument("--iso-step", type=float, default=2e-4)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("dem_ann_family.json"))
    args = ap.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    names = [n for n in args.datasets.split(",") if n]
    folders = {n: args.work / f"dem-{n}" for n in names}
    if args.generate:
        for n in names:
            generate(SPECS[n], PARAMS, folders[n], workers=args.workers)
    model_path = args.work / "family.safetensors"
    info: dict = {}
    if args.train:
        parts, used = zip(*(finished_rows(folders[n]) for n in names))
        cols = union(list(parts))  # path ids apart, for the rollout windows
        n = len(cols["deps1"])
        test = np.random.default_rng(0).random(n) < 0.05
        train_cols = {k: v[~test] for k, v in cols.items()}
        test_cols = {k: v[test] for k, v in cols.items()}
        t0 = time.perf_counter()
        shown = [0]

        def progress(f: float) -> None:  # a line every 5 % of the budget, with the time so far
            if f >= shown[0] + 0.05 or f >= 1.0:
                shown[0] = f
                print(f"training {100 * f:.0f} % ({time.perf_counter() - t0:.0f} s)", flush=True)

        start = load(args.init) if args.init else None
        model, history = train(train_cols, PARAMS, replace(CONFIG, epochs=args.epochs, lr=args.lr, width=args.width,
                                                                max_secant=args.max_secant, rollout=args.rollout,
                                                                rollout_weight=args.rollout_weight), progress,
                               cell=SOLVER, init=start)
        if start is not None:  # the whole recipe: the earlier stages' epochs, then these
            model.meta["recipe"] = start.meta.get("recipe", [{"epochs": start.meta["training_summary"]["epochs"],
                                                              "lr": CONFIG.lr}]) + [{"epochs": len(history), "lr": args.lr,
                                                                 "rollout": args.rollout, "rollout_weight": args.rollout_weight}]
        seconds = time.perf_counter() - t0
        bounding = [SPECS[k].to_dict() for k in names if k not in DENSIFYING] or [SPECS[k].to_dict() for k in names]
        model.meta.update(params=PARAMS.to_dict(), domain=training_domain(bounding),
                          training_data=[u for us in used for u in us],
                          metrics=evaluate(model, test_cols, "held-out rows"), history_tail=history[-3:])
        materials = np.unique(np.column_stack([cols["kt_kn"], cols["phi_g"], cols["alpha0"]]), axis=0)
        info = {"rows": n, "train_rows": int((~test).sum()), "test_rows": int(test.sum()),
                "shards": [u for us in used for u in us], "training_materials": len(materials),
                "epochs": len(history), "training_seconds": seconds,
                "test_r2": {m["output"]: m["r2"] for m in model.meta["metrics"] if m["quantity"] == "state after"}}
        model.meta["training_summary"] = info
        save(model, model_path)
        print(f"trained on {n:,} rows of {len(materials)} materials: {len(history)} epochs in {seconds:.0f} s")
    model = load(model_path)
    # the held-out rows' R² without the rows that jump (left out of the loss, and which alone
    # make most of the squared error of the state after)
    parts = [finished_rows(folders[n])[0] for n in names]
    cols = union(parts)
    test = np.random.default_rng(0).random(len(cols["deps1"])) < 0.05
    test_cols = {k: v[test] for k, v in cols.items()}
    form = model.formulation
    Y, _ = form.targets(test_cols)
    floor = (model.meta["config"].get("secant_floor") or form.m0) / form.m0
    jumped = jumps(Y, form.aux(test_cols), args.max_secant, floor) if args.max_secant else np.zeros(len(Y), bool)
    smooth = {k: v[~jumped] for k, v in test_cols.items()}
    held_out = {"rows": int(test.sum()), "jumps": int(jumped.sum()), "max_secant": args.max_secant,
                "r2_without_jumps": {m["output"]: m["r2"] for m in evaluate(model, smooth, "held-out rows without jumps")
                                     if m["quantity"] == "state after"}}
    print("held-out R² without the", held_out["jumps"], "jumps:",
          ", ".join(f"{k} {v:.5f}" for k, v in held_out["r2_without_jumps"].items()))
    family = SurrogateSolver(model, on_outside="fallback")
    # --draw-in DATASET: the sets over that dataset's material ranges (inside the model's domain)
    draw_domain = family.domain if args.draw_in is None else domain_in_params_units(
        training_domain([SPECS[args.draw_in].to_dict()]))
    sets = draw_sets(draw_domain, args.sets, args.seed)
    paths = {s.name: s for s in standard_paths(args.axial_strain)}
    # and materials it was trained on (DATASET:LOADING): does the network fit its own data?
    trained = [(f"{n}:{i}", SPECS[n].path_materials(PARAMS, [int(i)])[0])
               for n, _, i in (t.partition(":") for t in args.training_materials.split(",") if t)]
    rows, curves = [], []
    for k, p in [*enumerate(sets), *trained]:
        params = p.with_(n_theta=args.n_theta)
        for spec in (replace(paths["drained"], p0=(1e5,)), paths["undrained"]):
            ref, t_dem = run_path(params, spec, SOLVER, args.step, args.iso_step)
            ann = SurrogateSolver(model)
            status = "ok"
            try:
                res, t_ann = run_path(params, spec, ann, args.step, args.iso_step)
            except SolverError as e:
                status, res, t_ann = f"failed: {' '.join(str(e).split())[:120]}", e.partial, float("nan")
            d = deviations(ref, res)[0] if len(res) else {}
            half = SurrogateSolver(model)  # the same network at half the cell step: its own consistency
            half.max_increment = ann.max_increment / 2
            try:
                res_half = run_path(params, spec, half, args.step, args.iso_step)[0]
            except SolverError as e:
                res_half = e.partial
            d_half = deviations(res, res_half)[0] if status == "ok" and len(res_half) else {}
            for label, r in (("dem", ref), ("ann", res)):
                if len(r):
                    pt = r.point(0)
                    curves.extend({"set": k, "path": spec.name, "solver": label, "eps11": float(e), "q_kPa": float(q) / 1e3,
                                   "eps_v": float(v)} for e, q, v in zip(pt["eps11"], pt["q"], pt["eps_v"]))
            rows.append({"set": k, "kt_kn": p.kt_kn, "phi_g_deg": math.degrees(p.phi_g), "alpha0_deg": p.alpha0_deg,
                         "path": spec.name, "p0_kPa": spec.p0[0] / 1e3, "status": status,
                         "trained_on": isinstance(k, str),
                         "dem_peak_q_kPa": float(np.max(ref.point(0)["q"])) / 1e3,
                         "q_max_dev_pct_of_peak": 100 * d.get("q_max_dev_rel", float("nan")),
                         "q_rms_dev_pct_of_peak": 100 * d.get("q_rms_dev_rel", float("nan")),
                         "eps_v_max_dev": d.get("eps_v_max_dev", float("nan")),
                         "q_max_dev_half_cell_step_pct": 100 * d_half.get("q_max_dev_rel", float("nan")),
                         "seconds_dem": t_dem, "seconds_ann": t_ann})
            r = rows[-1]
            print(f"set {k} (kt/kn {p.kt_kn:.3f}, phi_g {r['phi_g_deg']:.1f}, alpha0 {r['alpha0_deg']:.1f}) "
                  f"{spec.name}: peak q {r['dem_peak_q_kPa']:.1f} kPa, max |dq| {r['q_max_dev_pct_of_peak']:.2f} % "
                  f"of peak ({r['q_max_dev_half_cell_step_pct']:.2f} % at half the cell step), {status}")
    # speed: the shipped network's material, one network each, same increments and cell step
    params = PARAMS.with_(n_theta=args.n_theta)
    drained = replace(paths["drained"], p0=(1e5,))
    speed = {}
    for label, m in (("single", load_shipped("hexagon-center-1")), ("family", model)):
        run_path(params, drained, SurrogateSolver(m), args.step, args.iso_step)  # warm-up
        c = time.process_time()
        _, wall = run_path(params, drained, SurrogateSolver(m), args.step, args.iso_step)
        speed[label] = {"seconds": wall, "cpu_seconds": time.process_time() - c}
    ratio = speed["family"]["seconds"] / speed["single"]["seconds"]
    unseen = [r for r in rows if not r["trained_on"]]
    done = [r["q_max_dev_pct_of_peak"] for r in unseen if r["status"] == "ok"]
    worst = max(done, default=float("nan"))
    results = [("paths at unseen sets that stopped before the end [-]", len(unseen) - len(done), "0"),
               ("worst max |dq| / peak q over the paths that ran through [%]", worst, "<= 2"),
               ("worst max |dq| / peak q between the cell step and half of it, same paths [%]",
                max((r["q_max_dev_half_cell_step_pct"] for r in unseen), default=float("nan")), "-"),
               ("family / single-material network, REV time per run [x]", ratio, "<= 2"),
               ("the same in CPU time [x]", speed["family"]["cpu_seconds"] / speed["single"]["cpu_seconds"], "<= 2")]
    for name, v, target in results:
        print(f"{name}: {v:.3g} (target {target})")
    rec = record(__file__, args, 1, results, datasets={k: SPECS[k].to_dict() for k in names},
                 domain=model.meta["domain"], training=info or model.meta.get("training_summary", {}),
                 held_out=held_out,
                 sets=[{"kt_kn": s.kt_kn, "phi_g_deg": math.degrees(s.phi_g), "alpha0_deg": s.alpha0_deg}
                       for s in sets], paths=rows, speed=speed)
    args.out.write_text(json.dumps(rec, indent=1, default=str) + "\n")
    if curves:  # none with --sets 0 and no training materials (a training run alone)
        with open(args.out.with_name(args.out.stem + "_curves.csv"), "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(curves[0]))
            w.writeheader()
            w.writerows(curves)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
