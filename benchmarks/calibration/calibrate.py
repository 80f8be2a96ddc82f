"""Calibration: speed of the batched evaluations and the identifiability of the H-model's
parameters from its own noisy curves (issue 21's targets).

Tests made by hmodel at known parameters (kn 2e8 N/m, kt/kn 0.5, φg 30°, α0 45°): drained
biaxial tests at 100, 200 and 400 kPa to 5 % axial strain, every 10th increment of 10⁻³ kept,
1 % Gaussian noise on q (seed 0). Closed form at nθ = 360 unless ``--solver`` says otherwise.

(a) one batched evaluation of 32 parameter sets (3 tests each: 96 material points) against 32
    single evaluations;
(b) least squares of kn, kt/kn, φg and α0 from 8 starts: wall time and the relative error of
    every fitted value;
(c) emcee, ``--walkers`` × ``--steps`` (default 32 × 2000) from the least-squares optimum: wall
    time, the 90 % intervals against the truth, autocorrelation times, acceptance
    (``--steps 0`` skips it).

A surrogate is trained for one material (kn, kt/kn, φg of Table 1.1) and refuses any other, so
with ``--solver surrogate`` only the fabric can be fitted: ``--fit alpha0``.

Usage: ``python -m benchmarks.calibration.calibrate [--solver closed-form] [--fit kn,kt_kn,phi_g,alpha0]
[--steps 2000] [--walkers 32] [--out PATH]``. Prints a table and writes ``calibrate.json`` (or
``--out``).
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from benchmarks.timing import record, write_table
from hmodel import Params
from hmodel.calibrate import Test, fit
from hmodel.calibrate.model import Model
from hmodel.calibrate.space import Space
from hmodel.loading import run_biaxial
from hmodel.solvers import get_solver

TRUE = Params(n_theta=360)
PRESSURES = (1e5, 2e5, 4e5)
FITTED = ("kn", "kt_kn", "phi_g", "alpha0")
STEP, ISO_STEP, STRAIN = 1e-3, 1e-4, 0.05


def make_tests(solver, noise: float = 0.01, seed: int = 0) -> list[Test]:
    rng = np.random.default_rng(seed)
    tests = []
    for p0 in PRESSURES:
        r = run_biaxial(TRUE, [p0], STRAIN, solver=solver, step=STEP, iso_step=ISO_STEP)
        c, s = r.stage("consolidation"), r.stage("shear")
        sel = slice(9, None, 10)
        e = (np.asarray(s["eps11"]) - c["eps11"][-1])[sel]
        q = np.asarray(s["q"])[sel]
        ev = (np.asarray(s["eps_v"]) - c["eps_v"][-1])[sel]
        tests.append(Test("drained", p0, e, q * (1 + noise * rng.normal(size=len(q))), ev,
                          f"drained {p0 / 1e3:g} kPa"))
    return tests


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--solver", default="closed-form")
    ap.add_argument("--fit", default=",".join(FITTED))
    ap.add_argument("--walkers", type=int, default=32)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--starts", type=int, default=8)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("calibrate.json"))
    args = ap.parse_args()
    fitted = tuple(args.fit.split(","))
    solver = get_solver(args.solver)
    tests = make_tests(solver)
    truth = {"kn": TRUE.kn, "kt_kn": TRUE.kt_kn, "phi_g": math.degrees(TRUE.phi_g),
             "alpha0": math.degrees(TRUE.alpha0)}
    rows = []

    # (a) one batched evaluation of 32 sets against 32 single ones
    space = Space.make(fitted, base=TRUE)
    z = np.random.default_rng(1).uniform(0.3, 0.7, (32, space.n))
    model = Model(tuple(tests), solver, STEP, ISO_STEP)
    sets = space.params(z)
    model.predict(sets[:2])  # compilation, caches
    t = time.perf_counter()
    pred = model.predict(sets)
    batched = time.perf_counter() - t
    t = time.perf_counter()
    for s in sets:
        model.predict([s])
    singles = time.perf_counter() - t
    rows += [("(a) 32 parameter sets, one batched evaluation [s]", batched, "<= 1"),
             ("(a) 32 single evaluations [s]", singles, "-"),
             ("(a) ratio singles / batched", singles / batched, "-"),
             ("(a) failed sets of 32", float(sum(bool(f) for f in pred.failed)), "-")]

    # (b) least squares, 4 parameters, 8 starts
    t = time.perf_counter()
    ls = fit(tests, fitted, base=TRUE, starts=args.starts, solver=solver, step=STEP, iso_step=ISO_STEP)
    rows.append((f"(b) least squares, {len(fitted)} parameters, {args.starts} starts [s]", time.perf_counter() - t, "<= 120"))
    for name in fitted:
        target = "<= 2 %" if name in ("phi_g", "alpha0") else "<= 10 %"
        rows.append((f"(b) |{name} - true| / true [%]", 100 * abs(ls.fitted[name] / truth[name] - 1), target))
    rows.append(("(b) parameter sets evaluated", float(ls.evaluations), "-"))
    extra = {"least_squares": ls.to_dict()}

    # (c) emcee
    if args.steps:
        t = time.perf_counter()
        bay = fit(tests, fitted, base=TRUE, method="bayes", starts=args.starts, walkers=args.walkers,
                  steps=args.steps, solver=solver, step=STEP, iso_step=ISO_STEP)
        rows.append((f"(c) emcee {args.walkers} walkers x {args.steps} steps (with its least squares) [s]",
                     time.perf_counter() - t, "<= 1200"))
        inside = [n for n in fitted if bay.posterior.summary[n]["q05"] <= truth[n] <= bay.posterior.summary[n]["q95"]]
        rows += [("(c) true values inside the 90 % intervals", float(len(inside)), f"= {len(fitted)}"),
                 ("(c) largest autocorrelation time [steps]", float(np.max(bay.posterior.tau)), "-"),
                 ("(c) steps / largest autocorrelation time", args.steps / float(np.max(bay.posterior.tau)), ">= 50"),
                 ("(c) acceptance fraction", bay.posterior.acceptance, "-")]
        extra["bayes"] = {**bay.posterior.to_dict(), "inside": inside}
    rec = record(__file__, args, 1, rows, solver=args.solver, truth=truth, pressures=list(PRESSURES),
                 strain=STRAIN, step=STEP, iso_step=ISO_STEP, noise_q=0.01, **extra)
    write_table(rows, args.out, rec)


if __name__ == "__main__":
    main()
