"""Calibration of the 3D H-model on triaxial tests (issue 35): the rule's cost and error, and the
least-squares recovery of known parameters from two noisy drained triaxial tests.

Tests made by the 3D H-model at known parameters (kn 2·10⁸ N/m, kt/kn 0.5, φg 30°, α0 45°,
sliding_rhs equilibrium as the 3D commands; the default rule, order 23 with 6 azimuths, axis 1
axial as the command line's): drained triaxial tests at 100 and 400 kPa to 5 % axial strain in
increments of 10⁻³ (consolidation in steps of 10⁻⁴), every 10th increment kept, 1 % Gaussian
noise on q (seed 0).

(a) each rule offered for calibration (order, azimuths) against a fine one (order 35, 8
    azimuths) at the true parameters, on the drained tests at 100 and 400 kPa, the undrained
    one at 200 kPa and the extension one at 200 kPa to 5 %: max |Δq| / peak q and max |Δεv|
    over the four tests, and the wall time of one batched evaluation of 32 parameter sets × 2
    drained tests (64 material points, one call);
(b) least squares of kn, kt/kn, φg and α0 from 8 starts (default bounds) with the default
    search: the starts at order 17 with 2 azimuths, the best point refined at the default rule
    (the target: ≤ 2 minutes); wall and CPU time, the relative error of every fitted value,
    the parameter sets evaluated and failed;
(c) the same fit at order 17 with 2 azimuths only (``--coarse``; ``--no-coarse`` skips it):
    what calibrating the coarse model on tests of the default one costs in the parameters.

The machine's load average is recorded before and after each fit (the machine is shared; run
it under ``flock /tmp/cpu.lock``).

Usage: ``python -m benchmarks.calibration.calibrate3d [--starts 8] [--no-coarse] [--out PATH]``.
Prints a table and writes ``calibrate3d.json``.
"""

from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path

import numpy as np

from benchmarks.timing import record, write_table
from hmodel import Params
from hmodel.calibrate import Kind, Test, fit
from hmodel.calibrate.model import Model
from hmodel.calibrate.space import Space
from hmodel.loading import run_triaxial
from hmodel.rev import Sphere

BASE = Params(sliding_rhs="equilibrium")
TRUE = BASE.with_(kn=2e8, kt_kn=0.5, phi_g=math.radians(30.0), alpha0=math.radians(45.0))
FITTED = ("kn", "kt_kn", "phi_g", "alpha0")
STEP, ISO_STEP, STRAIN = 1e-3, 1e-4, 0.05
AXIS = (1.0, 0.0, 0.0)  # the command line's axial axis
DEFAULT = Sphere(axis=AXIS)
FINE = Sphere(order=35, n_azimuth=8, axis=AXIS)
RULES = ((17, 2), (17, 4), (23, 2), (DEFAULT.order, DEFAULT.n_azimuth))
COARSE = (17, 2)
#: (kind, p0) of the rule comparison (a) and, the first two, of the fits (b), (c)
TESTS = ((Kind.TRIAXIAL_DRAINED, 1e5), (Kind.TRIAXIAL_DRAINED, 4e5), (Kind.TRIAXIAL_UNDRAINED, 2e5),
         (Kind.TRIAXIAL_EXTENSION, 2e5))


def make_test(kind: Kind, p0: float, sphere: Sphere, rng, noise: float = 0.01) -> Test:
    """A triaxial test of the 3D model at TRUE: every 10th increment, relative noise on q."""
    r = run_triaxial(TRUE, [p0], STRAIN, undrained=kind.undrained, extension=kind.extension,
                     sphere=sphere, step=STEP, iso_step=ISO_STEP)
    c, s = r.stage("consolidation"), r.stage("shear")
    sel = slice(9, None, 10)
    e = (np.asarray(s["eps11"]) - c["eps11"][-1])[sel]
    q = np.asarray(s["q"])[sel]
    ev = (np.asarray(s["eps_v"]) - c["eps_v"][-1])[sel]
    return Test(kind, p0, e, q * (1 + noise * rng.normal(size=len(q))), None if kind.undrained else ev,
                f"{kind} {p0 / 1e3:g} kPa")


