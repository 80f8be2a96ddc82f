"""Convergence in directions of the 3D H-model (issue 34): the drained triaxial test at
200 kPa to 10 % axial strain against the Lebedev rule's order and the azimuths per direction,
written to ``convergence.json``.

Two controls of the same test, both by Newton in :func:`hmodel.loading.run_segment` (which
picks the compiled 3D path where there is one):

- ``held``: σ22 = σ33 = p0 each, ε11 in increments of 1e-4 (the laboratory's test): peak q
  (q = σ11 - (σ22 + σ33)/2) and peak q/p, and the largest |ε22 - ε33| (the rule's lateral
  asymmetry shows in the strains);
- ``equal``: (σ22 + σ33)/2 = p0 with ε22 = ε33 (the strain-driven loop of docs/model3d.md):
  the largest |σ22 - σ33|/p0 along the path, the asymmetry the exact (continuous) average
  would not have.

Usage: ``python -m benchmarks.model3d.convergence [--orders 9,17,...] [--azimuths 2,4,...]
[--sliding-rhs equilibrium] [--out PATH]``; the wall time of each run (consolidation and
shear, one run, no warm-up other than the first rule's) is reported beside it.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from benchmarks.timing import FIGURES, record
from hmodel import Params
from hmodel.loading import Recorder, Segment, consolidate, run_segment
from hmodel.loading.compiled import supports
from hmodel.rev import Rev3D, Sphere
from hmodel.rev.sphere import DEFAULT_AZIMUTHS, DEFAULT_ORDER, OFFERED

P0 = 200e3
STRAIN = 0.1
STEPS = 1000


def held_segment() -> Segment:
    return Segment((False, True, True, False, False, False), np.eye(6),
                   np.array([STRAIN, P0, P0, 0.0, 0.0, 0.0]), STEPS, "shear")


def equal_segment() -> Segment:
    M = np.eye(6)
    M[1, :3] = (0.0, 0.5, 0.5)
    M[2, :3] = (0.0, 1.0, -1.0)
    return Segment((False, True, False, False, False, False), M,
                   np.array([STRAIN, P0, 0.0, 0.0, 0.0, 0.0]), STEPS, "shear")


def triaxial(rev: Rev3D, seg: Segment) -> tuple[dict, float]:
    t = time.perf_counter()
    state = consolidate(rev, P0)
    rec = Recorder()
    run_segment(rev, state, seg, rec)
    wall = time.perf_counter() - t
    return rec.result().columns, wall


def one_rule(params: Params, order: int, m: int) -> dict:
    rev = Rev3D(params, Sphere(order=order, n_azimuth=m))
    held, wall = triaxial(rev, held_segment())
    equal, wall_eq = triaxial(rev, equal_segment())
    q = held["q"]
    k = int(np.argmax(q))
    return {"order": order, "n_azimuth": m, "cells": rev.n_cells,
            "peak_q": float(q[k]), "peak_q_p": float(np.max(held["q"] / held["p"])),
            "axial_strain_at_peak": float(held["eps11"][k]),
            "eps_v_end": float(held["eps_v"][-1]),
            "max_lateral_strain_asymmetry": float(np.max(np.abs(held["eps22"] - held["eps33"]))),
            "max_lateral_stress_asymmetry": float(np.max(np.abs(equal["sig22"] - equal["sig33"])) / P0),
            "peak_q_equal_strains": float(np.max(equal["q"])),
            "wall_s": wall, "wall_equal_s": wall_eq, "compiled": bool(supports(rev))}


def figure(table: list[dict], out: Path) -> None:
    """Peak q against the bi-hexagons per point, and the lateral asymmetry, for each m."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    ref = max(table, key=lambda r: r["cells"])["peak_q"]
    for m in sorted({r["n_azimuth"] for r in table}):
        rows = sorted((r for r in table if r["n_azimuth"] == m), key=lambda r: r["cells"])
        cells = [r["cells"] for r in rows]
        ax[0].semilogx(cells, [r["peak_q"] / 1e3 for r in rows], "o-", ms=3, label=f"m = {m}")
        ax[1].loglog(cells, [r["max_lateral_stress_asymmetry"] for r in rows], "o-", ms=3, label=f"m = {m}")
        for r in rows:
            if m == DEFAULT_AZIMUTHS:
                ax[0].annotate(str(r["order"]), (r["cells"], r["peak_q"] / 1e3), fontsize=7,
                               textcoords="offset points", xytext=(2, 4))
    ax[0].axhspan(ref * (1 - 1e-3) / 1e3, ref * (1 + 1e-3) / 1e3, color="0.9", label="finest ± 1e-3")
    ax[0].set(xlabel="bi-hexagons per material point", ylabel="peak q [kPa]",
              title="drained triaxial 200 kPa: peak q (labels: Lebedev order)")
    ax[1].set(xlabel="bi-hexagons per material point", ylabel="max |σ22 − σ33| / p0",
              title="lateral asymmetry (ε22 = ε33, mean lateral stress held)")
    ax[1].set_ylim(1e-4, 0.3)  # (order 9 with m = 6 is symmetric to round-off: off the axis)
    for a in ax:
        a.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--orders", default="9,17,23,29,35,41,47,59,71,89,131")
    ap.add_argument("--azimuths", default="2,4,6,8")
    ap.add_argument("--sliding-rhs", default="equilibrium")
    ap.add_argument("--merge", action="store_true", help="add to the rows already in --out")
    ap.add_argument("--plot-only", action="store_true", help="only draw --figure from --out")
    ap.add_argument("--figure", type=Path, default=FIGURES / "convergence_3d.png")
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("convergence.json"))
    args = ap.parse_args()
    if args.plot_only:
        figure(json.loads(args.out.read_text())["table"], args.figure)
        return
    params = Params(sliding_rhs=args.sliding_rhs)
    old = json.loads(args.out.read_text())["table"] if args.merge and args.out.exists() else []
    rows = {(r["order"], r["n_azimuth"]): r for r in old}
    consolidate(Rev3D(params, Sphere(order=3)), P0)  # compile, outside the timings
    for m in map(int, args.azimuths.split(",")):
        for order in map(int, args.orders.split(",")):
            r = one_rule(params, order, m)
            rows[(order, m)] = r
            print(f"order {order:3d} m {m}: {r['cells']:6d} cells  peak q {r['peak_q']:.2f} Pa  "
                  f"q/p {r['peak_q_p']:.5f}  |s22-s33|/p0 {r['max_lateral_stress_asymmetry']:.2e}  "
                  f"|e22-e33| {r['max_lateral_strain_asymmetry']:.2e}  {r['wall_s']:.2f} s", flush=True)
    table = [rows[k] for k in sorted(rows)]
    by = {(r["order"], r["n_azimuth"]): r for r in table}
    offered = [(o, DEFAULT_AZIMUTHS) for o in OFFERED if (o, DEFAULT_AZIMUTHS) in by]
    results = []
    if len(offered) >= 2:
        a, b = by[offered[-2]], by[offered[-1]]
        results.append((f"peak q change between the two finest offered rules (orders {offered[-2][0]}, "
                        f"{offered[-1][0]}; m = {DEFAULT_AZIMUTHS})",
                        abs(a["peak_q"] - b["peak_q"]) / b["peak_q"], "< 1e-3"))
    if (DEFAULT_ORDER, DEFAULT_AZIMUTHS) in by:
        d = by[(DEFAULT_ORDER, DEFAULT_AZIMUTHS)]
        results += [(f"default rule (order {DEFAULT_ORDER}, m = {DEFAULT_AZIMUTHS}): max |s22 - s33|/p0",
                     d["max_lateral_stress_asymmetry"], "small"),
                    (f"default rule: drained triaxial wall time [s] (compiled: {d['compiled']})",
                     d["wall_s"], "-")]
    rec = record(__file__, args, 1, results, table=table,
                 offered={"orders": list(OFFERED), "default_order": DEFAULT_ORDER,
                          "default_n_azimuth": DEFAULT_AZIMUTHS})
    for name, value, target in results:
        print(f"{name}: {value:.4g} (target {target})")
    args.out.write_text(json.dumps(rec, indent=2) + "\n")
    figure(table, args.figure)
    print(f"written {args.out}, {args.figure}")


if __name__ == "__main__":
    main()
