"""Critical state of the 3D H-model (issue 34): drained and undrained triaxial tests from a
dense and a loose state at three pressures to large strain; does (p, q, specific volume)
approach one line? Writes ``critical_state.json`` and ``docs/figures/critical_state_3d.png``.

States: the initial opening angle α0 sets the initial packing (``--dense`` and ``--loose``, in
degrees: at 45° the drained test dilates and softens after its peak, at 65° it contracts first).
Every test is one material point of one batched run (one parameter set per point, one run per
drainage condition):

- drained: σ22 = σ33 = p0 each, ε11 in increments of ``--step``, shear strains held (with
  ``--radial equal``: ε22 = ε33 and (σ22 + σ33)/2 = p0, as ``run_triaxial(..., radial="equal")``);
- undrained: ε11 increments, ε11 + ε22 + ε33 = 0, σ22 = σ33, shear strains held.

The **specific volume** of the REV is defined from its macro volume, V = V0(α0) det(I - ε)
(docs/model3d.md, "The REV"), against the initial volume of the α0 = 45° REV of the same
grains: ν = V / V0(45°). The grains (radius, number of cells) are the same for every α0, so
ν is the volume per unit solid up to one constant factor, and a critical-state line in
(ln p, ν) is one in (ln p, e) for any choice of the solid volume (e = c ν - 1). Two more
measures of the ends' volume (docs/mechanisms.md, "Three measures of the REV's volume"): the
cells' own, V0 exp(-ε_v) with ε_v the sum of the volumetric increments (every cell length
integrates δl = -l δε, so this is the volume those lengths describe, and an undrained test
keeps it exactly), and the box measure, the REV's mean box l1·l2·l3 at the end over the
α0 = 45° REV's at its start (as the 2D benchmark's, ``benchmarks.mechanisms.critical_state_2d``:
the box at the start and at the end, where the other two start on the hexagon volume). Each
gets the issue's criterion: the largest distance of the ends of the tests that reached the end
from one least-squares line ν = Γ - λ ln p.

With ``--kfs TAG`` the tests run at a Karlsruhe fine sand calibration instead of the fixed
parameters: the record ``benchmarks/calibration/kfs_TAG.json`` gives the variant, its calibrated
parameters, its sphere and how its tests held their sides, and the dense and loose states are
the sand's densest and loosest specimens (the smallest and largest e0 of the 25 tests), each at
the α0 the variant maps its e0 on (``Variant.initial_params``): the critical state of the model
as it was fitted to the sand, at the sand's own range of densities.

Usage: ``python -m benchmarks.model3d.critical_state [--order 17] [--n-azimuth 2]
[--strain 0.3] [--step 1e-4] [--kfs TAG] [--out PATH] [--figure PATH]``.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from benchmarks.timing import FIGURES, record
from hmodel import Params
from hmodel.loading import Recorder, Segment, consolidate, run_segment
from hmodel.loading.lab_tests import default_radial
from hmodel.loading.stages import ROWS_3D
from hmodel.rev import Rev3D, Sphere
from hmodel.rev.kernels3d import mean_box_volume


def parse_mechanisms(text: str) -> dict:
    """``NAME=VALUE,...`` (the cell's mechanism options, Params fields) as a dict."""
    out = {}
    for item in filter(None, (t.strip() for t in text.split(","))):
        name, _, value = item.partition("=")
        out[name.strip()] = value.strip()
    return out


def segment(undrained: bool, p0: np.ndarray, strain: float, steps: int, radial: str = "free") -> Segment:
    M = np.eye(6)
    if not undrained and radial == "equal":
        M[1], M[2] = ROWS_3D["sig_r"][1], ROWS_3D["eps22-eps33"][1]   # = p0, = 0
        stress = (False, True, False, False, False, False)
        values = np.column_stack([np.full(len(p0), strain), p0, np.zeros((len(p0), 4))])
    elif undrained:
        M[1, :3] = (1.0, 1.0, 1.0)      # eps_v = 0
        M[2, :3] = (0.0, 1.0, -1.0)     # sig22 - sig33 = 0
        stress = (False, False, True, False, False, False)
        values = np.column_stack([np.full(len(p0), strain), np.zeros((len(p0), 5))])
    else:
        stress = (False, True, True, False, False, False)
        values = np.column_stack([np.full(len(p0), strain), p0, p0, np.zeros((len(p0), 3))])
    return Segment(stress, M, values, steps, "shear")


def kfs_states(tag: str) -> tuple[list, Sphere, dict]:
    """The dense and loose states of a Karlsruhe fine sand calibration (``--kfs``): the
    parameter sets of the sand's densest and loosest specimens as the record's variant maps
    their e0, the record's sphere, and what the JSON says of where they came from."""
    from benchmarks.calibration.kfs import load_tests
    from benchmarks.calibration.kfs_long import stored

    variant, params, e_ref, sphere, _, radial = stored(tag)
    e0s = {t.name: t.e0 for t in load_tests(1)[0]}
    dense, loose = min(e0s, key=e0s.get), max(e0s, key=e0s.get)
    states = [(state, variant.initial_params(params, 3, e0s[name], e_ref))
              for state, name in (("dense", dense), ("loose", loose))]
    return states, sphere, {"record": f"kfs_{tag}.json" if tag else "kfs.json", "variant": variant.name,
                            "e_ref": e_ref, "radial": radial,
                            "specimens": {"dense": [dense, e0s[dense]], "loose": [loose, e0s[loose]]}}


def run(sets, p0, sphere, undrained, strain, steps, radial="free"):
    rev = Rev3D(sets, sphere)
    state = consolidate(rev, p0)
    rec = Recorder()
    failures: dict = {}
    end = run_segment(rev, state, segment(undrained, p0, strain, steps, radial), rec, failures=failures).state
    res = rec.result()
    geo = rev.geometry()
    out = []
    for b in range(len(sets)):
        r = res.point(b).columns
        eps = np.column_stack([r[f"eps{c}"] for c in ("11", "22", "33", "23", "13", "12")])
        nu = rev.macro_volume(eps, np.full(len(eps), b))
        out.append({"eps11": r["eps11"], "p": r["p"], "q": r["q"], "eps_v": r["eps_v"],
                    "volume": nu, "volume0": float(rev.volumes0[b]),
                    "box_end": float(mean_box_volume(end.cells.values[b], geo)), "failed": failures.get(b)})
    return out, rev


def reference_volumes(sphere: Sphere) -> tuple[float, float]:
    """The α0 = 45° REV's initial volume V0 and mean box l1·l2·l3 (at contact, unloaded): the
    units of the macro and cells' measures and of the box measure."""
    ref = Rev3D(Params(alpha0=math.radians(45.0)), sphere)
    return ref.volume0, float(mean_box_volume(ref.initial(1).cells.values[0], ref.geometry()))


def summary(path: dict, v_ref: float, window: float, p0: float, box_ref: float) -> dict:
    e, p, q = path["eps11"], path["p"], path["q"]
    nu = path["volume"] / v_ref
    end = e >= e[-1] - window
    rate = float(np.polyfit(e[end], path["eps_v"][end], 1)[0]) if end.sum() > 2 else math.nan
    qp_rate = float(np.polyfit(e[end], q[end] / p[end], 1)[0]) if end.sum() > 2 else math.nan
    k = int(np.argmax(q / np.where(p > 0, p, np.inf)))
    kmin = int(np.argmin(p))
    return {"p_min_over_p0": float(p[kmin] / p0), "axial_strain_at_p_min": float(e[kmin]),
            # a phase transformation: p turns and rises again after its lowest value (the 2D
            # benchmark's criterion, benchmarks.mechanisms.critical_state_2d)
            "p_rises_after_min": bool(p[-1] > 1.05 * p[kmin]),
            "axial_strain_end": float(e[-1]), "p_end": float(p[-1]), "q_end": float(q[-1]),
            "q_p_end": float(q[-1] / p[-1]), "nu_end": float(nu[-1]), "nu_start": float(nu[0]),
            "nu_cells_end": float(path["volume0"] * math.exp(-path["eps_v"][-1]) / v_ref),
            "nu_box_end": float(path["box_end"] / box_ref),
            "peak_q_p": float(q[k] / p[k]), "axial_strain_at_peak_q_p": float(e[k]),
            "deps_v_deps11_end": rate, "dq_p_deps11_end": qp_rate,
            "newton_failed": path["failed"] is not None}


#: The ends' volume measures (``summary``'s keys) and their names in the results.
MEASURES = (("nu_end", "macro volume V0 det(I - eps)"), ("nu_cells_end", "the cells' volume V0 exp(-eps_v)"),
            ("nu_box_end", "box measure, the mean l1 l2 l3 over the 45-degree REV's"))


def line_offset(rows: list, key: str) -> float:
    """Largest distance in ν of the ends ``rows[i][key]`` from the least-squares line
    ν = Γ - λ ln p through them (the issue's criterion: within 0.01 of one line)."""
    if len(rows) < 3:
        return math.nan
    lnp = np.log([r["p_end"] for r in rows])
    nu = np.array([r[key] for r in rows])
    coef = np.polyfit(lnp, nu, 1)
    return float(np.abs(nu - np.polyval(coef, lnp)).max())


def figure(paths, labels, out: Path, nu_label: str = "specific volume ν = V/V0(45°)") -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(14, 4.3))
    colors = {"dense": "tab:blue", "loose": "tab:red"}
    for path, lab in zip(paths, labels):
        c = colors[lab["state"]]
        ls = "-" if lab["test"] == "drained" else "--"
        kw = dict(color=c, ls=ls, lw=1.2, alpha=0.35 + 0.2 * lab["k"])
        ax[0].plot(path["eps11"] * 100, path["q"] / path["p"], **kw)
        ax[1].plot(path["p"] / 1e3, path["q"] / 1e3, **kw)
        ax[2].semilogx(path["p"] / 1e3, path["volume"] / lab["v_ref"], **kw)
        for a, x, y in ((ax[1], path["p"][-1] / 1e3, path["q"][-1] / 1e3),
                        (ax[2], path["p"][-1] / 1e3, path["volume"][-1] / lab["v_ref"])):
            a.plot(x, y, "o" if lab["test"] == "drained" else "s", color=c, ms=4)
    ax[0].set(xlabel="axial strain ε11 [%]", ylabel="q/p", title="stress ratio")
    ax[1].set(xlabel="p [kPa]", ylabel="q [kPa]", title="q–p (end states: markers)")
    ax[2].set(xlabel="p [kPa] (log)", ylabel=nu_label, title="ν–ln p")
    from matplotlib.lines import Line2D
    ax[0].legend([Line2D([], [], color="tab:blue"), Line2D([], [], color="tab:red"),
                  Line2D([], [], color="k"), Line2D([], [], color="k", ls="--")],
                 ["dense (α0 = %g°)" % labels[0]["alpha0"], "loose (α0 = %g°)" % labels[-1]["alpha0"],
                  "drained", "undrained"], fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--order", type=int, default=None, help="default: Sphere()'s")
    ap.add_argument("--n-azimuth", type=int, default=None, help="default: Sphere()'s")
    ap.add_argument("--dense", type=float, default=45.0)
    ap.add_argument("--loose", type=float, default=65.0)
    ap.add_argument("--pressures", default="100e3,200e3,400e3")
    ap.add_argument("--strain", type=float, default=0.3)
    ap.add_argument("--step", type=float, default=1e-4)
    ap.add_argument("--window", type=float, default=0.03, help="strain window of the end rates")
    ap.add_argument("--sliding-rhs", default="equilibrium")
    ap.add_argument("--radial", default=None, choices=("free", "equal"),
                    help="how the drained tests hold their sides (run_triaxial's radial; default: by "
                         "the parameters, default_radial)")
    ap.add_argument("--mechanisms", default="", help="the cell's mechanisms on, NAME=VALUE,... "
                    "(docs/mechanisms.md; e.g. contact=hertz-mindlin,renewal=rebirth); the outputs "
                    "then carry the tag --tag")
    ap.add_argument("--kfs", default=None, metavar="TAG",
                    help="run at the calibration of benchmarks/calibration/kfs_TAG.json ('' for kfs.json), "
                         "dense and loose at the sand's densest and loosest e0 (replaces --mechanisms, "
                         "--dense, --loose and --sliding-rhs)")
    ap.add_argument("--tag", default="", help="suffix of the default JSON and figure names")
    ap.add_argument("--out", type=Path, default=None, help="default: critical_state[_TAG].json")
    ap.add_argument("--figure", type=Path, default=None, help="default: docs/figures/critical_state_3d[_TAG].png")
    args = ap.parse_args()
    suffix = f"_{args.tag}" if args.tag else ""
    args.out = args.out or Path(__file__).with_name(f"critical_state{suffix}.json")
    args.figure = args.figure or FIGURES / f"critical_state_3d{suffix}.png"
    mechanisms = parse_mechanisms(args.mechanisms)
    d = Sphere()
    pressures = [float(x) for x in args.pressures.split(",")]
    calibration = None
    if args.kfs is not None:
        states, sphere, calibration = kfs_states(args.kfs)
        if args.order or args.n_azimuth:
            sphere = Sphere(order=args.order or sphere.order, n_azimuth=args.n_azimuth or sphere.n_azimuth)
        mechanisms = {k: v for k, v in states[0][1].to_dict().items() if v != Params().to_dict()[k]}
    else:
        sphere = Sphere(order=args.order or d.order, n_azimuth=args.n_azimuth or d.n_azimuth)
        states = [(state, Params.from_strings(mechanisms, Params(alpha0=math.radians(a0), sliding_rhs=args.sliding_rhs)))
                  for state, a0 in (("dense", args.dense), ("loose", args.loose))]
    sets, p0, labels = [], [], []
    for state, params in states:
        for k, p in enumerate(pressures):
            sets.append(params)
            p0.append(p)
            labels.append({"state": state, "alpha0": math.degrees(params.alpha0), "p0": p, "k": k})
    p0 = np.array(p0)
    v_ref, box_ref = reference_volumes(sphere)
    steps = int(round(args.strain / args.step))
    table, paths, plabels = [], [], []
    radial = args.radial or (calibration or {}).get("radial") or default_radial(sets)
    t = time.perf_counter()
    for test in ("drained", "undrained"):
        out, _ = run(sets, p0, sphere, test == "undrained", args.strain, steps, radial)
        for path, lab in zip(out, labels):
            row = {"test": test, **{k: v for k, v in lab.items() if k != "k"},
                   **summary(path, v_ref, args.window, lab["p0"], box_ref)}
            table.append(row)
            paths.append(path)
            plabels.append({**lab, "test": test, "v_ref": v_ref})
            print(f"{test:9s} {lab['state']:5s} p0 {lab['p0'] / 1e3:4.0f} kPa: to ε11 {row['axial_strain_end']:.3f}"
                  f"  q/p {row['q_p_end']:.3f} (peak {row['peak_q_p']:.3f})  p {row['p_end'] / 1e3:7.1f} kPa"
                  f"  ν {row['nu_end']:.4f}  dεv/dε11 {row['deps_v_deps11_end']:+.3f}"
                  f"  d(q/p)/dε11 {row['dq_p_deps11_end']:+.2f}{'  (Newton failed)' if row['newton_failed'] else ''}",
                  flush=True)
    wall = time.perf_counter() - t
    figure(paths, plabels, args.figure)
    drained = [r for r in table if r["test"] == "drained"]
    reached = [r for r in table if not r["newton_failed"]]
    qp = [r["q_p_end"] for r in reached]
    results = [("spread of q/p at the end of the tests that reached the end (max - min)",
                max(qp) - min(qp) if qp else math.nan, "-> 0 at a critical state"),
               ("largest |deps_v/deps11| at the end of the drained tests",
                max(abs(r["deps_v_deps11_end"]) for r in drained), "-> 0 at a critical state"),
               *((f"ends off one line in (ln p, nu), {name}", line_offset(reached, key), "<= 0.01")
                 for key, name in MEASURES),
               ("wall time of the two batched runs [s]", wall, "-")]
    rec = record(__file__, args, 1, results, table=table, mechanisms=mechanisms,
                 sphere={"order": sphere.order, "n_azimuth": sphere.n_azimuth}, v_ref=v_ref, box_ref=box_ref, radial=radial,
                 **({"calibration": calibration} if calibration else {}))
    args.out.write_text(json.dumps(rec, indent=2) + "\n")
    for name, value, target in results:
        print(f"{name}: {value:.4g} ({target})")
    print(f"written {args.out}, {args.figure}")


if __name__ == "__main__":
    main()
