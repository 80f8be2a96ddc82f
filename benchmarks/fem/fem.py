"""FEM speed: plane-strain biaxial test, 8x16 Q4 elements (512 Gauss points), drained at
200 kPa, nθ = 360, to 5 % axial strain in 100 load steps, with the closed form and with the
shipped surrogate (``--solver surrogate``), each run once (a run is minutes, not milliseconds).

Also recorded: the cell increments the solver was asked for (every trial and tangent probe of
every cell) and the seconds per cell increment, load steps taken (with cuts), Newton iterations, the largest deviation of q from
the material-point test with the same increments up to its peak (relative to peak q), and the
median convergence rate of the residual (log r_{k+1} / log r_k).

The richer-cell surrogate runs with the closure its DEM cells follow:
``python -m benchmarks.fem.fem --solvers surrogate:hexagon-center -p sliding_rhs=equilibrium``.

Usage: ``python -m benchmarks.fem.fem [--solvers closed-form,surrogate] [-p NAME=VALUE ...] [--out PATH]``;
prints a table, writes ``fem.json`` (or ``--out``).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from benchmarks.fem.fem_dem import count_cells
from benchmarks.timing import record, write_table
from hmodel import Params
from hmodel.fem import biaxial, material_point_curve
from hmodel.params import parse_point_assignments
from hmodel.solvers import get_solver

TARGETS = {"closed-form": "<= 120", "surrogate": "<= 300"}


def rate(residuals) -> float:
    r = [np.log(x[k + 1]) / np.log(x[k]) for x in residuals for k in range(len(x) - 1)
         if 1e-14 < x[k + 1] and x[k] < 1e-2]
    return float(np.median(r)) if r else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--solvers", default="closed-form,surrogate")
    ap.add_argument("-p", "--param", action="append", default=[], help="NAME=VALUE (Params field)")
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("fem.json"))
    args = ap.parse_args()
    params = parse_point_assignments(args.param, Params(n_theta=360))[0]
    rows, details = [], {}
    for spec in args.solvers.split(","):
        solver = get_solver(spec)
        cells = count_cells(solver)
        t = time.perf_counter()
        res = biaxial(params, 2e5, 0.05, mesh=(8, 16), n_steps=100, solver=solver,
                      reference=False)
        wall = time.perf_counter() - t
        n_cells = cells[0]  # the material-point reference below counts too
        rows.append((f"FEM biaxial 8x16 Q4, 512 Gauss points, ntheta=360, 100 steps, {spec} [s]", wall,
                     TARGETS.get(spec.split(":")[0], "")))
        from hmodel.loading import run_biaxial
        c = material_point_curve(run_biaxial(params, 2e5, 0.05, solver=solver, step=5e-4))
        n = min(len(res), len(c["q"]))
        same = np.allclose(res.column("eps11")[:n], c["eps11"][:n])
        upto = min(n, int(np.argmax(c["q"])) + 1)
        dev = float(np.max(np.abs(res.column("q")[:upto] - c["q"][:upto])) / c["q"].max()) if same else None
        details[spec] = {"steps": len(res) - 1, "newton_iterations": int(res.column("newton_iterations").sum()),
                         "stopped": res.stopped, "q_deviation_to_peak": dev,
                         "median_convergence_rate": rate(res.residuals), "cell_increments": n_cells,
                         "seconds_per_cell_increment": wall / max(n_cells, 1)}
        # written after each solver: a slow one that is stopped leaves the others' results
        write_table(rows, args.out, record(__file__, args, 1, rows, details=details, params=args.param))
    for k, v in details.items():
        print(k, v)


if __name__ == "__main__":
    main()
