"""The learned 3D cell against the closed form: the 3D REV on the triaxial paths (issue 34).

The learned 3D cell is the bi-hexagon whose two hexagons the shipped 2D surrogate of the
closed-form H-cell steps (``BiHexSolver(hexagon=SurrogateSolver)``; exact by the closure's
decoupling, docs/model3d.md "The learned 3D cell"); it runs on the generic loading driver.
Paths, as ``hmodel compare`` does in 2D: drained triaxial compression at 100, 200 and 400 kPa,
undrained compression, drained extension and the true triaxial test at b = 0.5 (constant p),
all at 200 kPa but the first three, to ``--axial-strain``, with the shipped model's material
(the ``sliding_rhs`` the model was trained with: it refuses another). With the default model
(the report's λ) every path ends where the mixed-control Newton fails at a cell event
(``drop_failed``; docs/model3d.md says why), near 1 % axial strain; with ``--model
equilibrium`` (the 3D commands' learned cell) they run to ``--axial-strain``. Rows are matched stage by stage as in 2D (``hmodel.compare.deviations``)
up to the shorter run. Times: best of ``--repeat`` after one warm-up run, the closed form
compiled and on the generic driver, the learned cell (generic) with a fresh solver each run.

Usage: ``python -m benchmarks.surrogates.ann_rev3d [--order 23 --azimuths 6] [--repeat 1]``;
prints a table, writes ``ann_rev3d.json``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from benchmarks.timing import best_of, record
from hmodel import Params
from hmodel.compare import deviations
from hmodel.loading.lab_tests import run_triaxial, run_true_triaxial
from hmodel.rev.sphere import Sphere
from hmodel.surrogate.solver import SurrogateSolver, load_solver

PATHS = (("drained", (100e3, 200e3, 400e3), {}), ("undrained", (200e3,), {"undrained": True}),
         ("extension", (200e3,), {"extension": True}), ("true triaxial b=0.5", (200e3,), {"b": 0.5}))


def run(name, p0, kw, solver, sphere, axial, params, compiled=None):
    common = dict(sphere=sphere, solver=solver, drop_failed=True, compiled=compiled)
    if "b" in kw:
        return run_true_triaxial(params, list(p0), kw["b"], axial, **common)
    return run_triaxial(params, list(p0), axial, **kw, **common)


def ended(res, b: int) -> tuple[float, str]:
    """Axial strain of the last shear row of point b and why the run ended there."""
    r = res.point(b)
    eps = np.asarray(r["eps11"])[np.asarray(r["stage"]) == "shear"]
    why = res.meta.get("failed", {}).get(b)
    return float(abs(eps[-1] - eps[0]) if len(eps) else 0.0), ("Newton: " + why[:60]) if why else "end"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--order", type=int, default=23)
    ap.add_argument("--azimuths", type=int, default=6)
    ap.add_argument("--axial-strain", type=float, default=0.1)
    ap.add_argument("--model", default="default", help="shipped model or model file of the hexagons")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("ann_rev3d.json"))
    args = ap.parse_args()
    sphere = Sphere(order=args.order, n_azimuth=args.azimuths)
    learned = load_solver(f"surrogate:{args.model}")
    # the material the model was trained for (its sliding_rhs: the report's for the default)
    params = Params(sliding_rhs=(learned.formulation.to_dict().get("params") or {}).get("sliding_rhs", "report"))
    rows, results = [], []
    for name, p0, kw in PATHS:
        ref = run(name, p0, kw, None, sphere, args.axial_strain, params)
        solver = SurrogateSolver(learned.members)
        res = run(name, p0, kw, solver, sphere, args.axial_strain, params)
        t_cf = best_of(lambda: run(name, p0, kw, None, sphere, args.axial_strain, params), args.repeat)
        t_gen = best_of(lambda: run(name, p0, kw, None, sphere, args.axial_strain, params, compiled=False),
                        args.repeat)
        t_ann = best_of(lambda: run(name, p0, kw, SurrogateSolver(learned.members), sphere, args.axial_strain,
                                    params), args.repeat)
        for d in deviations(ref, res):
            b = d["point"]
            e_ref, why_ref = ended(ref, b)
            e_ann, why_ann = ended(res, b)
            row = {"path": name, "p0_kPa": p0[b] / 1e3, "rows_compared": d["rows"],
                   "peak_q_kPa": d["peak_q"] / 1e3,
                   "q_max_dev_pct_of_peak": 100 * d["q_max_dev_rel"],
                   "q_rms_dev_pct_of_peak": 100 * d["q_rms_dev_rel"],
                   "eps_v_max_dev": d["eps_v_max_dev"], "eps_v_rms_dev": d["eps_v_rms_dev"],
                   "axial_strain_reached_closed_form": e_ref, "axial_strain_reached_learned": e_ann,
                   "ended_closed_form": why_ref, "ended_learned": why_ann,
                   "seconds_closed_form_compiled": t_cf, "seconds_closed_form_generic": t_gen,
                   "seconds_learned_generic": t_ann,
                   "points_in_run": len(p0),
                   "learned_cell_updates": solver.counts["cell_updates"],
                   "learned_fallback_cells": solver.counts["fallback_cells"],
                   "learned_outside": solver.counts["outside"]}
            results.append(row)
            rows.append((f"{name} {p0[b] / 1e3:.0f} kPa: max |dq|/peak q [%]", row["q_max_dev_pct_of_peak"], "-"))
    print(f"{'path':<21}{'p0':>5}{'to eps11 % (cf/ANN)':>21}{'max dq %':>10}{'rms dq %':>10}{'max d eps_v':>12}"
          f"{'rms d eps_v':>12}{'cf comp s':>10}{'cf gen s':>9}{'ANN s':>7}{'fallbacks':>10}")
    for r in results:
        reached = f"{100 * r['axial_strain_reached_closed_form']:.2f}/{100 * r['axial_strain_reached_learned']:.2f}"
        print(f"{r['path']:<21}{r['p0_kPa']:>5.0f}{reached:>21}{r['q_max_dev_pct_of_peak']:>10.4f}"
              f"{r['q_rms_dev_pct_of_peak']:>10.4f}{r['eps_v_max_dev']:>12.2e}{r['eps_v_rms_dev']:>12.2e}"
              f"{r['seconds_closed_form_compiled']:>10.3f}{r['seconds_closed_form_generic']:>9.3f}"
              f"{r['seconds_learned_generic']:>7.3f}{r['learned_fallback_cells']:>10d}")
    rec = record(__file__, args, args.repeat, rows, sphere={"order": sphere.order, "n_azimuth": sphere.n_azimuth},
                 paths=results)
    import json
    args.out.write_text(json.dumps(rec, indent=1) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
