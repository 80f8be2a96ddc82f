"""The closed-form bi-hexagon with contacts between its hexagons (``cross_contacts``,
docs/mechanisms.md) against the DEM bi-hexagon of spheres whose lateral grains are free to touch
(:func:`hmodel.dem.validate3d.validate_bihex` with ``cross=True``), on every path of
:data:`hmodel.dem.validate3d.PATHS`; beside it, the published closure (``cross_contacts=none``)
against the same DEM runs.

The DEM runs twice: with frictionless cross contacts (``cross_friction=False``: like for like
with the closed form's stated assumption) and with the scene's friction (30°) and tangential
stiffness on them, which measures what friction adds on the paths where the lateral grains of A
and B slide past each other (``unequal``).

Usage: ``python -m benchmarks.dem.dem_bihex_cross [--strain 0.03] [--steps 30] [--out PATH]``.
Prints a table and writes ``dem_bihex_cross.json`` beside this file (docs/mechanisms.md's
``mechanisms-dem-bihex`` block, ``benchmarks.model3d.mechanisms_table``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from benchmarks.timing import record, write_table
from hmodel.dem.validate3d import VALIDATION_OPTIONS, validate_bihex
from hmodel.params import Params

HERE = Path(__file__).resolve().parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--strain", type=float, default=0.03)
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--out", type=Path, default=HERE / "dem_bihex_cross.json")
    args = ap.parse_args()
    rows, paths = [], []
    for friction in (False, True):
        dem = "DEM cross contacts " + ("with friction 30 deg" if friction else "frictionless")
        for setting in ("frictionless", "none"):
            params = Params(sliding_rhs="equilibrium", cross_contacts=setting)
            v = validate_bihex(params, strain=args.strain, steps=args.steps, cross=True,
                               cross_friction=friction)
            for r in v.rows:
                if not r["cross"]:
                    continue  # the DEM without cross contacts: benchmarks/dem/dem_bihex.py
                k = v.names.index(r["path"])
                end_cf, end_dem = v.vsig_cf[k, -1], v.vsig_dem_cross[k, -1]
                paths.append({"dem_cross_friction": friction, "closed_form_cross_contacts": setting,
                              **{key: r[key] for key in ("path", "dev_force", "dev_stress", "cross_steps",
                                                         "sliding_steps", "open_steps")},
                              "vsig_end_cf": end_cf.tolist(), "vsig_end_dem": end_dem.tolist()})
                if r["cross_steps"]:
                    name = f"{r['path']}, {dem}, closed form cross_contacts={setting}"
                    rows.append((f"{name}: max |dF| / max |F|", r["dev_force"], "-"))
                    rows.append((f"{name}: max |dVsig| / max |Vsig|", r["dev_stress"], "-"))
            rows.append((f"YADE wall time, {dem}, closed form cross_contacts={setting} run [s]", v.wall_s, "-"))
    rec = record(__file__, args, 1, rows, paths=paths, dem_options=VALIDATION_OPTIONS.__dict__)
    write_table(rows, args.out, rec)
    for p in paths:
        if p["cross_steps"]:
            print("DEM friction" if p["dem_cross_friction"] else "DEM frictionless",
                  p["closed_form_cross_contacts"], p["path"], "end V sigma (nn, t1t1, t2t2) CF",
                  np.round(p["vsig_end_cf"], -3), "DEM", np.round(p["vsig_end_dem"], -3))


if __name__ == "__main__":
    main()
