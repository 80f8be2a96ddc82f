"""The standard cell's family network against the closed form at materials it was not trained on (issue 36).

The family network (``surrogate:family``, ``h-cell-family.safetensors``) is the default
network's recipe (formulation ``compliance``) with the material as inputs (kt/kn and tan φg
after the cell state; kn and r scaled out), trained on closed-form rows whose material was drawn
per path over kt/kn 0.2–1, φg 10–45°, α0 35–75°. Here it runs the REV (the compiled loading
path) at parameter sets drawn uniformly over that domain with ``--seed`` (a path's material in
the training data is a continuous draw: no set below is one of them), drained biaxial tests at
100 and 300 kPa (one batched run) and an undrained one at 200 kPa, to ``--axial-strain``, against
the closed form on the same increments: max and RMS |Δq| / peak q, max |Δεv| (rows matched
stage by stage, :func:`hmodel.compare.deviations`).

Speed: the drained test at the default material (inside the domain) with the single-material
default network and with the family network, same increments, nθ = ``--n-theta``: best of
``--repeat`` wall and CPU times after a warm-up, and their ratio (the cost per cell increment
when both take the same increments and Newton iterations, which the table checks: cell
updates). Run the timing alone (``flock /tmp/cpu.lock``).

Usage: ``python -m benchmarks.surrogates.family [--sets 4 --seed 36] [--repeat 3]``; prints
the tables, writes ``family.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from benchmarks.timing import record
from hmodel import Params
from hmodel.compare import deviations
from hmodel.loading import run_biaxial
from hmodel.surrogate.solver import SurrogateSolver, load_solver

DRAINED = (100e3, 300e3)
UNDRAINED = 200e3


def draw_sets(domain: dict, n: int, seed: int, n_theta: int) -> list[Params]:
    """``n`` materials uniform over the model's domain (Params units), in draw order."""
    rng = np.random.default_rng(seed)
    keys = sorted(domain)
    out = []
    for _ in range(n):
        draw = {k: rng.uniform(*domain[k]) for k in keys}
        out.append(Params(n_theta=n_theta, **draw))
    return out


