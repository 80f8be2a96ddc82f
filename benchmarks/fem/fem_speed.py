"""FEM speed, where the time goes (issue 37): drained plane-strain biaxial tests of the local
H-model at every Gauss point, each run once under cProfile (a run is minutes; the profiler's
per-call overhead is a few thousand calls of the solver's outer functions).

Cases (``--cases``, comma-separated):

- ``rough-8x16``: 8x16 Q4 (512 Gauss points), nθ = 360, rough platens, 200 kPa, to 5 % in
  100 steps, default parameters and the closed form (target <= 120 s alone on the machine);
- ``band-8x16``, ``band-16x32``, ``band-32x64``: the band study of docs/fem.md (edge
  imperfection phi_g = 25°, alpha0 = 55° in a disc of 10 mm at (0, 0.05), smooth platens,
  ``sliding_rhs=equilibrium``), nθ = 90, to 10 % in 100 steps; 32x64 is 8,192 Gauss points
  (target: well under 300 s, so that a regularization costing at most twice the local model
  stays within issue 37's 10 minutes);
- ``nonlocal-16x32``, ``nonlocal-32x64``: the same specimen with the band case of the
  regularized mesh study, ``nonlocal:ell=0.003125,m=0.05`` (issue 37's target on 32x64:
  <= 10 minutes).

Per case: wall and CPU seconds, load steps, step cuts (failed attempts), cell-event
recoveries, Newton iterations, material trials (batched calls of every Gauss point's REV) and
tangents (three probe trials each), and the seconds spent in the material's trials, in its
tangents, in assembly (strains, internal forces, stiffness) and in the sparse solves.

Usage: ``python -m benchmarks.fem.fem_speed [--cases rough-8x16,band-8x16] [--out PATH]``;
prints a table, writes ``fem_speed.json`` (or ``--out``) after each case, keeping the
figures of the cases it did not run.
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import pstats
import time
from pathlib import Path

import numpy as np

from benchmarks.timing import provenance, record, write_table
from hmodel import Params
from hmodel.fem import biaxial

BAND = "phi_g=25,alpha0=55@0,0.05,0.01"
#: the band case of the regularized mesh study (docs/fem.md, Regularization)
NONLOCAL = "nonlocal:ell=0.003125,m=0.05"
CASES = {
    "rough-8x16": {"mesh": (8, 16), "n_theta": 360, "platens": "rough", "strain": 0.05, "band": False},
    "band-8x16": {"mesh": (8, 16), "n_theta": 90, "platens": "smooth", "strain": 0.10, "band": True},
    "band-16x32": {"mesh": (16, 32), "n_theta": 90, "platens": "smooth", "strain": 0.10, "band": True},
    "band-32x64": {"mesh": (32, 64), "n_theta": 90, "platens": "smooth", "strain": 0.10, "band": True},
    "nonlocal-16x32": {"mesh": (16, 32), "n_theta": 90, "platens": "smooth", "strain": 0.10,
                       "band": True, "regularization": NONLOCAL},
    "nonlocal-32x64": {"mesh": (32, 64), "n_theta": 90, "platens": "smooth", "strain": 0.10,
                       "band": True, "regularization": NONLOCAL},
}
TARGETS = {"rough-8x16": "<= 120", "band-32x64": "< 300", "nonlocal-32x64": "<= 600"}
#: profiled functions (file suffix, name) -> the part of the run they belong to
PARTS = {
    "trials": [("fem/material.py", "_fused_trials"), ("fem/material.py", "trial_calls")],
    "tangents": [("fem/material.py", "_fused_tangents"), ("fem/material.py", "_fd_tangent")],
    "assembly": [("fem/assembly.py", "strain"), ("fem/assembly.py", "internal_force"),
                 ("fem/assembly.py", "stiffness")],
    "solve": [("skfem/utils.py", "solve"), ("skfem/utils.py", "condense")],
}


def _calls(stats: dict, where: str, name: str) -> tuple[int, float]:
    """(calls, cumulative seconds) of the profiled function ``name`` in a file ending ``where``."""
    n, t = 0, 0.0
    for (path, _, fn), (_, nc, _, ct, _) in stats.items():
        if fn == name and path.replace(os.sep, "/").endswith(where):
            n, t = n + nc, t + ct
    return n, t


def run_case(name: str) -> tuple[dict, np.ndarray]:
    """One case under cProfile: its figures and its result rows."""
    c = CASES[name]
    kw = {"sliding_rhs": "equilibrium"} if c["band"] else {}
    params = Params(n_theta=c["n_theta"], **kw)
    prof = cProfile.Profile()
    load = os.getloadavg()[0]
    wall, cpu = time.perf_counter(), time.process_time()
    prof.enable()
    res = biaxial(params, 2e5, c["strain"], mesh=c["mesh"], platens=c["platens"], n_steps=100,
                  imperfection=BAND if c["band"] else None, reference=False,
                  regularization=c.get("regularization"))
    prof.disable()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    st = pstats.Stats(prof).stats
    attempts = _calls(st, "fem/newton.py", "_step_with_events")[0]
    solves = _calls(st, "fem/newton.py", "newton_step")[0]
    out = {"wall_s": wall, "cpu_s": cpu, "gauss_points": res.meta["gauss_points"],
           "dofs": res.meta["dofs"], "steps": len(res) - 1, "stopped": res.stopped,
           "cuts": attempts - (len(res) - 1), "event_recoveries": solves - attempts,
           "newton_iterations": int(res.column("newton_iterations").sum()),
           "material_trials": _calls(st, "fem/material.py", "trial")[0],
           "material_tangents": sum(_calls(st, *f)[0] for f in PARTS["tangents"][:1]),
           "peak_q": float(res.column("q").max()), "q_end": float(res.column("q")[-1]),
           # the machine is shared: the load beside the run says how far wall is from CPU
           "load_average_before": load, "load_average_after": os.getloadavg()[0],
           "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
           "numba_threads": os.environ.get("NUMBA_NUM_THREADS", "all cores"),
           "commit": provenance(__file__, {})["commit"]}
    for part, fns in PARTS.items():
        out[f"{part}_s"] = sum(_calls(st, *f)[1] for f in fns)
    out["other_s"] = wall - sum(out[f"{p}_s"] for p in PARTS)
    return out, np.column_stack([res.column(k) for k in res.columns])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default="rough-8x16,band-8x16,band-16x32")
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("fem_speed.json"))
    ap.add_argument("--rows", type=Path, default=None,
                    help="folder for each case's result rows (<case>.npy), to compare runs")
    args = ap.parse_args()
    names = args.cases.split(",")
    for name in names:
        if name not in CASES:
            raise SystemExit(f"unknown case {name!r} (known: {', '.join(CASES)})")
    # cases run separately (32x64 takes minutes) land in one file: the others' figures are kept
    details = json.loads(args.out.read_text()).get("details", {}) if args.out.exists() else {}
    for name in names:
        details[name], table = run_case(name)
        if args.rows is not None:
            args.rows.mkdir(parents=True, exist_ok=True)
            np.save(args.rows / f"{name}.npy", table)
        write_table(table_rows(details), args.out, record(__file__, args, 1, table_rows(details),
                                                          details=details))


def table_rows(details: dict) -> list:
    """(measure, value, target) rows of every case in ``details``, in the order of CASES."""
    rows = []
    for name in (n for n in CASES if n in details):
        d = details[name]
        rows.append((f"{name}: wall [s]", d["wall_s"], TARGETS.get(name, "")))
        rows.append((f"{name}: CPU [s]", d["cpu_s"], ""))
        for k in ("newton_iterations", "cuts", "event_recoveries", "material_trials", "material_tangents"):
            rows.append((f"{name}: {k.replace('_', ' ')}", d[k], ""))
        for part in (*PARTS, "other"):
            rows.append((f"{name}: in {part} [s]", d[f"{part}_s"], ""))
    return rows


if __name__ == "__main__":
    main()
