"""Drift of a learned richer cell along histories: the surrogate stepped alone, fed its own output.

Two kinds of history, for a ``meso`` model of a DEM cell (default: the model that
``benchmarks/dem/dem_ann.py`` builds for the hexagon-center cell):

- the data's paths: every sixth direction of the training dataset, from the unloaded (or
  prestrained) cell to the path's end, steps of the dataset's ``step``; compared with the
  dataset's start states along the path;
- a DEM-REV's own cells: a drained biaxial path (``--p0``, ``--n-theta`` cells, 3 % axial strain
  in steps of 10^-3) run with DEM cells, whose cell length histories then drive the surrogate
  cell by cell, from the DEM cell's state after consolidation.

Reported: max |V sigma_ANN - V sigma_DEM| over the history relative to the largest |V sigma| of
that history (data paths; at least 1 % of the largest of all paths, since a path that opens the
cell has next to none) or of the whole REV (REV cells), per direction; no REV feedback, so
this isolates the cell's drift. Prints a table, writes ``dem_ann_drift.json``.

Usage: ``python -m benchmarks.dem.dem_ann_drift [--model FILE] [--data DIR]``.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks.timing import provenance
from hmodel import Params
from hmodel.cell import CellState
from hmodel.data import Dataset
from hmodel.dem.solver import DEMSolver
from hmodel.loading.named_paths import biaxial, consolidate
from hmodel.rev.rev import Rev
from hmodel.surrogate.formulations.meso import STATE_FIELDS
from hmodel.surrogate.modelfile import load
from hmodel.surrogate.solver import SurrogateSolver


def data_paths(model, ds: Dataset, every: int = 6) -> list[dict]:
    """Drift along the dataset's own proportional paths."""
    f, P, spec = model.formulation, ds.params, ds.spec
    c = f.augment(ds.read())
    solver = SurrogateSolver(model)
    rows = []
    for p in np.unique(c["path_id"])[::every]:
        on = c["path_id"] == p
        th = float(c["theta"][on][0])
        strains = np.unique(c["start_strain"][on])
        ref = np.array([[c[k][on & (c["start_strain"] == s)][0] for k in ("Vs_nn", "Vs_tt")] for s in strains])
        first = np.column_stack([c[k][on & (c["start_strain"] == strains[0])][:1] for k in STATE_FIELDS])
        z = CellState(first)
        dl = -np.array([P.l10 * np.cos(th), P.l20 * np.sin(th)]) * spec.step
        out = [z.values[0, 8:10]]
        for _ in range(int(round((strains[-1] - strains[0]) / spec.step))):
            z, _ = solver.step(P, z, dl[:1], dl[1:])
            out.append(z.values[0, 8:10])
        got = np.array(out)[np.round((strains - strains[0]) / spec.step).astype(int)]
        rows.append({"history": "data path", "theta_deg": float(np.degrees(th)),
                     "max_abs_dev": float(np.abs(got - ref).max()), "dem_max_vs": float(np.abs(ref).max())})
    # relative to the path's largest |V sigma|, at least 1 % of the largest of all paths (a path
    # that opens the cell has next to none)
    floor = 0.01 * max(r["dem_max_vs"] for r in rows)
    for r in rows:
        r["max_dev_pct"] = 100 * r["max_abs_dev"] / max(r["dem_max_vs"], floor)
    return rows


def rev_cells(model, solver: str, p0: float, n_theta: int, axial: float = 0.03) -> list[dict]:
    """Drift of every cell driven along a drained DEM-REV's own cell histories."""
    f = model.formulation
    P = replace(Params.from_dict(model.meta["params"]), n_theta=n_theta)
    rev = Rev(P, DEMSolver(solver))
    s = consolidate(rev, [p0], step=2e-4)
    hist = [f.summary(s.cells.values[0])]
    for _ in range(int(round(axial / 1e-3))):
        s = biaxial(rev, s, 1e-3, step=1e-3, lateral_stress=[p0])
        hist.append(f.summary(s.cells.values[0]))
    rev.solver.yade().close()
    ann = SurrogateSolver(model)
    z = CellState(hist[0].copy())
    dev = np.zeros((n_theta, 2))
    for k in range(1, len(hist)):
        dl = hist[k][:, 6:8] - hist[k - 1][:, 6:8]
        z, _ = ann.step(P, z, dl[:, 0], dl[:, 1])
        dev = np.maximum(dev, np.abs(z.values[:, 8:10] - hist[k][:, 8:10]))
    scale = float(np.abs(np.array(hist)[:, :, 8:10]).max())
    return [{"history": f"drained DEM-REV {p0 / 1e3:g} kPa", "theta_deg": 180.0 * j / n_theta,
             "max_dev_pct": 100 * float(dev[j].max()) / scale, "dem_max_vs": scale} for j in range(n_theta)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", type=Path, required=True, help="e.g. WORK/model-0.safetensors of dem_ann.py")
    ap.add_argument("--data", type=Path, required=True, help="e.g. WORK/data-0 of dem_ann.py")
    ap.add_argument("--p0", type=float, default=1e5)
    ap.add_argument("--n-theta", type=int, default=12)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("dem_ann_drift.json"))
    args = ap.parse_args()
    model = load(args.model)
    ds = Dataset.open(args.data)
    rows = data_paths(model, ds) + rev_cells(model, ds.spec.solver, args.p0, args.n_theta)
    print(f"{'history':<26}{'theta':>8}{'max dVs %':>11}")
    for r in rows:
        print(f"{r['history']:<26}{r['theta_deg']:>8.1f}{r['max_dev_pct']:>11.2f}")
    args.out.write_text(json.dumps({**provenance(__file__, args), "model": str(args.model), "data": str(args.data), "rows": rows}, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
