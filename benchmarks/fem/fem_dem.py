"""FEM x DEM cells against FEM x learned DEM cells: the plane-strain biaxial test on a 1x2 Q4
mesh (8 Gauss points; ``--mesh``), drained at 200 kPa to 1 % axial strain in 10 load steps,
``sliding_rhs=equilibrium`` (the closure a DEM cell obeys), with every cell increment solved by
YADE (``--dem``), with the surrogate that learned those cells (``--learned``) and with the closed
form of the H-cell (a third reference: exact for the standard cell only). Wall times, their
ratios, q of each run, the cell increments each solver was asked for (every Newton trial and
tangent probe of every cell) and the seconds per cell increment, and an overlay figure
(``--figure``).

Each run is recorded as soon as it ends; ``--reuse`` keeps the runs of an earlier JSON with the
same settings (the DEM run is the long one).

Usage: ``python -m benchmarks.fem.fem_dem [--dem dem:hexagon-center:tol=1e-7,max_iter=100000]
[--learned surrogate:hexagon-center] [--n-theta 12] [--mesh 1x2] [--reuse] [--out PATH] [--figure PNG]``;
prints a table, writes ``fem_dem.json``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from benchmarks.timing import FIGURES, record
from hmodel import Params
from hmodel.fem import biaxial
from hmodel.solvers import get_solver


def count_cells(solver) -> list[int]:
    """Count the cells of every increment the solver is asked for (a one-item list, updated)."""
    n, step = [0], solver.step

    def counted(params, state, dl1, dl2):
        n[0] += int(np.prod(state.values.shape[:-1]))
        return step(params, state, dl1, dl2)
    solver.step = counted
    return n


def overlay(runs: dict, path: Path, title: str) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 3.6), layout="constrained")
    a, b = fig.subplots(1, 2)
    for name, r in runs.items():
        e = 100 * np.asarray(r["eps11"])
        a.plot(e, np.asarray(r["q"]) / 1e3, marker=".", label=f"{name} ({r['seconds']:.3g} s)")
        b.plot(e, 100 * np.asarray(r["eps_v"]), marker=".", label=name)
    a.set(xlabel="axial strain [%]", ylabel="q [kPa]", title=title)
    b.set(xlabel="axial strain [%]", ylabel="volumetric strain [%] (compression +)")
    a.legend(fontsize=8)
    fig.savefig(path, dpi=120)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dem", default="dem:hexagon-center:tol=1e-7,max_iter=100000")
    ap.add_argument("--learned", default="surrogate:hexagon-center")
    ap.add_argument("--n-theta", type=int, default=12)
    ap.add_argument("--mesh", default="1x2", help="elements NXxNY")
    ap.add_argument("--reuse", action="store_true", help="keep the runs of --out with the same settings")
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("fem_dem.json"))
    ap.add_argument("--figure", type=Path, default=FIGURES / "fem-dem.png")
    args = ap.parse_args()
    params = Params(n_theta=args.n_theta, sliding_rhs="equilibrium")
    mesh = tuple(int(x) for x in args.mesh.split("x"))
    settings = {"dem": args.dem, "learned": args.learned, "n_theta": args.n_theta, "mesh": args.mesh}
    label = f"FEM {args.mesh} Q4, {4 * mesh[0] * mesh[1]} Gauss points, ntheta={args.n_theta}, 1 % in 10 steps"
    runs: dict[str, dict] = {}
    if args.reuse and args.out.is_file():
        old = json.loads(args.out.read_text())
        if old.get("settings") == settings:
            runs = old.get("runs", {})

    def write() -> None:
        rows = [(f"{label}, {k} [s]", r["seconds"], "")
                for k, r in runs.items()]
        if args.dem in runs and args.learned in runs:
            rows.append(("DEM / learned time ratio", runs[args.dem]["seconds"] / runs[args.learned]["seconds"],
                         ">= 1000"))
            d, s = runs[args.dem], runs[args.learned]
            n = min(len(d["q"]), len(s["q"]))
            if np.allclose(d["eps11"][:n], s["eps11"][:n]):
                rows.append(("learned vs DEM: max |dq| / DEM peak q [%]",
                             100 * float(np.max(np.abs(np.subtract(d["q"][:n], s["q"][:n]))) / np.max(d["q"])), ""))
        if args.dem in runs and "closed-form" in runs:
            rows.append(("DEM / closed form time ratio", runs[args.dem]["seconds"] / runs["closed-form"]["seconds"], ""))
        args.out.write_text(json.dumps(record(__file__, args, 1, rows, settings=settings, runs=runs), indent=1) + "\n")
        for r in rows:
            print(f"{r[0]:<80} {r[1]:.4g}")

    for spec in ("closed-form", args.dem, args.learned):  # the DEM run is kept if the learned one fails
        if spec in runs:
            continue
        solver = get_solver(spec)
        cells = count_cells(solver)
        t = time.perf_counter()
        res = biaxial(params, 2e5, 0.01, mesh=mesh, n_steps=10, solver=solver, reference=False)
        runs[spec] = {"seconds": time.perf_counter() - t, "stopped": res.stopped, "cell_increments": cells[0],
                      "seconds_per_cell_increment": (time.perf_counter() - t) / max(cells[0], 1),
                      **{c: res.column(c).tolist() for c in ("eps11", "q", "eps_v", "newton_iterations")}}
        print(spec, f"{runs[spec]['seconds']:.3g} s", res.stopped, np.round(res.column("q") / 1e3, 2))
        write()
    overlay(runs, args.figure, f"FEM {args.mesh} Q4, n_theta = {args.n_theta}, drained 200 kPa")
    print(f"wrote {args.out} and {args.figure}")


if __name__ == "__main__":
    main()
