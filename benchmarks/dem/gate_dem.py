"""The richer cell's gated ANN-REV against the DEM-REV: accuracy against DEM calls.

``--solver surrogate:MODEL --fallback dem:hexagon-center --gate G`` (:mod:`hmodel.surrogate.shadow`:
each cell carries its DEM state as of its last DEM increment; a gated cell catches up with the
strain the network took it through, then takes the increment in DEM). For each gate level, on
the compared paths of ``benchmarks/dem/dem_ann.py`` (drained 100 and 200 kPa, undrained 200 kPa,
nθ = 12 and 36, to ``--axial``, REV increments of ``--step``): max |Δq| / peak q against the
DEM-REV, the share of cell states (or, for an ensemble's gate, of cell increments, Newton trials
included) sent to the DEM, and the DEM cell increments the gated run asked of YADE (Newton trials
and catch-up sub-steps included) over those of the DEM-REV on the same path.

Prints a table, writes ``gate_dem.json``.
Usage: ``python -m benchmarks.dem.gate_dem [--model hexagon-center] [--gates 1,0.99,0.9,0.5]``.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks.timing import provenance
from hmodel import Params
from hmodel.compare import deviations, run_path, standard_paths
from hmodel.dem.solver import DEMSolver
from hmodel.surrogate.solver import gated_solver, load_solver

SOLVER = "dem:hexagon-center:tol=1e-7,max_iter=100000"
PARAMS = Params(sliding_rhs="equilibrium")


def counted(solver: DEMSolver) -> DEMSolver:
    """``solver`` counting the cell increments asked of it (``solver.cell_increments``)."""
    solver.cell_increments = 0
    step = solver.step

    def counting(params, state, dl1, dl2):
        solver.cell_increments += int(np.prod(state.shape))
        return step(params, state, dl1, dl2)

    solver.step = counting
    return solver


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default="hexagon-center", help="a shipped name, a file or A+B+...")
    ap.add_argument("--gates", default="1,0.99,0.9,0.5,0.25,0.1", help="1: ungated")
    ap.add_argument("--n-theta", default="12,36")
    ap.add_argument("--axial", type=float, default=0.03)
    ap.add_argument("--step", type=float, default=1e-3)
    ap.add_argument("--iso-step", type=float, default=2e-4)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("gate_dem.json"))
    args = ap.parse_args()
    gates = [float(g) for g in args.gates.split(",")]
    rows = []
    print(f"{'path':<10}{'nθ':>4}{'p0 kPa':>8}{'gate':>6}{'max |dq|/peak %':>17}{'gated %':>9}"
          f"{'DEM calls, % of DEM-REV':>25}{'ANN s':>8}{'DEM s':>8}")
    for n_theta in (int(n) for n in args.n_theta.split(",")):
        params = replace(PARAMS, n_theta=n_theta)
        paths = {s.name: s for s in standard_paths(args.axial)}
        for spec in (replace(paths["drained"], p0=(1e5, 2e5)), paths["undrained"]):
            dem = counted(DEMSolver(SOLVER))
            t = time.perf_counter()
            ref, _ = run_path(params, spec, dem, args.step, args.iso_step)
            t_dem = time.perf_counter() - t
            dem.yade().close()
            for gate in gates:
                fallback = counted(DEMSolver(SOLVER))
                solver = (load_solver(f"surrogate:{args.model}", on_outside="error") if gate >= 1
                          else gated_solver(f"surrogate:{args.model}", gate, fallback))
                t = time.perf_counter()
                res, _ = run_path(params, spec, solver, args.step, args.iso_step)
                t_ann = time.perf_counter() - t
                c = solver.counts
                for b, d in enumerate(deviations(ref, res)):
                    row = {"path": spec.name, "n_theta": n_theta, "p0_kPa": spec.p0[b] / 1e3, "gate": gate,
                           "q_max_dev_pct_of_peak": 100 * d["q_max_dev_rel"],
                           "q_rms_dev_pct_of_peak": 100 * d["q_rms_dev_rel"],
                           "eps_v_max_dev_pct": 100 * d["eps_v_max_dev"],
                           "gated_pct": 100 * c.get("gated", 0) / max(c.get("gate_checked", 0), 1),
                           "dem_cell_increments": fallback.cell_increments,
                           "dem_rev_cell_increments": dem.cell_increments,
                           "dem_share_pct": 100 * fallback.cell_increments / dem.cell_increments,
                           "seconds_ann": t_ann, "seconds_dem": t_dem}
                    rows.append(row)
                    print(f"{spec.name:<10}{n_theta:>4}{row['p0_kPa']:>8.0f}{gate:>6g}{row['q_max_dev_pct_of_peak']:>17.2f}"
                          f"{row['gated_pct']:>9.2f}{row['dem_share_pct']:>25.2f}{t_ann:>8.1f}{t_dem:>8.1f}",
                          flush=True)
                fallback.yade().close()
    args.out.write_text(json.dumps({**provenance(__file__, args), "model": args.model, "solver": SOLVER, "axial_pct": 100 * args.axial,
                                    "step": args.step, "rows": rows}, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
