"""Parameters per material point: a batch of B different materials against B points sharing one.

Drained biaxial tests (consolidation to 200 kPa, then axial compression, nθ = 360, default
steps), compiled path, one process: B material points that share one parameter set, and B
points with B parameter sets drawn at random (kn, kt/kn, φg, α0, αω, βω). Issue 20's target:
the batch of B sets costs at most 1.5 times the shared one at B = 64. Both batches do the same
work per point only on average (different materials take different Newton iterations), so the
trial counts per point are reported beside the times.

Usage: ``python -m benchmarks.engine.batch_params [--points 64] [--axial-strain 0.02] [--repeat 3]
[--out PATH]``. Prints a table and writes ``batch_params.json``.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
from scipy.stats import qmc

from benchmarks.timing import best_of, record, write_table
from hmodel import Params
from hmodel.loading import named_paths
from hmodel.loading.compiled import CompiledSegment
from hmodel.rev import Rev

BASE = Params(n_theta=360)
#: Ranges of the drawn materials (angles in degrees).
RANGES = {"kn": (1e8, 4e8), "kt_kn": (0.3, 1.0), "phi_g": (20.0, 40.0), "alpha0": (40.0, 60.0),
          "alpha_omega": (0.0, 0.4), "beta_omega": (0.0, 90.0)}


def drawn_sets(n: int, seed: int = 0) -> list[Params]:
    u = qmc.Sobol(len(RANGES), seed=seed).random(n)
    sets = []
    for row in u:
        v = {k: lo + x * (hi - lo) for (k, (lo, hi)), x in zip(RANGES.items(), row)}
        for k in ("phi_g", "alpha0", "beta_omega"):
            v[k] = math.radians(v[k])
        sets.append(BASE.with_(**v))
    return sets


def trials_per_point(params, n: int, axial: float) -> float:
    """Newton trials (REV trial evaluations) per point of the shear stage, from the kernel."""
    rev = Rev(params)
    state = named_paths.consolidate(rev, [2e5] * (n if isinstance(params, Params) else 1))
    seg = named_paths.biaxial_segment(state, axial, named_paths.strain_steps(axial, named_paths.AXIAL_STEP, "axial"),
                                      False, np.full(state.n_points, 2e5))
    from hmodel.loading.control import Tangent
    runner = CompiledSegment(rev, state, seg.stress_rows, seg.matrix, state.sig, seg.values,
                             seg.n_steps, Tangent())
    runner.run(1, seg.n_steps + 1)
    return float(runner.trials.mean())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=64)
    ap.add_argument("--axial-strain", type=float, default=0.02)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("batch_params.json"))
    args = ap.parse_args()
    from hmodel.loading import run_biaxial

    B, axial = args.points, args.axial_strain
    sets = drawn_sets(B)
    shared = best_of(lambda: run_biaxial(BASE, [2e5] * B, axial), args.repeat)
    mixed = best_of(lambda: run_biaxial(sets, [2e5], axial), args.repeat)
    single = best_of(lambda: run_biaxial(BASE, [2e5], axial), args.repeat)
    t_shared, t_mixed = trials_per_point(BASE, B, axial), trials_per_point(sets, B, axial)
    rows = [
        (f"{B} points, one shared parameter set [s]", shared, "-"),
        (f"{B} points, {B} parameter sets [s]", mixed, "-"),
        ("ratio mixed / shared", mixed / shared, "<= 1.5"),
        ("one point [s]", single, "-"),
        ("shear trials per point, shared", t_shared, "-"),
        ("shear trials per point, mixed", t_mixed, "-"),
    ]
    write_table(rows, args.out, record(__file__, args, args.repeat, rows, points=B, axial_strain=axial,
                                       ranges=RANGES))


if __name__ == "__main__":
    main()
