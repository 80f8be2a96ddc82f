"""The H-model calibrated on a DEM sample (``hmodel dem sample``), and its prediction of the
tests it was not calibrated on.

Least squares of kn, kt/kn, φg and α0 on the sample's drained tests named by ``--fit-on``; the
calibrated model then predicts every other test of the folder (another pressure, the undrained
test). Writes ``dem_calibration.json`` (the calibration record, the DEM's contact parameters,
the error of each prediction as a fraction of the test's peak q) and the figure
``docs/figures/dem-calibration.png`` (every test, DEM against model).

Usage: ``python -m benchmarks.calibration.dem_calibration SAMPLE_DIR [--fit-on drained_100kPa,drained_400kPa]
[--starts 8] [--out PATH]``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from benchmarks.timing import FIGURES, record, write_table
from hmodel.calibrate import Test, fit
from hmodel.calibrate.model import Model
from hmodel.calibrate.report import finish_figure, fitted_text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sample", type=Path)
    ap.add_argument("--fit-on", default="drained_100kPa,drained_400kPa")
    ap.add_argument("--starts", type=int, default=8)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("dem_calibration.json"))
    ap.add_argument("--figure", type=Path,
                    default=FIGURES / "dem-calibration.png")
    args = ap.parse_args()
    info = json.loads((args.sample / "sample.json").read_text())
    tests = {}
    for f in sorted(args.sample.glob("*_*kPa.csv")):
        kind, p0 = f.stem.split("_")
        tests[f.stem] = Test.from_csv(f, kind, float(p0.removesuffix("kPa")) * 1e3, f.stem)
    chosen = args.fit_on.split(",")
    missing = [n for n in chosen if n not in tests]
    if missing:
        sys.exit(f"no test {', '.join(missing)} in {args.sample}")
    cal = fit([tests[n] for n in chosen], ("kn", "kt_kn", "phi_g", "alpha0"), starts=args.starts)
    others = [t for n, t in tests.items() if n not in chosen]
    pred = Model(tuple(others)).predict([cal.params]) if others else None
    rows = [(f"fitted {k}", v, "-") for k, v in cal.fitted.items()]
    rows.append(("objective (scaled residuals)", cal.cost, "-"))
    errors = {}
    for k, t in enumerate(cal.tests):
        errors[t.name] = float(np.abs(cal.prediction.q[k][0] - t.q).max() / t.q_scale)
        rows.append((f"calibrated on {t.name}: max |dq| / peak q", errors[t.name], "-"))
    for k, t in enumerate(others):
        errors[t.name] = float(np.abs(pred.q[k][0] - t.q).max() / t.q_scale)
        rows.append((f"predicted {t.name}: max |dq| / peak q", errors[t.name], "-"))
    contact = {k: info["settings"][k] for k in ("kn", "kt_kn", "phi_g") if k in info.get("settings", {})}
    porosity = {n: t["consolidated"]["porosity"] for n, t in info["tests"].items()}
    rec = record(__file__, args, 1, rows, sample=str(args.sample), dem_settings=info["settings"],
                 dem_contact=contact, porosity=porosity, calibration=cal.to_dict(),
                 max_dq_over_peak_q=errors)
    write_table(rows, args.out, rec)
    _figure(cal, others, pred, args.figure)
    print(f"written {args.figure}")


def _figure(cal, others, pred, path: Path) -> None:
    fig = Figure(figsize=(10, 4.2))
    ax_q, ax_v = fig.subplots(1, 2)
    curves = [(t, cal.prediction.q[k][0], cal.prediction.eps_v[k][0], "calibrated on")
              for k, t in enumerate(cal.tests)]
    curves += [(t, pred.q[k][0], pred.eps_v[k][0], "predicted") for k, t in enumerate(others)]
    for k, (t, q, ev, how) in enumerate(curves):
        c = f"C{k}"
        ax_q.plot(100 * t.eps11, t.q / 1e3, ".", ms=3, color=c, label=f"{t.name} (DEM)")
        ax_q.plot(100 * t.eps11, q / 1e3, "-" if how == "calibrated on" else "--", color=c,
                  label=f"H-model, {how}")
        if t.eps_v is not None:
            ax_v.plot(100 * t.eps11, 100 * t.eps_v, ".", ms=3, color=c)
        ax_v.plot(100 * t.eps11, 100 * ev, "-" if how == "calibrated on" else "--", color=c)
    path.parent.mkdir(parents=True, exist_ok=True)
    finish_figure(fig, ax_q, ax_v, f"DEM sample against the calibrated H-model ({fitted_text(cal)})",
                  path, legend_size=6)


if __name__ == "__main__":
    main()
