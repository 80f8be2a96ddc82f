"""Cost of a bi-hexagon increment with contacts between its hexagons (``cross_contacts``,
docs/mechanisms.md) against the published closure: ``BiHexSolver.step`` on S cells compressed
isotropically until their hexagons overlap, then one triaxial-like increment (d2 of A and B
apart, so the coupled update runs in every cell), linear and Hertz-Mindlin contacts; the best
of ``--repeat`` timings of each.

Usage: ``python -m benchmarks.model3d.cross_cost [--cells 200000] [--repeat 7] [--out PATH]``.
Prints a table and writes ``cross_cost.json`` beside this file; what ran beside it on the
machine is not controlled (say so where the figures are quoted).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from benchmarks.timing import record, write_table
from hmodel.cell import BiHexSolver
from hmodel.params import Params

HERE = Path(__file__).resolve().parent


def best(solver, params, state, dl, repeat):
    solver.step(params, state, *dl.T)  # compiles
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        solver.step(params, state, *dl.T)
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=200_000)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--out", type=Path, default=HERE / "cross_cost.json")
    args = ap.parse_args()
    solver = BiHexSolver()
    rows = []
    for contact in ("linear", "hertz-mindlin"):
        on = Params(sliding_rhs="equilibrium", contact=contact, cross_contacts="frictionless")
        off = on.with_(cross_contacts="none")
        s = solver.initial(on, (args.cells,))
        l0 = s.values[:, [6, 7, 15]]
        for _ in range(10):
            s, f = solver.step(on, s, *(-l0 * 3e-4).T)
        dl = -l0 * np.array([1e-4, -0.4e-4, -0.2e-4])
        t_off = best(solver, off, s, dl, args.repeat)
        t_on = best(solver, on, s, dl, args.repeat)
        touching = float(f.flags[:, -1].mean())
        rows += [(f"{contact}: step, published closure [ns per cell]", 1e9 * t_off / args.cells, "-"),
                 (f"{contact}: step, cross_contacts=frictionless [ns per cell]",
                  1e9 * t_on / args.cells, "-"),
                 (f"{contact}: ratio", t_on / t_off, "issue 54: <= 1.5 with every mechanism"),
                 (f"{contact}: fraction of cells whose hexagons touch", touching, "-")]
    write_table(rows, args.out, record(__file__, args, args.repeat, rows))


if __name__ == "__main__":
    main()
