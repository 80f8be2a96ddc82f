"""Which strain-probe directions find the 3D instability cone: the least normalized d²W over
several direction sets, from the same states.

States of three paths at 200 kPa, default rule (Lebedev order 23, 6 azimuths), increments of
10⁻³ of ε11: drained triaxial compression (α0 = 50°, q peaks at 4.5 %), undrained triaxial
compression (α0 = 65°, q peaks at 1.6 %) and a drained true triaxial test at constant p and
b = 0.5 (α0 = 50°). From each, strain probes of norm 10⁻³ (about the increment's) in:
``F72`` / ``F2000`` 72 / 2000 directions of the Fibonacci sphere in principal space
(``probe_directions(n, False, 6)``), ``R36+F36`` 36 on the Rendulic circle and 36 Fibonacci
(``triaxial_directions(72)``), ``H72`` / ``H20000`` Halton directions on the unit sphere of
the six components (``probe_directions(n, True, 6)``), ``R36+H36``
(``triaxial_directions(72, shear=True)``).

Usage: ``python -m benchmarks.stability.directions3d``; prints a table, writes
``directions3d.json``.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from benchmarks.timing import provenance
from hmodel import Params
from hmodel.loading import Program
from hmodel.loading.probes import strain_responses
from hmodel.stability import probe_directions, second_order_work, triaxial_directions

SETS = {"F72": lambda: probe_directions(72, False, 6), "R36+F36": lambda: triaxial_directions(72),
        "F2000": lambda: probe_directions(2000, False, 6), "H72": lambda: probe_directions(72, True, 6),
        "R36+H36": lambda: triaxial_directions(72, shear=True),
        "H20000": lambda: probe_directions(20000, True, 6)}
PATHS = {  # name: (alpha0 [deg], shear stage, increments probed)
    "drained triaxial, α0 = 50°": (50, {"preset": "drained", "eps11": 0.045, "steps": 45}, (20, 25, 30, 40)),
    "undrained triaxial, α0 = 65°": (65, {"preset": "undrained", "eps11": 0.016, "steps": 16}, (8, 12, 15)),
    "true triaxial b = 0.5, α0 = 50°": (50, {"preset": "true_triaxial", "b": 0.5, "eps11": 0.04,
                                             "steps": 40}, (10, 20, 30, 39)),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--magnitude", type=float, default=1e-3)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("directions3d.json"))
    args = ap.parse_args()
    dirs = {k: f() for k, f in SETS.items()}
    rows = []
    for path, (alpha0, stage, ks) in PATHS.items():
        params = Params(sliding_rhs="equilibrium", alpha0=math.radians(alpha0))
        prog = Program.from_dict({"dim": 3, "stage": [{"preset": "iso", "p": 2e5},
                                                      {"name": "shear", **stage}]})
        states = {}

        def keep(state, k, states=states):
            states[k] = state
            return 1
        prog.run(params, chunk=keep)
        rev = prog.make_rev(params)
        for k in ks:
            s = states[k + 1]  # shown before increment k + 1: the state after k increments
            row = {"path": path, "axial_strain_pct": round(100 * k * stage["eps11"] / stage["steps"], 2)}
            for name, d in dirs.items():
                deps = args.magnitude * d
                w = second_order_work(deps, strain_responses(rev, s, deps) - s.sig[0])[1]
                row[name] = round(float(w.min()), 3)
            rows.append(row)
            print(" | ".join(str(v) for v in row.values()), flush=True)
    rec = {**provenance(__file__, args), "min_d2W_normalized": rows}
    args.out.write_text(json.dumps(rec, indent=2) + "\n")
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
