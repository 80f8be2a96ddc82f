"""How far to trust the Karlsruhe fine sand predictions, and what the calibrated model does past
the tests' 20 %: each variant's stored calibration (``kfs[_TAG].json``, written by
``benchmarks.calibration.kfs``) run again, nothing fitted.

(a) **Step convergence**: the 25 tests predicted at the benchmark's strain step (the ``--step``
    the calibration used) and at ten times finer; the medians of RMS |Δq| / peak q and RMS Δε_v,
    the tests within 10 %, the tests ending early and the largest change of one test's RMS
    |Δq| / peak q between the two steps (points of peak q), where both reached 20 %.
(b) **Past 20 %**: the 25 tests run on to ``--strain`` (default 50 %) at the benchmark's step:
    the model's void ratio at 20 % and at the end, e = e0 − ε_v (1 + e0) (ε_v contraction
    positive, the sand's own rule in ``kfs.sand_ends``), its q/p and dε_v/dε₁ over the last
    ``--window`` of strain, against the sand's e and q/p at 20 %. A critical state would show as
    dε_v/dε₁ → 0 and one q/p; the sand's own tests stop at 20 %.

The data: the KFS file of the Sand Triaxial Test Database (H. Wang, NGI; CC BY 4.0,
DOI 10.4121/086847a6-ba39-4d66-973b-6b93028c7ad8), tests of Wichtmann & Triantafyllidis (2016),
Acta Geotechnica 11(4):739–761, shipped with hmodel as ``example:kfs``.

Usage: ``python -m benchmarks.calibration.kfs_long [--tags ,hertz,rebirth,mix,cross,axisym,axisym_mix]
[--strain 0.5] [--window 0.03] [--out PATH]``. Prints a table and writes ``kfs_long.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from benchmarks.calibration.kfs import load_tests, predictions, sand_ends
from benchmarks.timing import record, write_table
from hmodel import Params
from hmodel.loading import run_triaxial
from hmodel.rev import Sphere
from hmodel.variants import get_variant

HERE = Path(__file__).parent
FULL = 0.199  # a test "reached 20 %" (its last row is at 0.2)


def stored(tag: str) -> tuple[object, Params, float | None, Sphere, float, str]:
    """What a KFS record's predictions ran with: the variant, the calibrated parameters, e_ref,
    the sphere, the step and how the tests held their sides."""
    rec = json.loads((HERE / (f"kfs_{tag}.json" if tag else "kfs.json")).read_text())
    model = rec["calibration"]["model"]
    variant = get_variant(model["variant"])  # the name resolved when it ran (`sand` has moved)
    sphere = Sphere(order=rec["options"]["order"], n_azimuth=rec["options"]["azimuths"])
    return (variant, Params(**model["params_rad"]), model["e_ref"], sphere, rec["options"]["step"],
            model.get("radial"))


def predict(tests, variant, params, e_ref, sphere, step: float, strain: float, radial: str):
    """Every test at its own p0 and e0 (one batched run) to ``strain``: the engine result, the
    parameter sets and the points whose Newton failed."""
    sets = [variant.initial_params(params, 3, t.e0, e_ref) for t in tests]
    res = run_triaxial(sets, [t.p0 for t in tests], strain, sphere=sphere, step=step, drop_failed=True,
                       radial=radial)
    return res, res.meta["failed"]


def summary(rows: list[dict]) -> dict:
    dq = [r["rms_dq"] for r in rows if r["rms_dq"] is not None]
    dv = [r["rms_dev"] for r in rows if r["rms_dev"] is not None]
    full = [r for r in rows if r["rms_dq"] is not None and r["reached"] >= FULL]
    return {"median_rms_dq": float(np.median(dq)) if dq else math.nan,
            "median_rms_dev": float(np.median(dv)) if dv else math.nan,
            "within_10": sum(r["rms_dq"] <= 0.10 for r in full), "ended_early": len(rows) - len(full)}


def long_ends(tests, res, failed, window: float) -> list[dict]:
    """Per test: the model's e at 20 % and at its last state, q/p and dε_v/dε₁ over the last
    ``window`` of strain, beside the sand's ends at 20 %."""
    out = []
    for b, t in enumerate(tests):
        mine = res["point"] == b
        e11, ev, qp = res["eps11"][mine], res["eps_v"][mine], res["q_p"][mine]
        void = t.e0 - ev * (1.0 + t.e0)
        last = e11 >= e11[-1] - window
        k20 = min(int(np.searchsorted(e11, 0.2)), len(e11) - 1)
        out.append({"test": t.name, "e0": t.e0, "p0_kPa": t.p0 / 1e3, **{f"sand_{k}": v for k, v in sand_ends(t).items()},
                    "e_20": float(void[k20]), "reached": float(e11[-1]), "e_end": float(void[-1]),
                    "q_p_end": float(qp[-1]), "failed": failed.get(b, ""),
                    "deps_v_deps11_end": float(np.polyfit(e11[last], ev[last], 1)[0]) if last.sum() > 2 else math.nan})
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tags", default=",hertz,rebirth,mix,cross,axisym,axisym_mix",
                    help="the records kfs[_TAG].json to run again (empty: kfs.json, the density variant)")
    ap.add_argument("--strain", type=float, default=0.5)
    ap.add_argument("--window", type=float, default=0.03)
    ap.add_argument("--out", type=Path, default=HERE / "kfs_long.json")
    args = ap.parse_args()
    tests, attribution = load_tests(5)
    results, variants = [], {}
    t0 = time.perf_counter()
    for tag in args.tags.split(","):
        variant, params, e_ref, sphere, step, radial = stored(tag)
        name = variant.name
        coarse = predictions(tests, params, variant, e_ref, sphere, step, radial)  # the benchmark's own rows
        fine = predictions(tests, params, variant, e_ref, sphere, step / 10, radial)
        moved = [abs(a["rms_dq"] - b["rms_dq"]) for a, b in zip(coarse, fine)
                 if a["rms_dq"] is not None and b["rms_dq"] is not None and min(a["reached"], b["reached"]) >= FULL]
        ends = long_ends(tests, *predict(tests, variant, params, e_ref, sphere, step, args.strain, radial), args.window)
        through = [r for r in ends if r["reached"] >= args.strain - 1e-9]
        rates = [abs(r["deps_v_deps11_end"]) for r in through]
        s0, s1 = summary(coarse), summary(fine)
        variants[name] = {"record": f"kfs_{tag}.json" if tag else "kfs.json", "step": step, "radial": radial,
                          "at_step": s0, "at_step_over_10": s1,
                          "largest_change_rms_dq": max(moved) if moved else math.nan, "long": ends}
        results += [(f"{name}: (a) median RMS |dq|/peak q [%], step {step:g}", 100 * s0["median_rms_dq"], "-"),
                    (f"{name}: (a)   the same, step {step / 10:g}", 100 * s1["median_rms_dq"], "-"),
                    (f"{name}: (a) median RMS d eps_v [% strain], step {step:g}", 100 * s0["median_rms_dev"], "-"),
                    (f"{name}: (a)   the same, step {step / 10:g}", 100 * s1["median_rms_dev"], "-"),
                    (f"{name}: (a) tests within 10 % (to 20 %), step {step:g} / {step / 10:g}",
                     float(s0["within_10"]), f"{s1['within_10']} at the finer step"),
                    (f"{name}: (a) tests ending early, step {step:g} / {step / 10:g}",
                     float(s0["ended_early"]), f"{s1['ended_early']} at the finer step"),
                    (f"{name}: (a) largest change of one test's RMS |dq|/peak q [points]",
                     100 * variants[name]["largest_change_rms_dq"], "-> 0 when converged"),
                    (f"{name}: (b) tests run to {100 * args.strain:.0f} %", float(len(through)), "25"),
                    (f"{name}: (b) smallest |deps_v/deps11| at the end", min(rates) if rates else math.nan,
                     "<= 0.05 at a critical state"),
                    (f"{name}: (b) largest |deps_v/deps11| at the end", max(rates) if rates else math.nan,
                     "<= 0.05 at a critical state"),
                    (f"{name}: (b) q/p at the end, min", min((r["q_p_end"] for r in through), default=math.nan), "-"),
                    (f"{name}: (b) q/p at the end, max", max((r["q_p_end"] for r in through), default=math.nan), "-"),
                    (f"{name}: (b) e at the end, min", min((r["e_end"] for r in through), default=math.nan), "-"),
                    (f"{name}: (b) e at the end, max", max((r["e_end"] for r in through), default=math.nan), "-")]
        print(f"{name}: done", flush=True)
    sand_e = [sand_ends(t)["e_end"] for t in tests]
    sand_qp = [sand_ends(t)["q_p_end"] for t in tests]
    results += [("the sand at 20 %: e, min", min(sand_e), "-"), ("the sand at 20 %: e, max", max(sand_e), "-"),
                ("the sand at 20 %: q/p, min", min(sand_qp), "-"), ("the sand at 20 %: q/p, max", max(sand_qp), "-"),
                ("wall time [s]", time.perf_counter() - t0, "-")]
    rec = record(__file__, args, 1, results, attribution=attribution, variants=variants)
    write_table(results, args.out, rec)


if __name__ == "__main__":
    main()
