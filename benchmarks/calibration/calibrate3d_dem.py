"""The 3D H-model calibrated on a DEM sphere sample (``hmodel dem sample --dim 3``), and its
prediction of the tests it was not calibrated on (issue 35); the 2D model on a DEM disk sample
(``--dim 2``) alike.

Least squares of kn, kt/kn, φg and α0 on the sample's drained triaxial tests named by
``--fit-on`` (default: the drained tests at the lowest and the highest pressure), at the model's
rule (``--order``, ``--azimuths``; default the Sphere's, axis 1 axial as the command line's)
with the default search (order 17, 2 azimuths, then refined); the calibrated model then
predicts every other test of the folder (another pressure, the undrained test, the extension
test). Per test: RMS and max of |Δq| / peak |q| and of |Δεv| (drained tests). With
``--bayes-steps N``: emcee (``--walkers``) on the same tests at the search rule (order 17, 2
azimuths: the default rule's batched calls would take hours), its posterior's 90 % intervals.

Writes ``calibrate3d_dem.json`` (the calibration record, the DEM's settings, the errors) and the
figure ``docs/figures/dem3d-calibration.png`` (every test, DEM against model).

With ``--model NAME`` a variant of the H-model (``hmodel models``) is fitted (its own fitted
parameters); with several sample folders one parameter set is fitted over all of them (tests
named FOLDER/STEM; a variant that uses e0 starts each test from the e0 of its CSV's ``e``
column): docs/mechanisms.md's DEM judge. Folders of biaxial tests (``drained_P0kPa.csv``,
``undrained_P0kPa.csv``: a disk sample's) calibrate the 2D model, at its default parameters
(``sliding_rhs`` the report's, as ``hmodel calibrate`` takes for 2D tests; ``--order`` and
``--azimuths`` do not apply); folders of one dimension only. ``--param NAME=VALUE`` fixes a parameter beyond the
variant's (a mechanism on a variant that lacks it: ``-p lateral=axisymmetric`` on ``density``,
the linear contacts of the linear-contact samples); ``--radial`` holds the drained tests' sides
(``run_triaxial``'s ``radial``; default: by the parameters).

Usage: ``python -m benchmarks.calibration.calibrate3d_dem [SAMPLE_DIR ...] [--model NAME] [--fit-on
triaxial-drained_100kPa,triaxial-drained_400kPa] [--starts 8] [--bayes-steps 0] [--out PATH]``
(SAMPLE_DIR default: ``benchmarks/dem/dem_sample3d_series``, the five tests of a 1,000-sphere
sample that ``benchmarks/dem/dem_sample3d.py`` kept for the calibration, docs/dem.md).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks.calibration.dem_calibration import _figure
from benchmarks.timing import FIGURES, ROOT, input_files, record, write_table
from hmodel.calibrate import Kind, Test, fit
from hmodel.calibrate.fitting import SEARCH_RULE
from hmodel.calibrate.model import Model, Prediction, has_eps_v
from hmodel import Params
from hmodel.rev import Sphere
from hmodel.rev.model3d import params_3d
from hmodel.variants import get_variant

FITTED = ("kn", "kt_kn", "phi_g", "alpha0")
AXIS = (1.0, 0.0, 0.0)  # the command line's axial axis


def read_tests(folder: Path, prefix: str = "", dim: int | None = 3) -> dict[str, Test]:
    """Every ``KIND_P0kPa.csv`` of a sample folder whose KIND is a test of the ``dim``-D model
    (triaxial kinds in 3D, biaxial ones in 2D; None: either), named ``prefix + stem``; its e0 is
    the first row of the CSV's void-ratio column ``e`` where it has one (``hmodel dem sample``
    writes it), for the variants that start each test from its e0."""
    tests = {}
    for f in sorted(folder.glob("*_*kPa.csv")):
        kind, p0 = f.stem.split("_")
        if kind in tuple(Kind) and dim in (None, Kind(kind).dim):
            name = prefix + f.stem
            test = Test.from_csv(f, kind, float(p0.removesuffix("kPa")) * 1e3, name)
            with f.open(encoding="utf-8") as fh:
                header = fh.readline().strip().split(",")
                first = fh.readline().strip().split(",")
            if "e" in header:
                test = replace(test, e0=float(first[header.index("e")]))
            tests[name] = test
    return tests


def errors(test: Test, q: np.ndarray, ev: np.ndarray) -> dict[str, float]:
    """RMS and max |Δq| / peak |q|, and |Δεv| where the test's εv is fitted."""
    dq = (q - test.q) / test.q_scale
    peak, peak_model = np.argmax(np.abs(test.q)), np.argmax(np.abs(q))
    out = {"rms_dq": float(np.sqrt(np.mean(dq ** 2))), "max_dq": float(np.abs(dq).max()),
           "peak_q": float(test.q[peak]), "peak_q_model": float(q[peak_model]),
           "peak_eps_a": float(test.eps11[peak]), "peak_eps_a_model": float(test.eps11[peak_model]),
           "end_eps_a": float(test.eps11[-1]), "end_q": float(test.q[-1]), "end_q_model": float(q[-1])}
    if test.eps_v is not None:
        out |= {"end_eps_v": float(test.eps_v[-1]), "end_eps_v_model": float(ev[-1]),
                "max_contraction": float(test.eps_v.max()), "max_contraction_model": float(ev.max())}
    if has_eps_v(test):
        dv = ev - test.eps_v
        out |= {"rms_deps_v": float(np.sqrt(np.mean(dv ** 2))), "max_deps_v": float(np.abs(dv).max())}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sample", type=Path, nargs="*",
                    default=[ROOT / "benchmarks" / "dem" / "dem_sample3d_series"],
                    help="sample folders; with several, tests are named FOLDER/STEM (one parameter set "
                         "over all of them: a variant that uses e0 starts each test from its own)")
    ap.add_argument("--model", default=None, help="the H-model variant (hmodel models; default published)")
    ap.add_argument("--fit-on", default="", help="comma list of test stems (default: the drained "
                                                  "tests at the lowest and highest pressure)")
    ap.add_argument("--starts", type=int, default=8)
    ap.add_argument("--order", type=int, default=None)
    ap.add_argument("--azimuths", type=int, default=None)
    ap.add_argument("--param", "-p", action="append", default=[], metavar="NAME=VALUE",
                    help="a fixed parameter of the model beyond the variant's (a mechanism: "
                         "lateral=axisymmetric, renewal=mix); repeatable")
    ap.add_argument("--radial", default=None, choices=("free", "equal"),
                    help="how the drained tests hold their sides (run_triaxial's radial)")
    ap.add_argument("--bayes-steps", type=int, default=0)
    ap.add_argument("--walkers", type=int, default=32)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("calibrate3d_dem.json"))
    ap.add_argument("--figure", type=Path, default=FIGURES / "dem3d-calibration.png")
    args = ap.parse_args()
    variant = get_variant(args.model)
    several = len(args.sample) > 1
    tests = {}
    for folder in args.sample:
        tests |= read_tests(folder, f"{folder.name}/" if several else "", dim=None)
    dims = {t.kind.dim for t in tests.values()}
    if len(dims) != 1:
        sys.exit(f"{', '.join(map(str, args.sample))}: tests of one model's dimension, biaxial (2D) or triaxial "
                 f"(3D), expected; found {'both' if dims else 'none'}")
    dim = dims.pop()
    drained_kind = Kind.DRAINED if dim == 2 else Kind.TRIAXIAL_DRAINED
    drained = sorted((t for t in tests.values() if t.kind is drained_kind), key=lambda t: t.p0)
    chosen = args.fit_on.split(",") if args.fit_on else [t.name for t in (drained[:1] + drained[-1:])]
    chosen = list(dict.fromkeys(chosen))
    missing = [n for n in chosen if n not in tests]
    if missing or not chosen:
        sys.exit(f"no test {', '.join(missing) or '(none drained)'} in {', '.join(map(str, args.sample))}")
    kw = {k: v for k, v in (("order", args.order), ("n_azimuth", args.azimuths)) if v is not None}
    if dim == 2 and kw:
        sys.exit("--order and --azimuths are of the 3D model's sphere; these are biaxial (2D) tests")
    sphere = Sphere(**kw, axis=AXIS) if dim == 3 else None
    t0 = time.perf_counter()
    fitted = FITTED if variant.name == "published" else variant.fitted
    base = (Params.parse_assignments(args.param, params_3d() if dim == 3 else Params()) if args.param
            else None)
    cal = fit([tests[n] for n in chosen], fitted, starts=args.starts, sphere=sphere, model=variant,
              radial=args.radial, base=base)
    wall = time.perf_counter() - t0
    others = [t for n, t in tests.items() if n not in chosen]
    # each prediction on its own: a Model's parameter set fails as a whole where one test fails
    alone = [Model((t,), sphere=sphere, variant=variant, e_ref=cal.e_ref, radial=cal.radial).predict([cal.params])
             for t in others]
    pred = (Prediction([a.q[0] for a in alone], [a.eps_v[0] for a in alone], [a.failed[0] for a in alone])
            if others else None)
    rows = [(f"fitted {k}", v, f"± {cal.stderr[k]:.3g}") for k, v in cal.fitted.items()]
    rows += [("objective (scaled residuals)", cal.cost, "-"),
             (f"least squares, {args.starts} starts [s]", wall, "-"),
             ("parameter sets evaluated / failed", float(cal.evaluations), f"{len(cal.failures)} failed")]
    errs = {}
    curves = [(t, cal.prediction.q[k][0], cal.prediction.eps_v[k][0], "calibrated on")
              for k, t in enumerate(cal.tests)]
    if pred is not None:
        curves += [(t, pred.q[k][0], pred.eps_v[k][0], "predicted") for k, t in enumerate(others)]
    failures = {t.name: why for t, why in zip(others, pred.failed) if why} if pred is not None else {}
    for t, q, ev, how in curves:
        if not np.all(np.isfinite(q)):
            rows.append((f"{how} {t.name}: the model's test failed", float("nan"), "-"))
            continue
        e = errs[t.name] = {"how": how, **errors(t, q, ev)}
        rows += [(f"{how} {t.name}: RMS |dq| / peak q [%]", 100 * e["rms_dq"], "-"),
                 (f"{how} {t.name}: max |dq| / peak q [%]", 100 * e["max_dq"], "-")]
        if "rms_deps_v" in e:
            rows += [(f"{how} {t.name}: RMS |d eps_v| [%]", 100 * e["rms_deps_v"], "-"),
                     (f"{how} {t.name}: max |d eps_v| [%]", 100 * e["max_deps_v"], "-")]
    extra = {}
    if args.bayes_steps:
        coarse = Sphere(order=SEARCH_RULE[0], n_azimuth=SEARCH_RULE[1], axis=AXIS) if dim == 3 else None
        t0 = time.perf_counter()
        bay = fit([tests[n] for n in chosen], fitted, model=variant, method="bayes", starts=args.starts, sphere=coarse,
                  search_rule=None, walkers=args.walkers, steps=args.bayes_steps, radial=args.radial)
        rule = f" at order {coarse.order}, m = {coarse.n_azimuth}" if coarse is not None else ""
        rows.append((f"emcee {args.walkers} x {args.bayes_steps}{rule} (with its least squares) [s]",
                     time.perf_counter() - t0, "-"))
        for k, s in bay.posterior.summary.items():
            rows.append((f"posterior {k}: mean (90 % interval)", s["mean"], f"{s['q05']:.4g} to {s['q95']:.4g}"))
        extra["bayes"] = {**bay.posterior.to_dict(), "least_squares": bay.fitted}
    infos = {str(f): json.loads((f / "sample.json").read_text()) for f in args.sample
             if (f / "sample.json").exists()}
    files = [str(f / f"{n.rpartition('/')[2]}.csv") for f in args.sample for n in tests
             if n.startswith(f"{f.name}/" if several else "")]
    csvs = input_files({"tests": files})  # their SHA-256
    rec = record(__file__, args, 1, rows, sample=[str(f) for f in args.sample], test_files=csvs,
                 dem_settings={k: v.get("settings") for k, v in infos.items()}, model=variant.name,
                 e0={n: t.e0 for n, t in tests.items()},
                 fit_on=chosen, calibration=cal.to_dict(), errors=errs, prediction_failures=failures, **extra)
    write_table(rows, args.out, rec)
    if pred is not None:
        _figure(cal, others, pred, args.figure)
        print(f"written {args.figure}")


if __name__ == "__main__":
    main()
