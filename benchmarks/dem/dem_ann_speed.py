"""Speed of the ANN-based H-model against the DEM-REV as the number of material points grows.

A boundary-value problem runs many material points at once. Both REVs take a batch of points
(the DEM solver sends every cell of every point in one YADE request per Newton trial; the ANN
cells are one NumPy batch per state), so the ratio at one point understates the ratio at scale.
Measured here, for the hexagon-center cell and the model of ``benchmarks/dem/dem_ann.py``:

- **REV**: drained biaxial paths of B material points (p0 spread over 100-200 kPa, consolidated
  in isotropic steps of 2e-4, then ``--axial`` in steps of 1e-3, ``--n-theta`` cells), the
  DEM-REV once with a warm YADE process, the ANN-REV as the best of ``--repeat`` runs; the
  same increments and output resolution; the q deviation of the batch is reported too.
- **the networks' ceiling**: the DEM-REV's time over the time of the network evaluations alone
  that one ANN-REV run makes (its rows, timed as batches of the run's size): the ratio a driver
  without any other cost would reach.
- **cell**: one step of n cells (states of a consolidated DEM-REV, a shear increment of 1e-3):
  the DEM solver's request against the ANN solver's step (network and way back), a fresh
  solver each time, so that the network runs (a solver reuses the outputs of the states it
  saw last).

Prints a table, writes ``dem_ann_speed.json``.
Usage: ``python -m benchmarks.dem.dem_ann_speed [--model FILE] [--points 1,4,16]``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from dataclasses import replace
from pathlib import Path

import numba
import numpy as np
from threadpoolctl import threadpool_limits

from benchmarks.timing import best_of, provenance
from hmodel import Params
from hmodel.cell import CellState
from hmodel.compare import deviations, run_path, standard_paths
from hmodel.dem.solver import DEMSolver
from hmodel.loading.named_paths import consolidate
from hmodel.rev.rev import Rev
from hmodel.surrogate.modelfile import load
from hmodel.surrogate.solver import SurrogateSolver

SOLVER = "dem:hexagon-center:tol=1e-7,max_iter=100000"
PARAMS = Params(sliding_rhs="equilibrium")


class GenericDriver(SurrogateSolver):
    """The same solver run by the generic Python driver: a solver without a compiled increment
    (``kernel``) is stepped by the loading drivers (``hmodel.loading.compiled.supports``)."""

    def kernel(self, params):
        return None


def _variants(models, teacher=()) -> list[tuple[str, list, type]]:
    """The ANN solvers timed: the model (``ann``), the same through the generic driver
    (``ann_generic``), for an ensemble its first network alone (``ann_one``), and the network
    a distilled model learned from (``teacher``), when given."""
    return ([("ann", models, SurrogateSolver), ("ann_generic", models, GenericDriver)]
            + ([("ann_one", models[:1], SurrogateSolver)] if len(models) > 1 else [])
            + ([("teacher", list(teacher), SurrogateSolver)] if teacher else []))


def _step_variants(models, teacher=()) -> list[tuple[str, list]]:
    """The variants of one solver step (no driver): all but the generic driver."""
    return [(k, ms) for k, ms, kind in _variants(models, teacher) if kind is SurrogateSolver]


def rev_rows(models, points, n_theta: int, axial: float, repeat: int, teacher=()) -> list[dict]:
    params = replace(PARAMS, n_theta=n_theta)
    rows = []
    for B in points:
        spec = replace({s.name: s for s in standard_paths(axial)}["drained"],
                       p0=tuple(np.linspace(1e5, 2e5, B)) if B > 1 else (1.5e5,))
        dem = DEMSolver(SOLVER)
        dem.step(params, dem.initial(params, (1,)), np.zeros(1), np.zeros(1))  # start YADE
        calls = dem.yade().calls
        t = time.perf_counter()
        ref, _ = run_path(params, spec, dem, 1e-3, 2e-4)
        t_dem = time.perf_counter() - t
        calls = dem.yade().calls - calls
        dem.yade().close()
        row = {"points": B, "n_theta": n_theta, "axial_pct": 100 * axial, "dem_requests": calls,
               "seconds_dem": t_dem}
        for key, ms, kind in _variants(models, teacher):
            ann = kind(ms, on_outside="error")
            res, _ = run_path(params, spec, ann, 1e-3, 2e-4)
            # the networks alone: the rows one run evaluates, timed in batches of the run's size
            rows_run = ann.counts["network_cells"]
            t_ann = best_of(lambda: run_path(params, spec, ann, 1e-3, 2e-4), repeat)
            t_net = rows_run * network_seconds_per_row(ms, B * n_theta, repeat)
            row |= {f"seconds_{key}": t_ann, f"dem_over_{key}": t_dem / t_ann,
                    f"network_rows_{key}": rows_run, f"seconds_network_{key}": t_net,
                    f"dem_over_network_{key}": t_dem / t_net,
                    f"q_max_dev_pct_of_peak_{key}": 100 * max(d["q_max_dev_rel"] for d in deviations(ref, res))}
        rows.append(row)
        print(f"REV  B={B:<4} n_theta={n_theta}  DEM {t_dem:8.2f} s ({calls} requests)  "
              + "  ".join(f"{k}: {row[f'seconds_{k}']:.4f} s, ratio {row[f'dem_over_{k}']:.0f} "
                          f"(networks alone {row[f'dem_over_network_{k}']:.0f}), "
                          f"max dq {row[f'q_max_dev_pct_of_peak_{k}']:.1f} %" for k, *_ in _variants(models, teacher)),
              flush=True)
    return rows


def network_seconds_per_row(models, n: int, repeat: int) -> float:
    """Seconds per row of the members' forward passes (float32, as the solver runs them) on
    batches of n rows spread over the first member's training domain."""
    lo, hi = models[0].input_range
    X = lo + (hi - lo) * np.random.default_rng(0).random((n, len(lo)))
    return best_of(lambda: [m.forward(X, single=True) for m in models], max(repeat, 5)) / n