def timed(fn, repeat: int) -> tuple[float, float]:
    """Best wall and CPU time of ``repeat`` calls after one warm-up call."""
    fn()
    walls, cpus = [], []
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        fn()
        walls.append(time.perf_counter() - w)
        cpus.append(time.process_time() - c)
    return min(walls), min(cpus)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default="family", help="family model (shipped name or file)")
    ap.add_argument("--single", default="default", help="the single-material network timed beside it")
    ap.add_argument("--sets", type=int, default=4)
    ap.add_argument("--seed", type=int, default=36)
    ap.add_argument("--n-theta", type=int, default=72)
    ap.add_argument("--axial-strain", type=float, default=0.05)
    ap.add_argument("--step", type=float, default=5e-4)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("family.json"))
    args = ap.parse_args()
    family = load_solver(f"surrogate:{args.model}")
    trained = family.model.meta["params"]
    sets = draw_sets(family.domain, args.sets, args.seed, args.n_theta)
    sets = [s.with_(sliding_rhs=trained["sliding_rhs"]) for s in sets]
    results, rows = [], []
    for k, p in enumerate(sets):
        for name, p0, undrained in (("drained", list(DRAINED), False), ("undrained", [UNDRAINED], True)):
            kw = {"undrained": undrained, "step": args.step, "drop_failed": True}
            ref = run_biaxial(p, p0, args.axial_strain, **kw)
            solver = SurrogateSolver(family.members)
            ann = run_biaxial(p, p0, args.axial_strain, solver=solver, **kw)
            for d in deviations(ref, ann):
                b = d["point"]
                # up to the closed form's peak of q (shear rows matched by index, as deviations)
                qa = np.asarray(ref.point(b)["q"])[np.asarray(ref.point(b)["stage"]) == "shear"]
                qc = np.asarray(ann.point(b)["q"])[np.asarray(ann.point(b)["stage"]) == "shear"]
                top = int(np.argmax(qa)) + 1
                pre = float(np.abs(qc[:top] - qa[:top]).max()) / d["peak_q"] if len(qc) >= top else float("nan")
                row = {"set": k, "kt_kn": p.kt_kn, "phi_g_deg": math.degrees(p.phi_g),
                       "alpha0_deg": p.alpha0_deg, "path": name, "p0_kPa": p0[b] / 1e3,
                       "rows_compared": d["rows"], "peak_q_kPa": d["peak_q"] / 1e3,
                       "q_max_dev_pct_of_peak": 100 * d["q_max_dev_rel"],
                       "q_rms_dev_pct_of_peak": 100 * d["q_rms_dev_rel"],
                       "q_max_dev_to_peak_pct_of_peak": 100 * pre,
                       "eps_v_max_dev": d["eps_v_max_dev"],
                       "closed_form_failed": bool(ref.meta.get("failed", {}).get(b)),
                       "ann_failed": bool(ann.meta.get("failed", {}).get(b)),
                       "outside_cells": solver.counts["outside"]}
                results.append(row)
    print(f"{'set':>3}{'kt/kn':>7}{'phi_g':>7}{'alpha0':>7}{'path':>10}{'p0':>6}{'rows':>6}{'peak q':>9}"
          f"{'max dq %':>10}{'to peak':>9}{'rms dq %':>10}{'max d eps_v':>12}{'outside':>9}")
    for r in results:
        print(f"{r['set']:>3}{r['kt_kn']:>7.3f}{r['phi_g_deg']:>7.2f}{r['alpha0_deg']:>7.2f}{r['path']:>10}"
              f"{r['p0_kPa']:>6.0f}{r['rows_compared']:>6}{r['peak_q_kPa']:>9.1f}{r['q_max_dev_pct_of_peak']:>10.4f}"
              f"{r['q_max_dev_to_peak_pct_of_peak']:>9.4f}"
              f"{r['q_rms_dev_pct_of_peak']:>10.4f}{r['eps_v_max_dev']:>12.2e}{r['outside_cells']:>9}")
    worst = max(r["q_max_dev_pct_of_peak"] for r in results)
    rows.append(("worst max |dq| / peak q over the unseen sets [%]", worst, "<= 1"))
    rows.append(("the same up to the closed form's peak [%]",
                 max(r["q_max_dev_to_peak_pct_of_peak"] for r in results), "<= 1"))

    # speed: the default material, same path, the single-material network and the family one
    p = Params(n_theta=args.n_theta, sliding_rhs=trained["sliding_rhs"])
    single = load_solver(f"surrogate:{args.single}")
    speed = {}
    for label, members in (("single", single.members), ("family", family.members)):
        counter = {}

        def go(members=members, counter=counter):
            s = SurrogateSolver(members)
            res = run_biaxial(p, list(DRAINED), args.axial_strain, solver=s, step=args.step)
            counter["increments"] = len(res["q"])
            return res

        wall, cpu = timed(go, args.repeat)
        speed[label] = {"seconds": wall, "cpu_seconds": cpu, "rows": counter["increments"]}
    ratio = speed["family"]["seconds"] / speed["single"]["seconds"]
    ratio_cpu = speed["family"]["cpu_seconds"] / speed["single"]["cpu_seconds"]
    print(f"speed, drained {DRAINED[0] / 1e3:.0f}+{DRAINED[1] / 1e3:.0f} kPa to {args.axial_strain:g}, "
          f"ntheta {args.n_theta}: single {speed['single']['seconds']:.3f} s "
          f"({speed['single']['cpu_seconds']:.3f} CPU), family {speed['family']['seconds']:.3f} s "
          f"({speed['family']['cpu_seconds']:.3f} CPU): x{ratio:.2f} (CPU x{ratio_cpu:.2f})")
    rows.append(("family / single-material network, REV time per run (same increments) [x]", ratio, "<= 2"))
    rows.append(("the same in CPU time [x]", ratio_cpu, "<= 2"))
    rec = record(__file__, args, args.repeat, rows, domain=family.model.meta["domain"],
                 material_inputs=list(family.formulation.material_inputs),
                 sets=[{"kt_kn": s.kt_kn, "phi_g_deg": math.degrees(s.phi_g), "alpha0_deg": s.alpha0_deg}
                       for s in sets], paths=results, speed=speed)
    args.out.write_text(json.dumps(rec, indent=1) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
