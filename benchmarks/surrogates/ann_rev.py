"""The ANN-based H-model against the closed form: accuracy and wall time on every comparison path.

Runs ``hmodel.compare.standard_paths`` (isotropic, drained 100/200/400 kPa, undrained, and the
paths the report never tried: unloading-reloading, oedometric, rotating axes) to 10 % axial
strain at nθ = 360 with the closed form (compiled) and the shipped surrogate (formulation
``compliance``, pure: a cell outside the training domain stops the run), at increments of 1e-3
and 1e-4. Times are the best of N runs after a warm-up, at the same output resolution, each
surrogate run with a fresh solver (a solver keeps the network's outputs of the states it saw:
a repeated run would find them all there).

Usage: ``python -m benchmarks.surrogates.ann_rev [--repeat N] [--steps 1e-3,1e-4]``; prints a table, writes
``ann_rev.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
from pathlib import Path

from benchmarks.timing import best_of, provenance
from hmodel import Params
from hmodel.compare import deviations, run_path, standard_paths
from hmodel.surrogate.solver import SurrogateSolver, load_solver


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--steps", default="1e-3,1e-4")
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("ann_rev.json"))
    args = ap.parse_args()
    params = Params(n_theta=360)
    rows = []
    for step in (float(s) for s in args.steps.split(",")):
        for spec in standard_paths(0.1):
            solver = load_solver("surrogate", on_outside="error")
            ref, _ = run_path(params, spec, "closed-form", step, 1e-4)
            res, _ = run_path(params, spec, solver, step, 1e-4)
            t_cf = best_of(lambda: run_path(params, spec, "closed-form", step, 1e-4), args.repeat)
            # a fresh solver each timed run: the solver keeps the network's outputs of the
            # states it saw, and a repeated run would find every one of them there
            t_s = best_of(lambda: run_path(params, spec, SurrogateSolver(solver.members, "error"), step, 1e-4),
                          args.repeat)
            for d in deviations(ref, res):
                rows.append({"path": spec.name, "in_report": spec.in_report, "step": step,
                             "p0_kPa": spec.p0[d["point"]] / 1e3,
                             "q_max_dev_pct_of_peak": 100 * d["q_max_dev_rel"],
                             "q_rms_dev_pct_of_peak": 100 * d["q_rms_dev_rel"],
                             "eps_v_max_dev_pct_strain": 100 * d["eps_v_max_dev"],
                             "seconds_closed_form": t_cf, "seconds_surrogate": t_s,
                             "surrogate_over_closed_form": t_s / t_cf,
                             "outside_cells": solver.counts["outside"]})
    print(f"{'path':<14}{'step':>7}{'p0 kPa':>8}{'max dq %':>10}{'rms dq %':>10}{'max d eps_v %':>15}"
          f"{'closed s':>10}{'ANN s':>8}{'ratio':>7}")
    for r in rows:
        print(f"{r['path']:<14}{r['step']:>7.0e}{r['p0_kPa']:>8.0f}{r['q_max_dev_pct_of_peak']:>10.3f}"
              f"{r['q_rms_dev_pct_of_peak']:>10.3f}{r['eps_v_max_dev_pct_strain']:>15.5f}"
              f"{r['seconds_closed_form']:>10.3f}{r['seconds_surrogate']:>8.3f}{r['surrogate_over_closed_form']:>7.1f}")
    args.out.write_text(json.dumps({**provenance(__file__, args), "machine": {"platform": platform.platform(), "cpus": os.cpu_count()},
                                    "n_theta": 360, "rows": rows}, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
