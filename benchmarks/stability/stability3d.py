"""Stability of the 3D H-model: probe speed, and where triaxial tests enter the bifurcation domain.

(a) ``strain_envelope``: 72 strain probes (``triaxial_directions``) from the consolidated state
    at 200 kPa, default rule (Lebedev order 23, 6 azimuths: 582 bi-hexagons), best of N;
(b) ``along_triaxial``: drained triaxial compression at 200 kPa to 10 % (1000 increments of
    10⁻⁴), 72 strain probes at every 10th state and at every state from the approach of the
    bifurcation domain to its entry, probes tied to the increment — the path and the probes
    together, best of N;
(c) the located points (no timing) of drained and undrained triaxial compression at 200 kPa,
    dense (α0 = 45°) and loose (α0 = 65°), default rule (the command line's: deposition axis 1), increments 10⁻⁴, 72 probes: the peak
    of q, the entry into the bifurcation domain (and what found it) and the loss of
    controllability (by the 3D default, the secant work, and by the loading increments), and
    the softening after the peak; the drained ones also with 72 spread
    probes (``rendulic=False``) and with all six components (``shear=True``). The drained dense path and its envelopes are drawn in
    ``--figure`` (and ``-envelopes`` beside it).

Usage: ``python -m benchmarks.stability.stability3d [--repeat N]``; prints the tables, writes
``stability3d.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path

import numpy as np

from benchmarks.timing import FIGURES, best_of, provenance
from hmodel import Params
from hmodel.loading import consolidate
from hmodel.rev.rev3d import Rev3D
from hmodel.rev.sphere import Sphere
from hmodel.stability import (_located, along_triaxial, plot_envelopes, plot_path,
                              strain_envelope, triaxial_directions)

P0 = 2e5
DENSE, LOOSE = 45.0, 65.0
#: the command line's sphere (``hmodel stability --test triaxial``, ``hmodel run triaxial``):
#: the default rule with the deposition axis along the axial axis 1
SPHERE = Sphere(axis=(1.0, 0.0, 0.0))


def _params(alpha0: float) -> Params:
    return Params(sliding_rhs="equilibrium", alpha0=math.radians(alpha0))


def _pct(x: float) -> float | None:
    return round(100 * x, 3) if math.isfinite(x) else None


def _measure(alpha0: float, undrained: bool, axial: float, **kw) -> tuple[dict, object]:
    ps = along_triaxial(_params(alpha0), P0, axial, undrained=undrained, n_probes=72,
                        sphere=SPHERE, **kw)
    q = ps.result.stage("shear")["q"]
    i = int(np.argmax(q))
    interior = i < len(q) - 1
    after = ps.loading_w[i + 1:]  # the increments after the peak (loading_w[j]: into row j)
    opened = np.diff(ps.result.stage("shear")["frac_open"])[i:] > 0
    probes = "6 components" if kw.get("shear") else ("spread" if kw.get("rendulic") is False
                                                    else "half Rendulic")
    row = {"test": "undrained" if undrained else "drained", "alpha0_deg": alpha0,
           "probes": probes, "to_axial_pct": _pct(float(ps.shear_strain[-1])),
           "ended": "Newton" if len(ps.shear_strain) < round(axial / 1e-4) else "end",
           "peak_q_kPa": round(float(q[i]) / 1e3, 1) if interior else None,
           "peak_q_at_pct": _pct(float(ps.shear_strain[i])) if interior else None,
           "bifurcation_pct": _pct(ps.bifurcation), "found_by": ps.bifurcation_by,
           "controllability_pct": _pct(ps.controllability),
           # the same path's loss of controllability by the 2D rule (the loading increments)
           "controllability_increments_pct": _pct(_located(ps.result, {}, {}, True).controllability),
           "probed_states": len(ps.check_step),
           # the softening after the peak: q at the end over the peak, the share of increments
           # with d2W <= 0, and the share of those in which more contacts are open after
           "q_end_over_peak": round(float(q[-1] / q[i]), 3) if interior else None,
           "negative_after_peak": round(float(np.mean(after <= 0)), 3) if interior else None,
           "negative_with_contacts_opening": (round(float(np.mean(opened[after <= 0])), 3)
                                              if interior and (after <= 0).any() else None)}
    return row, ps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--figure", type=Path, default=FIGURES / "stability3d.png")
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("stability3d.json"))
    args = ap.parse_args()
    load = round(os.getloadavg()[0], 2)  # the timings are wall times: what ran beside them
    rev = Rev3D(_params(DENSE), SPHERE)
    state = consolidate(rev, [P0])
    d72 = triaxial_directions(72)
    timings = [
        {"measure": f"one envelope, 72 strain probes, default rule ({rev.n_cells} bi-hexagons) [s]",
         "seconds": best_of(lambda: strain_envelope(rev, state, 72, 1e-4, directions=d72), args.repeat)},
        {"measure": "d2W map, drained 200 kPa to 10 %, 72 probes, default rule [s]",
         "seconds": best_of(lambda: along_triaxial(_params(DENSE), P0, 0.1, n_probes=72, sphere=SPHERE), args.repeat)},
    ]
    located = []
    drawn = None
    for alpha0, undrained, axial in ((DENSE, False, 0.12), (LOOSE, False, 0.06),
                                     (DENSE, True, 0.06), (LOOSE, True, 0.04)):
        at = (0.01, 0.04, 0.085) if (alpha0, undrained) == (DENSE, False) else ()
        row, ps = _measure(alpha0, undrained, axial, at=at)
        located.append(row)
        drawn = drawn or ps
        if not undrained:
            located.append(_measure(alpha0, undrained, axial, rendulic=False)[0])
            located.append(_measure(alpha0, undrained, axial, shear=True)[0])
    title = "drained triaxial compression, p0 = 200 kPa, α0 = 45°, default rule"
    plot_path(drawn, args.figure, title)
    plot_envelopes(drawn.envelopes, args.figure.with_name(args.figure.stem + "-envelopes.png"), title)
    for t in timings:
        print(f"{t['measure']:<75} {t['seconds']:.4g}")
    keys = list(located[0])
    print(" | ".join(keys))
    for r in located:
        print(" | ".join(str(r[k]) for k in keys))
    rec = {**provenance(__file__, args), "repeat": args.repeat, "load_average_before": load,
           "timings": timings, "located": located}
    args.out.write_text(json.dumps(rec, indent=2) + "\n")
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
