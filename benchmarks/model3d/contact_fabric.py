"""The 3D REV's stress split by its contacts' tilt, as the DEM samples' is (issue 54,
docs/notes/2026-12-07-contact-fabric.md).

The fabric probe (``benchmarks.model3d.fabric_turn``) split the REV's stress by the tilt of each
bi-hexagon's axis n and the DEM samples' by the tilt of each contact's branch vector. A
bi-hexagon's contacts do not lie along its axis: its four inclined contacts per hexagon lie at
the opening angle α from n. So the two splits measure different things. This one splits the
REV the DEM's way.

**The decomposition** is the package's (:mod:`hmodel.rev.contacts`, the measure of ``hmodel run
... --contact-fabric`` and of a DEM sample's ``*_contact_fabric.csv``): Love-Weber (report eq.
1.11) contact by contact from the branch vectors, each contact counting its cell's weight w_c as
a DEM contact counts 1; summed, it is the REV's stress (tests/test_contacts.py).

**The comparison.** The bands of :data:`hmodel.rev.contacts.TILT_BANDS` (0-30°, 30-50°,
50-70°, 70-90°): each band's share of the carrying contacts, of σ11 and of σr = (σ22 + σ33)/2,
for the REV (sand variant's mechanisms, the package's defaults, α0 45° and 65°, drained at
100 kPa, one radial strain, steps of 1e-4) at consolidation and at 25 %, the rule of the fabric
probe off and turning (κ 20), and for the DEM samples of the fabric probe's ``dem`` part (600
Hertz-Mindlin spheres, dense and loose, drained at 100 kPa to 25 %; reused from
``--dem-folder``, run there when missing). The distance of two splits is the total variation
½ Σ_bands |a - b| (0: the same shares, 1: no band in common), per share.

Usage: ``python -m benchmarks.model3d.contact_fabric [--dem-folder DIR] [--out PATH]``. Prints a
table and writes ``contact_fabric.json``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from benchmarks.model3d.fabric_turn import dem_part, run, sand
from benchmarks.timing import provenance
from hmodel.dem.sample.state import SampleState
from hmodel.loading import consolidate
from hmodel.rev import Rev3D, Sphere
from hmodel.rev.contacts import TILT_BANDS, Fabric, cell_contacts, fabric

#: The shares a fabric is compared by (:meth:`hmodel.rev.contacts.Fabric.distance`).
SHARES = ("contacts", "sig_axial", "sig_lateral")


def rev_part(alpha0: float, strain: float, rule: str, kappa: float, p0: float = 100e3) -> dict:
    """The REV's fabric at consolidation to ``p0`` and at the end of the fabric probe's drained
    test (:func:`benchmarks.model3d.fabric_turn.run`: sand variant's mechanisms, defaults, α0
    [deg], steps of 1e-4, the rule ``rule`` at rate ``kappa``), with its q/p and εv."""
    params = sand(alpha0)
    rev = Rev3D([params], Sphere())
    first = consolidate(rev, np.array([p0]))
    path = run(params, p0, strain, 1e-4, rule, kappa)
    return {"alpha0": alpha0, "eps11": strain, "rule": rule, "kappa": kappa,
            "q_p": float(path["q"][-1] / path["p"][-1]), "eps_v": float(path["eps_v"][-1]),
            "consolidated": fabric(cell_contacts(rev, first)).as_dict(),
            "final": fabric(cell_contacts(path["rev"], path["state"])).as_dict()}


def as_fabric(d: dict) -> Fabric:
    return Fabric(np.array(d["tensor"]), np.array(d["force_tensor"]), d["count"], d["stress_ratio"], d["bands"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dem-folder", type=Path, default=Path("results/fabric-dem"),
                    help="the fabric probe's DEM tests (reused when there)")
    ap.add_argument("--kappa", type=float, default=20.0, help="rate of the turning rule")
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("contact_fabric.json"))
    args = ap.parse_args()
    result = {**provenance(__file__, args), "bands": [list(b) for b in TILT_BANDS]}
    dem_part(args.dem_folder)  # runs the two tests where they are missing
    result["dem"] = []
    for name in ("dense-hertz", "loose-hertz"):
        with np.load(args.dem_folder / name / "triaxial-drained_100kPa.npz") as z:
            states = {s: SampleState(cell=tuple(z[f"{s}_cell"]), radii=z["radii"], positions=z[f"{s}_positions"],
                                     contacts=z[f"{s}_contacts"]) for s in ("consolidated", "final")}
        result["dem"].append({"sample": name, **{s: st.fabric() for s, st in states.items()}})
    result["rev"] = [rev_part(a0, 0.25, rule, k) for rule, k in (("off", 0.0), ("turn", args.kappa))
                     for a0 in (45.0, 65.0)]
    dem = {r["sample"]: r for r in result["dem"]}
    for r in result["rev"]:
        for state in ("consolidated", "final"):
            ref = as_fabric(dem["dense-hertz" if r["alpha0"] < 55.0 else "loose-hertz"][state])
            r[state]["distance_to_dem"] = {k: as_fabric(r[state]).distance(ref, k) for k in SHARES}
    for label, x in [*((f"DEM {r['sample']} {s}", r[s]) for r in result["dem"] for s in ("consolidated", "final")),
                     *((f"REV α0 {r['alpha0']:g} {r['rule']} {s} (q/p {r['q_p']:.3f}, εv {r['eps_v']:.3f})", r[s])
                       for r in result["rev"] for s in ("consolidated", "final"))]:
        print(f"{label}: σ11/σr {x['stress_ratio']:.3f}, F11 {x['tensor'][0][0]:.3f} (force {x['force_tensor'][0][0]:.3f}); "
              + "; ".join(f"{b['lo']:g}-{b['hi']:g}°: n {b['contacts']:.2f} σ11 {b['sig_axial']:.2f} "
                          f"σr {b['sig_lateral']:.2f}" for b in x["bands"])
              + ("; TV to DEM " + " ".join(f"{x['distance_to_dem'][k]:.2f}" for k in SHARES)
                 if "distance_to_dem" in x else ""))
    args.out.write_text(json.dumps(result, indent=2, default=float) + "\n")
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
