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

**The judge** (``judge``): each 3D variant as the DEM judge calibrated it on the samples'
stress-strain curves (``benchmarks/calibration/dem_judge_VARIANT.json``: its parameters, e_ref,
sphere, step and sides), run from the e0 of the dense and the loose sample's drained tests at
100 kPa (their stored CSVs) to 25 % as ``hmodel run triaxial --contact-fabric`` runs it; its final
fabric against the DEM's, beside the record's RMS |Δq|/peak q of the same test. The calibration saw stresses only, so the fabric is a prediction.

**The swap** (``swap``): ``axisym`` and the sand variant each at its own DEM-judge calibration and
at the other's, to tell the mechanism's part of the fabric from the calibrated α0's.

**The turning rule** (``turn``): the fabric probe's DEM judge of the sand variant with its turning
rule off and on (``fabric_turn.json``'s calibrations), run the same way.

Usage: ``python -m benchmarks.model3d.contact_fabric [--parts rev,judge,swap,turn] [--dem-folder DIR]
[--out PATH]``. Prints a table and writes ``contact_fabric.json``.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from benchmarks.calibration.calibrate3d_dem import read_tests
from benchmarks.model3d.fabric_turn import dem_part, run, sand, specimen
from benchmarks.timing import ROOT, provenance
from hmodel import Params
from hmodel.dem.sample.state import SampleState
from hmodel.loading import consolidate, run_triaxial
from hmodel.rev import Rev3D, Sphere
from hmodel.rev.contacts import TILT_BANDS, Fabric, cell_contacts, fabric
from hmodel.variants import get_variant

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


#: The 3D variants the DEM judge calibrated (``benchmarks/calibration/dem_judge_NAME.json``).
JUDGED = ("axisym_mix", "axisym", "mix", "rebirth", "hertz", "cross", "density")
#: The DEM tests whose fabric the judge compares: (sample, stored CSV of its e0).
JUDGE_TESTS = (("dense-hertz", "triaxial-drained_100kPa"), ("loose-hertz", "triaxial-drained_100kPa"))


def judge_record(name: str) -> dict:
    """The DEM-judge record ``benchmarks/calibration/dem_judge_NAME.json``."""
    return json.loads((ROOT / "benchmarks" / "calibration" / f"dem_judge_{name}.json").read_text())


def judge_test(sample: str, stem: str):
    """The stored DEM test ``sample/stem`` (its e0 from the CSV)."""
    return read_tests(ROOT / "benchmarks" / "dem" / "granular" / sample)[stem]


def distances(f: dict, ref: dict) -> dict:
    """The distance of fabric ``f`` to ``ref`` (both :meth:`Fabric.as_dict`) in each of :data:`SHARES`."""
    a, b = Fabric.from_dict(f), Fabric.from_dict(ref)
    return {k: a.distance(b, k) for k in SHARES}


def judged_params(rec: dict, variant: str, e0: float) -> Params:
    """The specimen at void ratio ``e0`` of ``variant`` at the DEM-judge record ``rec``'s calibration."""
    m = rec["calibration"]["model"]
    return get_variant(variant).initial_params(Params(**m["params_rad"]), 3, e0, m["e_ref"])


def calibrated_run(rec: dict, params: Params, sample: str, dem: dict, strain: float) -> dict:
    """The specimen ``params`` (:func:`judged_params`) run with the DEM-judge record ``rec``'s
    sphere, step and sides, drained at 100 kPa to ``strain`` as ``hmodel run triaxial
    --contact-fabric`` runs it: α0, the strain and volume reached, q/p, the final fabric and its
    distance to the DEM sample's (``dem``: sample -> its fabrics). Raises where the model fails."""
    m, sph = rec["calibration"]["model"], rec["calibration"]["sphere"]
    r = run_triaxial(params, 1e5, strain, sphere=Sphere(order=sph["order"], n_azimuth=sph["n_azimuth"]),
                     step=m["step"], radial=rec["options"].get("radial"), contact_fabric=True).point(0)
    start, shear = r.stage("consolidation"), r.stage("shear")
    f = r.meta["contact_fabric"]["final"][0]
    return {"alpha0_deg": float(np.degrees(params.alpha0)),
            "eps11": float(shear["eps11"][-1] - start["eps11"][-1]), "q_p": float(shear["q_p"][-1]),
            "eps_v": float(shear["eps_v"][-1] - start["eps_v"][-1]), "final": f,
            "distance_to_dem": distances(f, dem[sample]["final"])}


def judge_part(dem: dict, strain: float = 0.25) -> list[dict]:
    """Each of :data:`JUDGED` at its DEM-judge calibration (:func:`calibrated_run`) from each of
    :data:`JUDGE_TESTS`' e0, beside the record's RMS |Δq|/peak q of the same test."""
    rows = []
    for name in JUDGED:
        rec = judge_record(name)
        variant = rec["calibration"]["model"]["variant"]
        for sample, stem in JUDGE_TESTS:
            e0 = judge_test(sample, stem).e0
            params = judged_params(rec, variant, e0)
            row = {"variant": get_variant(variant).name, "record": f"dem_judge_{name}.json", "sample": sample,
                   "e0": e0, "alpha0_deg": float(np.degrees(params.alpha0)),
                   # the stress's error the record measured, to 25 %
                   "rms_dq_judge": rec["errors"].get(f"{sample}/{stem}", {}).get("rms_dq")}
            try:
                rows.append({**row, **calibrated_run(rec, params, sample, dem, strain)})
            except Exception as err:  # a Newton that fails is the variant's result, recorded
                rows.append({**row, "failed": f"{type(err).__name__}: {str(err).split(' for cell')[0]}"})
    return rows


def swap_part(dem: dict, strain: float = 0.25) -> list[dict]:
    """``axisym`` and ``axisym-mix`` (the sand variant) each at its own DEM-judge calibration and at
    the other's (:func:`calibrated_run`; one radial strain, as both records): whether the fabric
    follows the mechanism or the calibrated α0."""
    rows = []
    for record in ("axisym", "axisym_mix"):
        rec = judge_record(record)
        for variant in ("axisym", "axisym-mix"):
            for sample, stem in JUDGE_TESTS:
                params = judged_params(rec, variant, judge_test(sample, stem).e0)
                rows.append({"calibration": f"dem_judge_{record}.json", "variant": variant, "sample": sample,
                             **calibrated_run(rec, params, sample, dem, strain)})
    return rows


def turn_part(dem: dict, strain: float = 0.25) -> list[dict]:
    """The fabric probe's DEM judge of the sand variant (``fabric_turn.json``, ``dem_judge``: its
    calibrations with the turning rule off and on), run as that probe runs it from the e0 of each
    of :data:`JUDGE_TESTS` to ``strain``: q/p, εv, the final fabric and its distance to the DEM's."""
    probe = json.loads((ROOT / "benchmarks" / "model3d" / "fabric_turn.json").read_text())["dem_judge"]
    rec = json.loads((ROOT / "benchmarks" / "calibration" / probe["record"]).read_text())
    m, sph = rec["calibration"]["model"], rec["calibration"]["sphere"]
    model = (get_variant(m["variant"]), Params(**m["params_rad"]), m["e_ref"],
             Sphere(order=sph["order"], n_azimuth=sph["n_azimuth"]), m["step"])
    rows = []
    for rule, fit in probe["fits"].items():
        f = fit["fitted"]
        x = [math.log10(f["shear_modulus"]), f["poisson"], f["phi_g_deg"], f["alpha0_deg"], f["kappa"]]
        for sample, stem in JUDGE_TESTS:
            params = specimen(model, x, judge_test(sample, stem).e0)
            path = run(params, 1e5, strain, m["step"], rule, x[4], sphere=model[3])
            fab = fabric(cell_contacts(path["rev"], path["state"])).as_dict()
            rows.append({"rule": rule, "kappa": x[4], "sample": sample, "alpha0_deg": float(np.degrees(params.alpha0)),
                         "q_p": float(path["q"][-1] / path["p"][-1]), "eps_v": float(path["eps_v"][-1]), "final": fab,
                         "distance_to_dem": distances(fab, dem[sample]["final"])})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dem-folder", type=Path, default=Path("results/fabric-dem"),
                    help="the fabric probe's DEM tests (reused when there)")
    ap.add_argument("--kappa", type=float, default=20.0, help="rate of the turning rule")
    ap.add_argument("--parts", default="rev,judge,swap,turn")
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("contact_fabric.json"))
    args = ap.parse_args()
    result = {**provenance(__file__, args), "bands": [list(b) for b in TILT_BANDS]}
    dem_part(args.dem_folder)  # runs the two tests where they are missing
    result["dem"] = []
    for name in ("dense-hertz", "loose-hertz"):
        npz = args.dem_folder / name / "triaxial-drained_100kPa.npz"
        states = {s: SampleState.from_npz(npz, s) for s in ("consolidated", "final")}
        with np.load(npz) as z:
            end = dict(zip((str(c) for c in z["row_columns"]), z["rows"][-1]))
        sig_r = 0.5 * (end["s22"] + end["s33"])
        p = (end["s11"] + 2.0 * sig_r) / 3.0
        result["dem"].append({"sample": name, "q_p": float((end["s11"] - sig_r) / p),
                              "eps_v": float(end["eps11"] + end["eps22"] + end["eps33"]),
                              **{s: st.fabric() for s, st in states.items()}})
    parts = args.parts.split(",")
    dem = {r["sample"]: r for r in result["dem"]}
    if "judge" in parts:
        result["judge"] = judge_part(dem)
        for r in result["judge"]:
            print(f"judge {r['variant']} {r['sample']} (α0 {r['alpha0_deg']:.1f}°): " + (
                r["failed"] if "failed" in r else
                f"q/p {r['q_p']:.3f}, εv {r['eps_v']:.3f}, F11 {r['final']['tensor'][0][0]:.3f} "
                f"(force {r['final']['force_tensor'][0][0]:.3f}), TV to DEM "
                + " ".join(f"{r['distance_to_dem'][k]:.2f}" for k in SHARES)))
    if "swap" in parts:
        result["swap"] = swap_part(dem)
        for r in result["swap"]:
            print(f"swap {r['variant']} at {r['calibration']} {r['sample']} (α0 {r['alpha0_deg']:.1f}°): q/p {r['q_p']:.3f}, "
                  f"εv {r['eps_v']:.3f}, TV to DEM " + " ".join(f"{r['distance_to_dem'][k]:.2f}" for k in SHARES))
    if "turn" in parts:
        result["turn"] = turn_part(dem)
        for r in result["turn"]:
            print(f"turn {r['rule']} κ {r['kappa']:.1f} {r['sample']}: q/p {r['q_p']:.3f}, εv {r['eps_v']:.3f}, TV to DEM "
                  + " ".join(f"{r['distance_to_dem'][k]:.2f}" for k in SHARES))
    result["rev"] = [rev_part(a0, 0.25, rule, k) for rule, k in (("off", 0.0), ("turn", args.kappa))
                     for a0 in (45.0, 65.0)] if "rev" in parts else []
    for r in result["rev"]:
        for state in ("consolidated", "final"):
            ref = dem["dense-hertz" if r["alpha0"] < 55.0 else "loose-hertz"][state]
            r[state]["distance_to_dem"] = distances(r[state], ref)
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
