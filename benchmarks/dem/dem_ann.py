"""The ANN-based H-model trained on DEM data against the DEM-REV (YADE cells).

Pipeline, all from the library: a Dataset 2 of single DEM increments (the recipe of
``hmodel.surrogate.shipped.REV_DATASET``: increments <= 0.2 % in one sub-step from paths over
theta -60:150, scaled down to minutes: fewer directions, opening angles and start states;
``sliding_rhs=equilibrium``, the closure the DEM cells follow) -> a random train/test sample ->
a surrogate -> the REV with that surrogate next to the DEM-REV on drained and undrained biaxial
paths at small n_theta. Two cases (``--mesostructure``):

- ``hexagon-center`` (default; the issue's richer cell): the hexagon with a free centre grain
  (radius ratio sqrt(3) - 1, touching grains 2, 3, 5, 6 at alpha0 = 45 deg), no closed form;
  the ``meso`` formulation (summary state with the Love-Weber meso-stress) trained with rollout
  windows, on the recipe's data, unloading paths from a consolidated cell and a Dataset 3 (the
  increments from the states of a 16-cell DEM-REV's cells along drained and undrained loadings
  at other pressures than the compared ones); data and reference DEM at the quasi-static
  tolerance 1e-7.
- ``standard``: the H-cell in DEM, the ``compliance`` formulation; the closed form is listed as
  a third reference.

The hexagon-center ANN-REV is the 64x3 student distilled from one 96x3 network (``STUDENT``;
``--no-student``: the network itself), the network listed beside it; ``--members N`` trains an
ensemble of N networks alike (seeds 0 ... N-1), whose increments it averages, each listed alone.

Reported per path: max and RMS deviation of q relative to the DEM-REV's peak q (and the closed
form's, as a reference; for an ANN run that fails, over its rows before the failure, with the
axial strain where it failed), overlay figures in ``WORK/figures``, and the wall times at the
same output resolution (same increments):
the ANN-REV as the best of ``--repeat`` runs after a warm-up, the DEM-REV with a warm YADE
process (its start-up, measured on a fresh solver's first one-cell request, is listed apart).

Usage: ``python -m benchmarks.dem.dem_ann [--mesostructure NAME] [--work DIR] [--reuse] [--members N]``; prints
a table, writes ``dem_ann.json`` (``dem_ann_standard.json`` for the standard cell).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks.timing import best_of, provenance
from hmodel import Params
from hmodel.compare import deviations, run_path, standard_paths
from hmodel.data import DatasetSpec
from hmodel.data.sampling import write_split
from hmodel.data.store import generate
from hmodel.dem.solver import DEMSolver
from hmodel.surrogate.distill import DistillConfig, distill_on_sample
from hmodel.surrogate.modelfile import load, save
from hmodel.surrogate.solver import SurrogateSolver
from hmodel.surrogate.training import TrainConfig, train_on_sample

PARAMS = Params(sliding_rhs="equilibrium")
#: The H-cell in DEM: the hexagon-center recipe below (72 directions over -60:150 at the REV's
#: alpha0, paths to 8 %, starts every 0.2 % and the unloaded cell, one sub-step, tolerance 1e-7).
#: (A spread of alpha0 around 45 deg at the default tolerance 1e-10 took > 15 min per shard.)
STANDARD_SOLVER = "dem:standard:tol=1e-7,max_iter=100000"
STANDARD_DATASET = DatasetSpec(kind=2, n_directions=72, theta_min=-60.0, theta_max=150.0,
                               alpha0_min=45.0, alpha0_max=45.0, alpha0_step=1.0, max_strain=0.08,
                               step=0.001, start_every=0.002, magnitude=0.002, magnitude_min=0.0,
                               n_increments=24, substeps=1, shard_rows=4000, solver=STANDARD_SOLVER,
                               from_unloaded=True)
STANDARD_TRAINING = TrainConfig(formulation="compliance", width=64, depth=3, activation="silu",
                                epochs=1000, patience=100, seed=0, device="cpu", max_minutes=5.0)
#: The richer cell at the REV's alpha0 only (a surrogate of one mesostructure): 72 directions over
#: -60:150, paths to 8 %, a start state every 0.2 % and the unloaded cell, 24 increments each:
#: 70,848 rows (3 min here).
#: The quasi-static tolerance 1e-7 (the solver's default 1e-10 is not reached by some of these
#: cells within 100k steps, which held a whole batch).
HEX_SOLVER = "dem:hexagon-center:tol=1e-7,max_iter=100000"
HEX_DATASET = replace(STANDARD_DATASET, solver=HEX_SOLVER)
#: The same paths after an isotropic cell strain of 0.1 % (a REV's consolidation to 100-250 kPa):
#: the REV's cells turn from consolidation into shear, states the first dataset's proportional
#: paths never reach. Added with ``--prestrained``.
HEX_PRESTRAINED = replace(HEX_DATASET, prestrain=0.001)
#: The first shear increments at low confinement: the same 72 directions from the cell after an
#: isotropic cell strain of 0.02 % and 0.04 % (a REV consolidated to ~70 and ~135 kPa; the data
#: above has start states at 0 and 0.2 % only), paths to 0.4 % in steps of 0.01 %, a start state
#: every 0.05 % and the consolidated cell, 24 increments each: 31,104 rows. Added with
#: ``--low-pressure``.
HEX_LOW = tuple(replace(HEX_DATASET, prestrain=e, step=1e-4, max_strain=0.004, start_every=5e-4)
                for e in (2e-4, 4e-4))
#: Unloading from a consolidated cell: paths over 150:300 deg (extension and the mixed
#: directions the first dataset leaves out) after an isotropic cell strain of 0.1 %, to 1 %:
#: cells that open completely, as a REV's cells at 45 deg do in dilatant drained shear
#: (10,368 rows, 20 s).
HEX_UNLOADING = replace(HEX_DATASET, theta_min=150.0, theta_max=300.0, prestrain=0.001, max_strain=0.01)
#: Dataset 3: the same increments (16 directions) from the states a 16-cell DEM-REV's cells pass
#: through, drained at 50, 75, 125, 150, 250 and 300 kPa and undrained at 100, 150 and 300 kPa,
#: every 0.1 % of axial strain to 4 %: the bent strain paths of a REV's cells (consolidation, then
#: shear; dilation, opening). Loadings and directions apart from the compared REVs' (drained 100
#: and 200 kPa, undrained 200 kPa; 12 and 36 cells). 94,464 rows.
HEX_REV = replace(HEX_DATASET, kind=3, n_directions=16, theta_min=0.0, theta_max=90.0, max_strain=0.04,
                  start_every=0.001, n_increments=16,
                  rev_paths="drained:50e3,drained:75e3,drained:125e3,drained:150e3,drained:250e3,"
                            "drained:300e3,undrained:100e3,undrained:150e3,undrained:300e3")
#: Dataset 3 again, at the start of shear, dense in increment size: the states every 0.05 % of
#: axial strain to 0.6 % of the same loadings, 64 increment directions with magnitudes spread over
#: 1e-4 ... 2.5e-3 (golden-ratio sequence: every size along every sector). A REV's first shear
#: increment from a consolidated cell crosses the onsets of sliding within the increment; the
#: rows above hold one size per direction, and the network took the first increments as linear
#: (too soft for small REV increments, too stiff for large ones: the rate dependence of
#: benchmarks/dem/dem_ann_start.py). 119,808 rows (4 min here).
HEX_START = replace(HEX_REV, max_strain=0.006, step=5e-4, start_every=5e-4, n_increments=64,
                    magnitude=2.5e-3, magnitude_min=1e-4)
#: Errors weighed as errors of the secant dz/|de| down to increments of 2.5e-4 (``secant_floor``):
#: on dz/m0 the first shear increments from a consolidated cell were left to the large increments,
#: and every network was too soft there at 100 kPa (docs/dem.md).
#: Width 96: as accurate as 128 on the compared paths (one network each, seeds 0 and 1: 1.17 and
#: 1.88 % of peak q at most, against 1.83 % for 128) at 0.6 of its products; 64 was 2.8 % off.
HEX_TRAINING = TrainConfig(formulation="meso", width=96, depth=3, activation="silu",
                           epochs=3000, patience=60, seed=0, device="cpu", max_minutes=20.0,
                           mechanisms=4, rollout=4, rollout_weight=0.5, secant_floor=2.5e-4)
#: Networks per ANN-REV: one. An ensemble (``--members``, seeds 0, 1, ..., averaged increments)
#: of three 128-wide networks was within 0.29-1.38 % of peak q, at three times the cost
#: (docs/dem.md).
MEMBERS = {"hexagon-center": 1, "standard": 1}
#: The compared ANN-REV of the hexagon-center cell: the 96x3 network distilled into a 64x3 one
#: (``hmodel.surrogate.distill``: increments, raw outputs and 4-step rollouts of the teacher),
#: half the products per cell; the teacher is listed beside it.
STUDENT = {"hexagon-center": DistillConfig(width=64, depth=3, raw_weight=0.01, rollout=4, rollout_weight=0.5,
                                           patience=30, max_minutes=25.0), "standard": None}
CASES = {"hexagon-center": ((HEX_DATASET, HEX_UNLOADING, HEX_REV), HEX_TRAINING, HEX_SOLVER),
         "standard": ((STANDARD_DATASET,), STANDARD_TRAINING, STANDARD_SOLVER)}


def build_models(work: Path, specs, config: TrainConfig, n_train: int, n_test: int, workers: int,
                 members: int, reuse: bool) -> tuple[list[Path], dict]:
    """Datasets -> samples (``n_train``/``n_test`` rows each) -> ``members`` models trained on
    them all alike, with seeds ``config.seed + k`` (an ensemble; ``work/model-K.safetensors``,
    kept with ``reuse``); returns their paths and the stage timings of this run."""
    paths = [work / f"model-{k}.safetensors" for k in range(members)]
    todo = [k for k, p in enumerate(paths) if not (reuse and p.is_file())]
    t = {"dataset_s": 0.0, "sample_s": 0.0, "training_s": [], "epochs": [], "test_metrics": []}
    if not todo:
        return paths, {}
    samples, rows, n_rows = [], [], []
    for k, spec in enumerate(specs):
        t0 = time.perf_counter()
        ds = generate(spec, PARAMS, work / f"data-{k}", workers=workers)
        t["dataset_s"] += time.perf_counter() - t0
        n_te = min(n_test, ds.n_rows // 6)
        n_tr = min(n_train, ds.n_rows - n_te - ds.n_rows // 20)  # cleaning drops a few rows
        t0 = time.perf_counter()
        write_split(ds, work / f"sample-{k}", n_tr, n_te)
        t["sample_s"] += time.perf_counter() - t0
        samples.append(work / f"sample-{k}")
        rows.append(ds.n_rows)
        n_rows.append((n_tr, n_te))
    for k in todo:
        t0 = time.perf_counter()
        model, history = train_on_sample(samples, replace(config, seed=config.seed + k))
        t["training_s"].append(time.perf_counter() - t0)
        t["epochs"].append(len(history))
        t["test_metrics"].append(model.meta.get("metrics"))
        save(model, paths[k])
    info = {**t, "trained_members": todo, "rows": sum(rows), "train_rows": sum(a for a, _ in n_rows),
            "test_rows": sum(b for _, b in n_rows)}
    return paths, info


def build_student(work: Path, teacher: Path, n_samples: int, config: DistillConfig, reuse: bool) -> Path:
    """``teacher`` distilled on its training samples (``work/sample-K``) into
    ``work/student-WxD.safetensors`` (kept with ``reuse``)."""
    path = work / f"student-{config.width}x{config.depth}.safetensors"
    if not (reuse and path.is_file()):
        student, _ = distill_on_sample(load(teacher), [work / f"sample-{k}" for k in range(n_samples)], config)
        save(student, path)
    return path


def yade_startup(solver: str) -> float:
    """Wall time of a fresh DEM solver's first request (one unloaded cell, no increment)."""
    s = DEMSolver(solver)
    cell = s.initial(PARAMS, (1,))
    t = time.perf_counter()
    s.step(PARAMS, cell, np.zeros(1), np.zeros(1))
    out = time.perf_counter() - t
    s.yade().close()
    return out


