"""FEM x DEM cells: the plane-strain biaxial test on a 1x2 Q4 mesh (8 Gauss points), drained at
200 kPa to 1 % axial strain in 10 load steps, nθ = 36, with DEM cells solved by YADE
(``dem:standard``) and with the closed form of the same cell (``sliding_rhs=equilibrium``, the
closure a DEM cell obeys); wall times, their ratio, and q of both.

No learned DEM cell ships with hmodel (the shipped surrogate learned the closed form), so the
fast side here is the closed form, which the DEM standard cell matches within 0.14-0.22 % at
the material point (docs/dem.md).

Usage: ``python benchmarks/fem_dem.py [--solver dem:standard]``; writes ``fem_dem.json``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from timing import record

from hmodel import Params
from hmodel.fem import biaxial
from hmodel.solvers import get_solver


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--solver", default="dem:standard")
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("fem_dem.json"))
    args = ap.parse_args()
    params = Params(n_theta=36, sliding_rhs="equilibrium")
    runs = {}
    for spec in ("closed-form", args.solver):
        t = time.perf_counter()
        res = biaxial(params, 2e5, 0.01, mesh=(1, 2), n_steps=10, solver=get_solver(spec), reference=False)
        runs[spec] = (time.perf_counter() - t, res)
        print(spec, runs[spec][0], res.stopped, np.round(res.column("q") / 1e3, 2))
    (tc, rc), (td, rd) = runs["closed-form"], runs[args.solver]
    n = min(len(rc), len(rd))
    same = np.allclose(rc.column("eps11")[:n], rd.column("eps11")[:n])
    rows = [("FEM 1x2 Q4, 8 Gauss points, ntheta=36, 1 % in 10 steps, closed form [s]", tc, ""),
            (f"same with {args.solver} [s]", td, ""), ("DEM / closed form time ratio", td / tc, "")]
    rec = record(__file__, 1, rows, eps11=rc.column("eps11")[:n].tolist(),
                 q_closed_form=rc.column("q")[:n].tolist(), q_dem=rd.column("q")[:n].tolist(),
                 max_q_difference_over_peak=(float(np.max(np.abs(rc.column("q")[:n] - rd.column("q")[:n]))
                                                   / rc.column("q").max()) if same else None),
                 stopped_dem=rd.stopped)
    args.out.write_text(json.dumps(rec, indent=2) + "\n")
    for r in rows:
        print(f"{r[0]:<80} {r[1]:.4g}")


if __name__ == "__main__":
    main()
