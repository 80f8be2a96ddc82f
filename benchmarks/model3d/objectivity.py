"""Objectivity of the 3D H-model in the loading layer (issue 34): the drained triaxial test at
200 kPa to 10 % axial strain with its loading frame rotated, against the Lebedev rule's order,
written to ``objectivity.json``.

The test of :mod:`benchmarks.model3d.convergence` (σ22 = σ33 = p0 each, ε11 increments of 1e-4,
shear strains held) is run in a frame (x'1, x'2, x'3) = (R e1, R e2, R e3): each of its six rows
is the same row on the rotated components X' = Rᵀ X R, so the axial direction is R e1. An
objective REV gives σ' (the stress in the rotated frame) equal to the stress of the unrotated
test at every increment. The error is the largest |σ'_ij - σ_ij| over the path and the
components, over p0, and the relative change of the peak q; the fabric is isotropic
(α_ω = 0), so the material has no axis that should turn with the loading.

Usage: ``python -m benchmarks.model3d.objectivity [--orders 9,17,...] [--rotations 3]
[--n-azimuth 2] [--out PATH]``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from benchmarks.timing import record
from hmodel import Params
from hmodel.loading import Recorder, Segment, consolidate, run_segment
from hmodel.rev import Rev3D, Sphere
from hmodel.rev.rev3d import VOIGT, tensor_to_voigt, voigt_to_tensor

P0 = 200e3


def rotated_rows(R: np.ndarray) -> np.ndarray:
    """A (6, 6): row r gives the Voigt component r of Rᵀ X R from the Voigt components of X
    (tensor shear components, for strains and stresses alike)."""
    A = np.zeros((6, 6))
    for r, (i, j) in enumerate(VOIGT):
        for c, (k, m) in enumerate(VOIGT):
            A[r, c] = R[k, i] * R[m, j] + (R[m, i] * R[k, j] if k != m else 0.0)
    return A


def triaxial(rev: Rev3D, R: np.ndarray, strain: float, steps: int) -> np.ndarray:
    """σ' (K, 6) in the frame of R along the drained triaxial test whose axis is R e1."""
    state = consolidate(rev, P0)
    seg = Segment((False, True, True, False, False, False), rotated_rows(R),
                  np.array([strain, P0, P0, 0.0, 0.0, 0.0]), steps, "shear")
    rec = Recorder()
    run_segment(rev, state, seg, rec)
    res = rec.result().stage("shear")
    sig = np.column_stack([res[f"sig{c}"] for c in ("11", "22", "33", "23", "13", "12")])
    return tensor_to_voigt(np.einsum("ki,bkm,mj->bij", R, voigt_to_tensor(sig), R))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--orders", default="9,17,23,35,59,89")
    ap.add_argument("--rotations", type=int, default=3)
    ap.add_argument("--n-azimuth", type=int, default=2)
    ap.add_argument("--strain", type=float, default=0.1)
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--sliding-rhs", default="equilibrium")
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("objectivity.json"))
    args = ap.parse_args()
    params = Params(sliding_rhs=args.sliding_rhs)
    rotations = Rotation.random(args.rotations, random_state=7).as_matrix()
    table = []
    for order in map(int, args.orders.split(",")):
        rev = Rev3D(params, Sphere(order=order, n_azimuth=args.n_azimuth))
        ref = triaxial(rev, np.eye(3), args.strain, args.steps)
        q_ref = ref[:, 0] - 0.5 * (ref[:, 1] + ref[:, 2])
        errs, qerrs = [], []
        for R in rotations:
            rot = triaxial(rev, R, args.strain, args.steps)
            n = min(len(rot), len(ref))
            errs.append(float(np.abs(rot[:n] - ref[:n]).max() / P0))
            q = rot[:, 0] - 0.5 * (rot[:, 1] + rot[:, 2])
            qerrs.append(float(abs(q.max() - q_ref.max()) / q_ref.max()))
        row = {"order": order, "n_azimuth": args.n_azimuth, "cells": rev.n_cells,
               "max_stress_error_over_p0": max(errs), "mean_stress_error_over_p0": float(np.mean(errs)),
               "max_peak_q_change": max(qerrs), "mean_peak_q_change": float(np.mean(qerrs))}
        table.append(row)
        print(f"order {order:3d}: max |s' - s|/p0 {row['max_stress_error_over_p0']:.2e} (mean "
              f"{row['mean_stress_error_over_p0']:.2e}), peak q change max {row['max_peak_q_change']:.2e} "
              f"(mean {row['mean_peak_q_change']:.2e})", flush=True)
    results = [(f"order {r['order']}: max |s' - s|/p0 under rotation of the loading frame",
                r["max_stress_error_over_p0"], "falls with the order") for r in table]
    rec = record(__file__, args, 1, results, table=table)
    args.out.write_text(json.dumps(rec, indent=2) + "\n")
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