def rule_rows(tests: list[Test]) -> list[tuple]:
    """(a): every rule against the fine one at TRUE, and its batched evaluation's wall time."""
    ref = Model(tuple(tests), None, STEP, ISO_STEP, FINE).predict([TRUE])
    z = np.random.default_rng(1).uniform(0.3, 0.7, (32, len(FITTED)))
    sets = Space.make(FITTED, {"kn": (1e8, 4e8), "kt_kn": (0.3, 1.0), "phi_g": (20.0, 40.0),
                               "alpha0": (40.0, 60.0)}, BASE).params(z)
    rows = []
    for order, m in RULES:
        sphere = Sphere(order=order, n_azimuth=m, axis=AXIS)
        pred = Model(tuple(tests), None, STEP, ISO_STEP, sphere).predict([TRUE])
        dq = max(float(np.abs(pred.q[k][0] - ref.q[k][0]).max() / np.abs(ref.q[k][0]).max())
                 for k in range(len(tests)))
        dv = max(float(np.abs(pred.eps_v[k][0] - ref.eps_v[k][0]).max())
                 for k, t in enumerate(tests) if not t.kind.undrained)
        drained = Model(tuple(tests[:2]), None, STEP, ISO_STEP, sphere)
        drained.predict(sets[:2])  # compilation, caches
        t = time.perf_counter()
        out = drained.predict(sets)
        wall = time.perf_counter() - t
        rule = f"order {order}, m = {m} ({sphere.n_cells} bi-hexagons)"
        rows += [(f"(a) {rule}: max |dq| / peak q against order 35, m = 8 [%]", 100 * dq, "-"),
                 (f"(a) {rule}: max |d eps_v| against order 35, m = 8", dv, "-"),
                 (f"(a) {rule}: 32 sets x 2 drained tests, one batched evaluation [s]", wall, "-"),
                 (f"(a) {rule}: failed sets of 32", float(sum(bool(f) for f in out.failed)), "-")]
    return rows


def fit_rows(tag: str, tests: list[Test], truth: dict, starts: int, sphere: Sphere,
             search_rule, target: str) -> tuple[list[tuple], dict]:
    """One least-squares fit, timed: its rows and record."""
    load0 = os.getloadavg()[0]
    t, c = time.perf_counter(), time.process_time()
    cal = fit(tests, FITTED, base=BASE, starts=starts, sphere=sphere, search_rule=search_rule,
              step=STEP, iso_step=ISO_STEP)
    wall, cpu = time.perf_counter() - t, time.process_time() - c
    load1 = os.getloadavg()[0]
    rows = [(f"{tag} least squares, 4 parameters, {starts} starts, two drained tests [s]", wall, target),
            (f"{tag}   CPU time of the process (all threads) [s]", cpu, "-"),
            (f"{tag}   load average (1 min) before / after", load0, f"{load1:.2f} after")]
    for name in FITTED:
        rows.append((f"{tag}   |{name} - true| / true [%]", 100 * abs(cal.fitted[name] / truth[name] - 1), "-"))
    rows += [(f"{tag}   parameter sets evaluated", float(cal.evaluations), "-"),
             (f"{tag}   parameter sets failed (Newton)", float(len(cal.failures)), "-"),
             (f"{tag}   objective", cal.cost, "-")]
    rec = cal.to_dict()
    rec.pop("failures")  # their parameters and reasons: long; the count is in the table
    return rows, {**rec, "failures_count": len(cal.failures), "load_average": [load0, load1], "cpu_s": cpu}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=8)
    ap.add_argument("--coarse", action=argparse.BooleanOptionalAction, default=True)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("calibrate3d.json"))
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    noisy = [make_test(k, p0, DEFAULT, rng) for k, p0 in TESTS[:2]]
    exact = [make_test(k, p0, DEFAULT, rng, noise=0.0) for k, p0 in TESTS]
    truth = {"kn": TRUE.kn, "kt_kn": TRUE.kt_kn, "phi_g": math.degrees(TRUE.phi_g),
             "alpha0": math.degrees(TRUE.alpha0)}
    rows = rule_rows(exact)
    fits = {}
    r, fits["default_rule"] = fit_rows("(b)", noisy, truth, args.starts, DEFAULT, COARSE, "<= 120")
    rows += r
    if args.coarse:
        r, fits["coarse_rule"] = fit_rows("(c) order 17, m = 2 only:", noisy, truth, args.starts,
                                          Sphere(order=COARSE[0], n_azimuth=COARSE[1], axis=AXIS), None, "-")
        rows += r
    rec = record(__file__, args, 1, rows, truth=truth, pressures=[p for _, p in TESTS[:2]],
                 strain=STRAIN, step=STEP, iso_step=ISO_STEP, noise_q=0.01,
                 rules=[list(x) for x in RULES], reference_rule=[FINE.order, FINE.n_azimuth],
                 search_rule=list(COARSE), **fits)
    write_table(rows, args.out, rec)


if __name__ == "__main__":
    main()