def compare(models: list, solver: str, n_thetas, axials, step: float, iso_step: float,
            repeat: int, figures: Path, others: dict | None = None):
    """Rows of the comparison table; overlay figures (DEM-REV vs ANN-REV) into ``figures``. A
    failed ANN run keeps its rows up to the failure: deviations there, and where it failed. The
    ANN-REV is the ensemble of the models; ``others`` (name: models; default each member of an
    ensemble alone) are listed too (max deviation, or nan where it failed)."""
    from hmodel.compare import plot_overlay
    from hmodel.errors import SolverError

    rows = []
    for n_theta, axial in ((n, a) for n in n_thetas for a in axials):
        params = replace(PARAMS, n_theta=n_theta)
        paths = {s.name: s for s in standard_paths(axial)}
        for spec in (replace(paths["drained"], p0=(1e5, 2e5)), paths["undrained"]):
            dem = DEMSolver(solver)
            ann = SurrogateSolver(models, on_outside="error")
            alone = {}
            ref, _ = run_path(params, spec, dem, step, iso_step)  # also starts YADE
            if others is None:
                others = {f"member {k}": [m] for k, m in enumerate(models)} if len(models) > 1 else {}
            for name, ms in others.items():
                try:
                    alone[name] = [d["q_max_dev_rel"] for d in deviations(
                        ref, run_path(params, spec, SurrogateSolver(ms, on_outside="error"), step, iso_step)[0])]
                except SolverError:
                    alone[name] = [float("nan")] * len(spec.p0)
            calls0 = dem.yade().calls
            t_dem = best_of(lambda: run_path(params, spec, dem, step, iso_step), 1)
            status, failed_at = "ok", float("nan")
            try:
                res, _ = run_path(params, spec, ann, step, iso_step)
                t_ann = best_of(lambda: run_path(params, spec, ann, step, iso_step), repeat)
            except SolverError as e:  # reported, not hidden; compared up to the failure
                status, t_ann, res = f"failed: {' '.join(str(e).split())[:160]}", float("nan"), e.partial
                shear = res.stage("shear")
                failed_at = float(np.max(shear["eps11"])) if len(shear) else 0.0
            dev = deviations(ref, res) if len(res) else []
            if len(res):
                plot_overlay(f"{spec.name}, n_theta = {n_theta}, {solver}", ref, res, ("DEM-REV", "ANN-REV"),
                             figures / f"{spec.name}_ntheta{n_theta}_axial{100 * axial:g}.png")
            dev_cf = []
            if solver.startswith("dem:standard"):  # the H-cell's closed form as a third reference
                dev_cf = deviations(ref, run_path(params, spec, "closed-form", step, iso_step)[0])
            for b in range(len(spec.p0)):
                d = dev[b] if dev else {}
                rows.append({"path": spec.name, "n_theta": n_theta, "axial_pct": 100 * axial,
                             "p0_kPa": spec.p0[b] / 1e3,
                             "rows": len(ref.point(b)), "status": status,
                             "dem_peak_q_kPa": float(np.max(ref.point(b)["q"])) / 1e3,
                             "ann_failed_at_axial_pct": 100 * failed_at,
                             "ann_q_max_dev_pct_of_peak": 100 * d.get("q_max_dev_rel", float("nan")),
                             "ann_q_rms_dev_pct_of_peak": 100 * d.get("q_rms_dev_rel", float("nan")),
                             "others_q_max_dev_pct_of_peak": {k: 100 * a[b] for k, a in alone.items()},
                             "ann_eps_v_max_dev_pct": 100 * d.get("eps_v_max_dev", float("nan")),
                             "closed_form_q_max_dev_pct_of_peak":
                                 100 * dev_cf[b]["q_max_dev_rel"] if dev_cf else float("nan"),
                             "seconds_dem": t_dem, "seconds_ann": t_ann,
                             "dem_over_ann": t_dem / t_ann,
                             "dem_requests_per_run": dem.yade().calls - calls0,
                             "ann_outside_cells": ann.counts["outside"]})
            dem.yade().close()
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesostructure", choices=list(CASES), default="hexagon-center")
    ap.add_argument("--work", type=Path, required=True, help="folder of the datasets, samples and models (reused with --reuse)")
    ap.add_argument("--n-theta", default="12,36")
    ap.add_argument("--axial", default="0.02,0.03", help="axial strains of the biaxial paths")
    ap.add_argument("--step", type=float, default=1e-3)
    ap.add_argument("--iso-step", type=float, default=2e-4)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--train", type=int, default=60000)
    ap.add_argument("--test", type=int, default=6000)
    ap.add_argument("--width", type=int, default=None, help="hidden-layer width (default: the case's)")
    ap.add_argument("--members", type=int, default=None, help="networks of the ensemble (default: the case's)")
    ap.add_argument("--reuse", action="store_true", help="reuse the model files in --work")
    ap.add_argument("--no-student", action="store_true",
                    help="compare the trained network(s), not the case's distilled student")
    ap.add_argument("--prestrained", action="store_true",
                    help="hexagon-center: train on the prestrained dataset too")
    ap.add_argument("--low-pressure", action="store_true",
                    help="hexagon-center: train on the low-confinement datasets too")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    specs, config, solver = CASES[args.mesostructure]
    if args.width:
        config = replace(config, width=args.width)
    if args.prestrained:
        specs = specs + (HEX_PRESTRAINED,)
    if args.low_pressure:
        specs = specs + HEX_LOW
    work = args.work
    out = args.out or Path(__file__).with_name(
        ("dem_ann" if args.mesostructure == "hexagon-center" else f"dem_ann_{args.mesostructure}")
        + ("_prestrained" if args.prestrained else "") + ("_low" if args.low_pressure else "") + ".json")
    work.mkdir(parents=True, exist_ok=True)
    members = args.members or MEMBERS[args.mesostructure]
    model_files, info = build_models(work, specs, config, args.train, args.test, args.workers, members, args.reuse)
    if not info and out.is_file():  # the same models: keep the record of how they were built
        info = json.loads(out.read_text()).get("build", {})
    startup = yade_startup(solver)
    (work / "figures").mkdir(exist_ok=True)
    models = [load(p) for p in model_files]
    others, student_info = None, {}
    student_config = None if args.no_student else STUDENT[args.mesostructure]
    if student_config is not None:  # the student is compared, its teacher(s) listed beside it
        student_file = build_student(work, model_files[0], len(specs), student_config, args.reuse)
        meta = load(student_file).meta  # the record of how it was made travels in the file
        student_info = {"file": str(student_file), "epochs": meta["epochs_run"], "distill_s": meta["seconds"],
                        "best_val_loss": meta["best_val_loss"], "config": meta["distilled"]["config"]}
        others = {f"teacher {models[0].architecture.width}x{models[0].architecture.depth}": models}
        models, model_files = [load(student_file)], [student_file]
    rows = compare(models, solver, [int(n) for n in args.n_theta.split(",")],
                   [float(a) for a in args.axial.split(",")], args.step, args.iso_step, args.repeat,
                   work / "figures", others)
    if info:
        print(f"dataset {info['rows']} rows in {info['dataset_s']:.0f} s, sample {info['sample_s']:.1f} s, "
              f"training of members {info['trained_members']}: {[round(x) for x in info['training_s']]} s "
              f"({info['epochs']} epochs, {info['train_rows']} rows)")
    print(f"{solver}: YADE start-up (first request of a fresh solver) {startup:.2f} s")
    print(f"{'path':<10}{'ntheta':>7}{'axial%':>7}{'p0 kPa':>8}{'rows':>6}{'peak q kPa':>11}{'ANN max dq %':>13}"
          f"{'rms dq %':>10}{'CF max dq %':>12}{'DEM s':>8}{'ANN s':>9}{'DEM/ANN':>9}  status")
    for r in rows:
        print(f"{r['path']:<10}{r['n_theta']:>7}{r['axial_pct']:>7.1f}{r['p0_kPa']:>8.0f}{r['rows']:>6}{r['dem_peak_q_kPa']:>11.1f}"
              f"{r['ann_q_max_dev_pct_of_peak']:>13.3f}{r['ann_q_rms_dev_pct_of_peak']:>10.3f}"
              f"{r['closed_form_q_max_dev_pct_of_peak']:>12.3f}{r['seconds_dem']:>8.2f}"
              f"{r['seconds_ann']:>9.4f}{r['dem_over_ann']:>9.0f}  {r['status']}"
              + (f"  ({', '.join(f'{k}: {x:.2f}' for k, x in r['others_q_max_dev_pct_of_peak'].items())})"
                 if r["others_q_max_dev_pct_of_peak"] else ""))
    members_info = [{"file": str(p), "architecture": f"{m.architecture.width}x{m.architecture.depth}",
                     "seed": (m.meta.get("config") or m.meta.get("distilled", {}).get("config", {})).get("seed"),
                     "distilled": "distilled" in m.meta, "epochs": m.meta.get("epochs_run"),
                     "training_s": m.meta.get("seconds"), "best_val_loss": m.meta.get("best_val_loss")}
                    for p, m in zip(model_files, models)]
    for r in members_info:
        print(f"{'student' if r['distilled'] else 'member'} {r['architecture']} seed {r['seed']}: {r['epochs']} "
              f"epochs in {r['training_s']:.0f} s, validation loss {r['best_val_loss']:.3g}")
    out.write_text(json.dumps({**provenance(__file__, args),
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count()},
        "mesostructure": args.mesostructure, "solver": solver, "datasets": [s.to_dict() for s in specs],
        "training": config.__dict__, "build": info, "student": student_info, "members": members_info, "axial_strains": args.axial, "step": args.step,
        "iso_step": args.iso_step, "yade_startup_s": startup, "rows": rows}, indent=1, default=str))
    print(f"wrote {out}; figures in {work / 'figures'}")


if __name__ == "__main__":
    main()