def cell_rows(models, sizes, repeat: int, teacher=()) -> list[dict]:
    """One step of n cells: consolidated DEM-REV cells (36 directions) repeated, sheared by 1e-3."""
    params = replace(PARAMS, n_theta=36)
    dem = DEMSolver(SOLVER)
    rev = Rev(params, dem)
    cells = consolidate(rev, [1.5e5], step=2e-4).cells.values[0]
    dl = rev.localize(CellState(cells[None]), np.array([[1e-3, -5e-4, 0.0]]))[0]
    f = models[0].formulation
    rows = []
    for n in sizes:
        k = -(-n // len(cells))
        full = np.tile(cells, (k, 1))[:n]
        d = np.tile(dl, (k, 1))[:n]
        # distinct rows (the DEM solver sends identical rows once): shift each length by < 1e-9
        d = d * (1.0 + 1e-6 * np.arange(n)[:, None] / n)
        t = time.perf_counter()
        dem.step(params, CellState(full), d[:, 0], d[:, 1])
        t_dem = time.perf_counter() - t
        z = CellState(f.summary(full))
        # a fresh solver each time: the solver keeps the network's outputs of the states it saw
        # last (a Newton iteration's trials reuse them), which would leave the network untimed
        row = {"cells": n, "seconds_dem": t_dem, "us_per_cell_dem": 1e6 * t_dem / n}
        for key, ms in _step_variants(models, teacher):
            t_ann = best_of(lambda: SurrogateSolver(ms, on_outside="error").step(params, z, d[:, 0], d[:, 1]),
                            repeat)
            row |= {f"seconds_{key}": t_ann, f"us_per_cell_{key}": 1e6 * t_ann / n, f"dem_over_{key}": t_dem / t_ann}
        rows.append(row)
        print(f"cell n={n:<6} DEM {1e6 * t_dem / n:9.1f} us/cell  "
              + "  ".join(f"{k}: {row[f'us_per_cell_{k}']:.2f} us/cell, ratio {row[f'dem_over_{k}']:.0f}"
                          for k, _ in _step_variants(models, teacher)), flush=True)
    dem.yade().close()
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", required=True,
                    help="a model file, or an ensemble A+B+... (e.g. WORK/student-64x3.safetensors of dem_ann.py)")
    ap.add_argument("--teacher", default=None, help="also time this model (the student's teacher)")
    ap.add_argument("--points", default="1,4,16")
    ap.add_argument("--n-theta", type=int, default=36)
    ap.add_argument("--axial", type=float, default=0.01)
    ap.add_argument("--cells", default="36,576,2304")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("dem_ann_speed.json"))
    args = ap.parse_args()
    models = [load(p) for p in args.model.split("+")]
    teacher = [load(p) for p in args.teacher.split("+")] if args.teacher else []
    # one core each: YADE runs single-threaded (-j1), so do NumPy's BLAS and the compiled
    # loading path (which runs the points of a batch on every core otherwise)
    numba.set_num_threads(1)
    with threadpool_limits(limits=1):
        cells = cell_rows(models, [int(n) for n in args.cells.split(",")], args.repeat, teacher)
        revs = rev_rows(models, [int(b) for b in args.points.split(",")], args.n_theta, args.axial, args.repeat,
                        teacher)
    args.out.write_text(json.dumps({**provenance(__file__, args),
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count()}, "model": args.model, "members": len(models),
        "teacher": args.teacher,
        "solver": SOLVER, "threads": 1, "cell": cells, "rev": revs}, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
