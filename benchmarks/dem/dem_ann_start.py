"""Where the ANN-REV of the hexagon-center cell misses at low confinement: consolidation and the
first shear increments, and whether the REV increment changes it.

For the model of ``benchmarks/dem/dem_ann.py`` (one network, or an ensemble) against the DEM-REV, drained at 100 and 200 kPa
(nθ = 12): the rows of consolidation and of the first ``--axial`` of shear at increments of
``--step`` (volumetric strain and q of both), and the max |Δq| / peak q over 1 % paths at the REV
increments ``--steps`` (default 2·10⁻³, 10⁻³, 5·10⁻⁴ and 2.5·10⁻⁴); and whether the model's first shear increment is
linear in the strain, as an elastic one is (:func:`onset`).

Prints both tables, writes ``dem_ann_start.json``.
Usage: ``python -m benchmarks.dem.dem_ann_start [--model A+B+C|hexagon-center] [--steps 2e-3,1e-3,...]``.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks.timing import provenance
from hmodel import Params
from hmodel.compare import deviations, run_path, standard_paths
from hmodel.dem.solver import DEMSolver
from hmodel.surrogate.modelfile import load
from hmodel.surrogate.shipped import model_paths
from hmodel.surrogate.solver import SurrogateSolver

SOLVER = "dem:hexagon-center:tol=1e-7,max_iter=100000"
PARAMS = Params(sliding_rhs="equilibrium", n_theta=12)
P0 = (1e5, 2e5)


def both(models, axial: float, step: float):
    """DEM-REV and ANN-REV results of the drained path at ``step``."""
    spec = replace({s.name: s for s in standard_paths(axial)}["drained"], p0=P0)
    dem = DEMSolver(SOLVER)
    ref, _ = run_path(PARAMS, spec, dem, step, 2e-4)
    dem.yade().close()
    res, _ = run_path(PARAMS, spec, SurrogateSolver(models, on_outside="error"), step, 2e-4)
    return ref, res


def onset(models, step: float) -> list[dict]:
    """Is the model's first shear increment linear, as an elastic one is? For the consolidated
    ANN-REV cells under a first shear increment (axial ``step``, lateral extension step/2), the
    learned V sigma increments per unit strain summed over the cells, for 10^-3 of the
    increment (the tangent) and for the whole increment; they differ
    where a learned mechanism (an onset of sliding) is active within the increment."""
    from hmodel.cell import CellState
    from hmodel.loading.named_paths import consolidate
    from hmodel.rev.rev import Rev

    rev = Rev(PARAMS, SurrogateSolver(models, on_outside="error"))
    f = models[0].formulation
    out = []
    for p0 in P0:
        v = consolidate(rev, [p0], step=2e-4).cells.values[0]
        dl = rev.localize(CellState(v[None]), np.array([[step, -step / 2, 0.0]]))[0]
        e1, e2 = -dl[:, 0] / PARAMS.l10, -dl[:, 1] / PARAMS.l20
        X = f.features(v)
        row = {"p0_kPa": p0 / 1e3}
        for key, s in (("tangent", 1e-3), ("whole_step", 1.0)):
            dz = np.mean([f.increment(m.forward(X, single=True), s * e1, s * e2) for m in models], axis=0) / s
            row[f"sum_dVs_nn_{key}"], row[f"sum_dVs_tt_{key}"] = float(dz[:, 4].sum()), float(dz[:, 5].sum())
        out.append(row)
        print(f"{p0 / 1e3:g} kPa, first shear increment: sum of learned dVs_nn / e over the cells "
              f"{row['sum_dVs_nn_tangent']:.3f} (tangent) vs {row['sum_dVs_nn_whole_step']:.3f} (whole step); "
              f"dVs_tt {row['sum_dVs_tt_tangent']:.3f} vs {row['sum_dVs_tt_whole_step']:.3f}")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default="hexagon-center",
                    help="a shipped model's name or a model file, or an ensemble A+B+...")
    ap.add_argument("--steps", default="2e-3,1e-3,5e-4,2.5e-4", help="REV increments of the 1 %% paths")
    ap.add_argument("--step", type=float, default=2.5e-4)
    ap.add_argument("--axial", type=float, default=0.002)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("dem_ann_start.json"))
    args = ap.parse_args()
    models = [load(p) for p in model_paths(args.model)]
    ref, res = both(models, args.axial, args.step)
    rows = []
    print(f"{'p0 kPa':>7} {'stage':<14}{'eps11 %':>9}{'eps_v DEM %':>12}{'eps_v ANN %':>12}{'q DEM kPa':>11}{'q ANN kPa':>11}")
    for b, p0 in enumerate(P0):
        r, a = ref.point(b), res.point(b)
        if len(r) != len(a):
            raise SystemExit(f"p0 {p0:g}: the REVs have {len(r)} and {len(a)} rows")
        for k in range(len(r)):
            row = {"p0_kPa": p0 / 1e3, "stage": str(np.asarray(r["stage"])[k]),
                   "eps11_pct": 100 * float(np.asarray(r["eps11"])[k]),
                   "eps_v_dem_pct": 100 * float(np.asarray(r["eps_v"])[k]),
                   "eps_v_ann_pct": 100 * float(np.asarray(a["eps_v"])[k]),
                   "q_dem_kPa": float(np.asarray(r["q"])[k]) / 1e3, "q_ann_kPa": float(np.asarray(a["q"])[k]) / 1e3}
            rows.append(row)
            print(f"{row['p0_kPa']:>7.0f} {row['stage']:<14}{row['eps11_pct']:>9.4f}{row['eps_v_dem_pct']:>12.4f}"
                  f"{row['eps_v_ann_pct']:>12.4f}{row['q_dem_kPa']:>11.2f}{row['q_ann_kPa']:>11.2f}")
    kinks = onset(models, args.step)
    steps = []
    for step in (float(x) for x in args.steps.split(",")):
        dev = deviations(*both(models, 0.01, step))
        steps.append({"step": step, **{f"q_max_dev_pct_of_peak_{p0 / 1e3:g}kPa": 100 * d["q_max_dev_rel"]
                                       for p0, d in zip(P0, dev)}})
        print(f"REV increment {step:g}, to 1 % axial: max |dq| / peak q " + ", ".join(
            f"{p0 / 1e3:g} kPa {100 * d['q_max_dev_rel']:.2f} %" for p0, d in zip(P0, dev)))
    args.out.write_text(json.dumps({**provenance(__file__, args), "model": args.model, "solver": SOLVER, "n_theta": PARAMS.n_theta,
                                    "step": args.step, "rows": rows, "first_step_linearity": kinks,
                                    "step_sensitivity": steps}, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
