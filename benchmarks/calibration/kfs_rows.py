"""Which initial state each density of Karlsruhe fine sand asks of a calibrated H-model, and
whether the loosest specimens can contract and carry as the sand does: a probe of a stored KFS
calibration (``kfs[_TAG].json``, written by ``benchmarks.calibration.kfs``), nothing fitted.

(a) **rows**: each density row (five tests of one e0 at five pressures) run at the calibration's
    parameters with one α0 for the whole row, over a grid of α0: the row's mean and largest
    RMS |Δq| / peak q and its mean RMS Δε_v; the α0 that minimizes the mean of each, beside the
    α0s the density map gives the row's specimens (``docs/calibration.md``, "One parameter set
    across densities").
(b) **loose**: the loosest row over a grid of α0 and grain friction φg, the rest as calibrated.
(c) **variants**: the loosest row at a few α0 with other mechanisms (``--variants``: a comma list
    of ``hmodel models`` names), the calibration's contacts and φg, one radial strain as the
    record's tests: the errors, the smallest strain a test reached (Newton) and q/p at the end.
(d) **turn**: the loosest row with the weight-turning rule of ``benchmarks.model3d.fabric_turn``
    (a probe, not an option of the package) over a grid of α0, φg and its rate κ.

A test that ends early is scored over the rows it reached (as in ``kfs``), so (c) gives the
strain reached beside its errors.

The data: the KFS file of the Sand Triaxial Test Database (H. Wang, NGI; CC BY 4.0,
DOI 10.4121/086847a6-ba39-4d66-973b-6b93028c7ad8), tests of Wichtmann & Triantafyllidis (2016),
Acta Geotechnica 11(4):739–761, shipped with hmodel as ``example:kfs``.

Usage: ``python -m benchmarks.calibration.kfs_rows [--tag axisym_mix] [--parts rows,loose,variants,turn]
[--out PATH]``. Prints a table and writes ``kfs_rows.json``.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks.calibration.kfs import errors, load_tests
from benchmarks.calibration.kfs_long import stored
from benchmarks.timing import record, write_table
from hmodel import Params
from hmodel.calibrate.model import curves_at
from hmodel.errors import PointFailure
from hmodel.loading import run_triaxial
from hmodel.variants import get_variant

HERE = Path(__file__).parent
#: a failed test's score in a grid (it counts as far off; the rows report how many failed)
FAILED = math.inf


def floats(text: str) -> list[float]:
    return [float(x) for x in text.split(",") if x]


def row_scores(tests, results: list[tuple[np.ndarray, np.ndarray]]) -> dict:
    """The scores of one row's tests from their model curves ``results`` ((q, ε_v) per test, NaN
    where the model did not reach): mean and largest RMS |Δq| / peak q, mean RMS Δε_v, the
    smallest strain reached and how many tests reached no row."""
    scores = [errors(t, q, ev) for t, (q, ev) in zip(tests, results)]
    dq = [FAILED if s["rms_dq"] is None else s["rms_dq"] for s in scores]
    dv = [FAILED if s["rms_dev"] is None else s["rms_dev"] for s in scores]
    return {"mean_rms_dq": float(np.mean(dq)), "max_rms_dq": float(np.max(dq)), "mean_rms_dev": float(np.mean(dv)),
            "reached_min": min(s["reached"] for s in scores), "none": sum(s["rms_dq"] is None for s in scores)}


def best(grid: list[dict], key: str) -> dict:
    """The grid point of the smallest ``key``."""
    return min(grid, key=lambda g: g[key])


def run_row(tests, sets: list[Params], sphere, step: float, radial) -> list[dict]:
    """Each parameter set of ``sets`` on every test of the row ``tests`` (one batched run):
    its :func:`row_scores` and q/p at the end (min, max over the row)."""
    n = len(tests)
    res = run_triaxial([s for s in sets for _ in tests], [t.p0 for _ in sets for t in tests],
                       max(float(t.eps11[-1]) for t in tests), sphere=sphere, step=step, drop_failed=True,
                       radial=radial)
    failed = res.meta["failed"]
    out = []
    for k in range(len(sets)):
        curves = [curves_at(res, k * n + j, t, dropped=k * n + j in failed) for j, t in enumerate(tests)]
        qp = [res["q_p"][res["point"] == k * n + j][-1] for j in range(n) if (res["point"] == k * n + j).any()]
        out.append({**row_scores(tests, curves), "q_p_end_min": float(min(qp, default=math.nan)),
                    "q_p_end_max": float(max(qp, default=math.nan))})
    return out


def rows_part(tests, variant, params, e_ref, sphere, step, radial, alphas) -> list[dict]:
    out = []
    for lvl in range(5):
        row = tests[5 * lvl:5 * lvl + 5]
        grid = [{"alpha0": a, **s} for a, s in zip(alphas, run_row(
            row, [replace(params, alpha0=math.radians(a)) for a in alphas], sphere, step, radial))]
        mapped = [math.degrees(variant.initial_params(params, 3, t.e0, e_ref).alpha0) for t in row] \
            if variant.uses_e0 else []
        out.append({"e0_mean": float(np.mean([t.e0 for t in row])), "tests": [t.name for t in row],
                    "map_alpha0": mapped, "best_q": best(grid, "mean_rms_dq"), "best_ev": best(grid, "mean_rms_dev"),
                    "grid": grid})
    return out


def loose_part(tests, params, sphere, step, radial, alphas, phis) -> list[dict]:
    combos = [(a, f) for f in phis for a in alphas]
    sets = [replace(params, alpha0=math.radians(a), phi_g=math.radians(f)) for a, f in combos]
    return [{"alpha0": a, "phi_g": f, **s} for (a, f), s in zip(combos, run_row(tests[:5], sets, sphere, step, radial))]


def variants_part(tests, params, sphere, step, radial, names, alphas) -> list[dict]:
    out = []
    for name in names:
        v = get_variant(name)
        # the calibration's contacts, grains and friction with the mechanisms off, then the variant's on
        base = v.apply(replace(params, renewal="none", lateral="affine", cross_contacts="none"))
        for a, s in zip(alphas, run_row(tests[:5], [replace(base, alpha0=math.radians(a)) for a in alphas],
                                        sphere, step, radial)):
            out.append({"variant": v.name, "alpha0": a, **s})
    return out


def turn_part(tests, params, sphere, step, alphas, phis, kappas) -> list[dict]:
    from benchmarks.model3d.fabric_turn import run

    out = []
    row = tests[:5]
    for a in alphas:
        for f in phis:
            for k in kappas:
                p = replace(params, alpha0=math.radians(a), phi_g=math.radians(f))
                curves, qp = [], []
                for t in row:
                    try:
                        path = run(p, t.p0, float(t.eps11[-1]), step, "turn" if k > 0 else "off", k, sphere=sphere)
                    except PointFailure:  # the probe's generic driver keeps no path: the test counts as failed
                        curves.append((np.full(len(t.eps11), np.nan), np.full(len(t.eps11), np.nan)))
                        continue
                    q = np.interp(t.eps11, path["eps11"], path["q"])
                    q[t.eps11 > path["eps11"][-1] + 1e-12] = np.nan
                    curves.append((q, np.interp(t.eps11, path["eps11"], path["eps_v"])))
                    qp.append(path["q"][-1] / path["p"][-1])
                out.append({"alpha0": a, "phi_g": f, "kappa": k, **row_scores(row, curves),
                            "q_p_end_min": float(min(qp, default=math.nan)),
                            "q_p_end_max": float(max(qp, default=math.nan))})
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tag", default="axisym_mix", help="the record kfs_TAG.json probed")
    ap.add_argument("--parts", default="rows,loose,variants,turn")
    ap.add_argument("--alphas", default="46,48,50,52,54,56,58,60,62,64,66,68,70", help="α0 grid of (a) [deg]")
    ap.add_argument("--loose-alphas", default="56,60,62,64,66,68,70", help="α0 grid of (b) [deg]")
    ap.add_argument("--phis", default="40,45,50,55,60,65", help="φg grid of (b) [deg]")
    ap.add_argument("--variants", default="hertz,mix,axisym,axisym-mix")
    ap.add_argument("--variant-alphas", default="58,64,68", help="α0 of (c) [deg]")
    ap.add_argument("--turn-alphas", default="62,64,66,68")
    ap.add_argument("--turn-phis", default="40,50")
    ap.add_argument("--kappas", default="0,20,50,100", help="κ of (d) (0: the rule off)")
    ap.add_argument("--out", type=Path, default=HERE / "kfs_rows.json")
    args = ap.parse_args()
    parts = set(args.parts.split(","))
    tests, attribution = load_tests(5)
    variant, params, e_ref, sphere, step, radial = stored(args.tag)
    params = variant.apply(params)  # a record stores the parameters without the variant's mechanisms
    t0 = time.perf_counter()
    rec, rows = {}, []
    if "rows" in parts:
        rec["densities"] = rows_part(tests, variant, params, e_ref, sphere, step, radial, floats(args.alphas))
        for r in rec["densities"]:
            name = f"(a) e0 {r['e0_mean']:.3f} ({r['tests'][0]}-{r['tests'][-1]})"
            span = f"map {min(r['map_alpha0']):.1f}-{max(r['map_alpha0']):.1f}" if r["map_alpha0"] else "-"
            rows += [(f"{name}: alpha0 of the least mean RMS |dq|/peak q [deg]", r["best_q"]["alpha0"], span),
                     (f"{name}:   its mean RMS |dq|/peak q [%]; mean RMS d eps_v {100 * r['best_q']['mean_rms_dev']:.2f} %",
                      100 * r["best_q"]["mean_rms_dq"], "<= 10"),
                     (f"{name}: alpha0 of the least mean RMS d eps_v [deg]", r["best_ev"]["alpha0"], span),
                     (f"{name}:   its mean RMS d eps_v [% strain]; mean RMS |dq|/peak q "
                      f"{100 * r['best_ev']['mean_rms_dq']:.0f} %", 100 * r["best_ev"]["mean_rms_dev"], "<= 0.5")]
    if "loose" in parts:
        rec["loose"] = loose_part(tests, params, sphere, step, radial, floats(args.loose_alphas), floats(args.phis))
        good_ev = [g for g in rec["loose"] if g["mean_rms_dev"] <= 0.005]
        b = best(good_ev, "mean_rms_dq") if good_ev else None
        rows += [("(b) loosest row: least mean RMS |dq|/peak q over the grid [%]",
                  100 * best(rec["loose"], "mean_rms_dq")["mean_rms_dq"], "<= 10"),
                 ("(b)   the same where the mean RMS d eps_v <= 0.5 % [%]" +
                  (f" (alpha0 {b['alpha0']:g}, phi_g {b['phi_g']:g})" if b else ""),
                  100 * b["mean_rms_dq"] if b else math.nan, "<= 10")]
    if "variants" in parts:
        rec["variants"] = variants_part(tests, params, sphere, step, radial, args.variants.split(","),
                                        floats(args.variant_alphas))
        rows += [(f"(c) {g['variant']}, alpha0 {g['alpha0']:g}: mean RMS |dq|/peak q [%]; "
                  f"smallest strain reached {100 * g['reached_min']:.1f} %, q/p at the end "
                  f"{g['q_p_end_min']:.2f}-{g['q_p_end_max']:.2f}", 100 * g["mean_rms_dq"], "-")
                 for g in rec["variants"]]
    if "turn" in parts:
        rec["turn"] = turn_part(tests, params, sphere, step, floats(args.turn_alphas), floats(args.turn_phis),
                                floats(args.kappas))
        rows += [(f"(d) alpha0 {g['alpha0']:g}, phi_g {g['phi_g']:g}, kappa {g['kappa']:g}: mean RMS |dq|/peak q [%]; "
                  f"RMS d eps_v {100 * g['mean_rms_dev']:.2f} %, {g['none']} failed, q/p at the end {g['q_p_end_min']:.2f}-"
                  f"{g['q_p_end_max']:.2f}", 100 * g["mean_rms_dq"], "-") for g in rec["turn"]]
    rows.append(("wall time [s]", time.perf_counter() - t0, "-"))
    out = record(__file__, args, 1, rows, attribution=attribution, calibration={
        "record": f"kfs_{args.tag}.json", "variant": variant.name, "e_ref": e_ref, "step": step, "radial": radial,
        "sphere": {"order": sphere.order, "azimuths": sphere.n_azimuth}}, **rec)
    write_table(rows, args.out, out)


if __name__ == "__main__":
    main()
