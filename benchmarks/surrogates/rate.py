"""Rate independence of the cell solvers: does a response depend on how a strain is cut into
REV increments?

For each solver, drained biaxial tests at 100, 200 and 400 kPa and an undrained one at 200 kPa
(nθ = 360, to 3 % axial strain after consolidation in increments of 10⁻⁴) run at REV increments
2.5·10⁻⁴, 5·10⁻⁴, 10⁻³ and 2·10⁻³. Each curve q(ε11 − ε11 at the end of consolidation) is
interpolated onto the states of the coarsest run; the measure is the largest |Δq| between any two
increments, over the tests, divided by the test's peak q. The closed form is the reference: its
own figure is the part that comes from the H-model itself (events of cells inside an increment).

Usage: ``python -m benchmarks.surrogates.rate [--solvers closed-form,surrogate,surrogate:increment]``;
prints a table, writes ``rate.json``.
"""

from __future__ import annotations

import argparse
import itertools
from pathlib import Path

import numpy as np

from benchmarks.timing import record, write_table
from hmodel import Params, SolverError
from hmodel.loading import run_biaxial
from hmodel.solvers import get_solver

STEPS = (2.5e-4, 5e-4, 1e-3, 2e-3)
TESTS = (("drained", (1e5, 2e5, 4e5)), ("undrained", (2e5,)))


def curves(solver: str, undrained: bool, p0, step: float, strain: float) -> list[tuple]:
    """(axial strain since consolidation, q) of every point of one batched run."""
    res = run_biaxial(Params(), list(p0), strain, undrained=undrained, solver=get_solver(solver),
                      step=step, iso_step=1e-4)
    out = []
    for b in range(len(p0)):
        mine = res["point"] == b
        cons = np.flatnonzero(mine & (res["stage"] == "consolidation"))[-1]
        shear = mine & (res["stage"] == "shear")
        out.append((res["eps11"][shear] - res["eps11"][cons], res["q"][shear]))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--solvers", default="closed-form,surrogate,surrogate:increment")
    ap.add_argument("--strain", type=float, default=0.03)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("rate.json"))
    args = ap.parse_args()
    rows = []
    for solver in args.solvers.split(","):
        for kind, p0 in TESTS:
            try:
                runs = {s: curves(solver, kind == "undrained", p0, s, args.strain) for s in STEPS}
            except SolverError as e:
                print(f"{solver} {kind}: failed: {' '.join(str(e).split())[:160]}")
                rows.append((f"{solver}, {kind} {'/'.join(f'{p / 1e3:g}' for p in p0)} kPa: failed", float("nan"), "<= 2 %"))
                continue
            worst = 0.0
            for b in range(len(p0)):
                grid = runs[STEPS[-1]][b][0]
                q = {s: np.interp(grid, *runs[s][b]) for s in STEPS}
                peak = max(np.max(np.abs(runs[s][b][1])) for s in STEPS)
                for a, c in itertools.combinations(STEPS, 2):
                    worst = max(worst, float(np.max(np.abs(q[a] - q[c]))) / peak)
            rows.append((f"{solver}, {kind} {'/'.join(f'{p / 1e3:g}' for p in p0)} kPa: "
                         f"max |dq| / peak q between increments [%]", 100 * worst, "<= 2 %"))
    write_table(rows, args.out, record(__file__, args, 1, rows, steps=list(STEPS), strain=args.strain))


if __name__ == "__main__":
    main()
