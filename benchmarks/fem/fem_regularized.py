"""The regularized H-model (``hmodel.fem.regularization``) under mesh refinement, beside the local
model, for docs/fem.md (Regularization): ``fem_regularized.json`` and ``docs/figures/fem-regularized.png``.

(b) biaxial: the edge imperfection of ``fem_study`` (φg = 25°, α0 = 55° in a disc of radius
    10 mm at the middle of the left side), smooth platens, 200 kPa drained, nθ = 90,
    ``sliding_rhs=equilibrium``, to 10 % in 100 steps, on 8x16, 16x32 and 32x64 Q4, local
    (``local-MESH``), ``nonlocal:ell=ELL`` (``nonlocal-MESH``) and ``nonlocal:ell=ELL,m=M``
    (``partial-MESH``): q at 10 %, the band's angle and width (``hmodel.fem.bands``), wall
    and CPU time of each run (one case per process call: ``--cases``); the same with the
    imperfection in a quarter disc of radius 15 mm at the bottom of the left side, local
    (``cornerlocal-MESH``) and ``nonlocal:ell=ELL,m=M`` (``corner-MESH``); the edge imperfection
    on B-bar elements (``--element q4b``), local (``localb-MESH``) and ``nonlocal:ell=ELL,m=M``
    (``partialb-MESH``);
(f) footing: rough, B = 0.4 m on a 4.0 x 1.0 m layer (wide enough for the failure mechanism to
    form inside the walls), 100 kPa, nθ = 30, ``sliding_rhs=equilibrium``, Q8 elements, to
    s/B = 0.3 in 30 steps on 20x5, 40x10 and 80x20: ``nonlocal:ell=FOOT_ELL,m=FOOT_M``
    (``footing-MESH``) and local (``footlocal-MESH``).

Usage: ``python -m benchmarks.fem.fem_regularized --cases nonlocal-8x16,local-8x16 ...`` (the
partial cases with ``--ell 0.003125 --m 0.05``, the corner ones with ``--ell 0.005 --m 0.05``);
each case's numbers are merged into the JSON (several processes may run cases at once); ``--publish`` writes the published form (one table row
per case, the curves in ``fem_regularized_curves.csv``), ``--plot`` draws the figures (the fields
from this machine's last runs, kept in /tmp; ``--plot-kinds localb,partialb --figure NAME``
draws those kinds alone into docs/figures/NAME).
"""

from __future__ import annotations

import argparse
import fcntl
import json
import math
import tempfile
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from benchmarks.timing import FIGURES, provenance
from hmodel import Params
from hmodel.fem import biaxial, footing, material_point_curve
from hmodel.fem.bands import shear_band
from hmodel.fem.outputs import deviatoric_strain

ELL = 0.005
PARTIAL_M = 0.05  # the "partial" cases: nonlocal share m of the inelastic stress
#: case kind -> (regularization: None, "nonlocal" with --ell, "partial" with --ell and --m;
#: imperfection zone; element)
KINDS = {"local": (None, "edge", "q4"), "nonlocal": ("nonlocal", "edge", "q4"),
         "partial": ("partial", "edge", "q4"), "cornerlocal": (None, "corner", "q4"),
         "corner": ("partial", "corner", "q4"), "localb": (None, "edge", "q4b"),
         "partialb": ("partial", "edge", "q4b")}
FOOT_KINDS = ("footing", "footlocal")
FOOT_ELL = 0.1
FOOT_M = 0.05
FOOT = {"width": 0.4, "layer": (4.0, 1.0), "element": "q8", "settlement": 0.3, "n_steps": 30}
FOOT_PARAMS = Params(n_theta=30, sliding_rhs="equilibrium")
#: imperfection zones (x, y, radius): a disc at the middle of the left side, and a quarter disc at
#: its bottom
ZONES = {"edge": (0.0, 0.05, 0.01), "corner": (0.0, 0.0, 0.015)}
MESHES = {"8x16": (8, 16), "16x32": (16, 32), "32x64": (32, 64)}
FOOT_MESHES = {"20x5": (20, 5), "40x10": (40, 10), "80x20": (80, 20)}
PARAMS = Params(n_theta=90, sliding_rhs="equilibrium")
FIELDS = Path("/tmp/hmodel-fem-regularized")  # post-peak fields for the figure (large arrays)


def is_foot(name: str) -> bool:
    return name.split("-")[0] in FOOT_KINDS


def biaxial_case(name: str, ell: float, m: float) -> dict:
    kind, mesh = name.split("-")
    form, where, element = KINDS[kind]
    reg = {None: None, "nonlocal": f"nonlocal:ell={ell:g}", "partial": f"nonlocal:ell={ell:g},m={m:g}"}[form]
    zone = ZONES[where]
    t, c = time.perf_counter(), time.process_time()
    res = biaxial(PARAMS, 2e5, 0.10, mesh=MESHES[mesh], element=element, n_steps=100, n_saved=100, reference=True,
                  imperfection=f"phi_g=25,alpha0=55@{zone[0]},{zone[1]},{zone[2]}", regularization=reg)
    wall, cpu = time.perf_counter() - t, time.process_time() - c
    q, e = res.column("q"), res.column("eps11")
    band = shear_band(res, zone)
    ipk = int(np.argmax(q))
    snaps = {s.step: s for s in res.snapshots}
    inc = deviatoric_strain(res.snapshots[-1].eps - snaps[ipk].eps)
    FIELDS.mkdir(exist_ok=True)
    np.savez(FIELDS / f"{name}.npz", x=res.gauss_x, dx=res.gauss_dx, inc=inc)
    rates = [math.log(r[2]) / math.log(r[1]) for r in res.residuals if len(r) >= 3 and r[1] < 1e-2 and r[2] > 1e-14]
    # the last iteration of each step (a step's list also holds an event's restoration, whose
    # first iterations start over from 1e-3): log r_n / log r_(n-1), 2 for quadratic convergence
    terminal = [math.log(r[-1]) / math.log(r[-2]) for r in res.residuals
                if len(r) >= 3 and 1e-14 < r[-2] < 1e-3 and r[-1] > 1e-15]
    ref = material_point_curve(res.reference)
    return {"regularization": res.meta["regularization"], "mesh": mesh, "element": element,
            "gauss_points": int(res.gauss_dx.size),
            "dofs": res.meta["dofs"], "imperfection_zone": ",".join(f"{v:g}" for v in zone),
            "wall_s": wall, "cpu_s": cpu, "stopped": res.stopped, "steps": len(res) - 1,
            "newton_iterations": int(res.column("newton_iterations").sum()),
            "median_rate": float(np.median(rates)) if rates else None,
            "terminal_rate": float(np.median(terminal)) if terminal else None, "warnings": res.meta["warnings"],
            "peak_q": float(q[ipk]), "peak_strain": float(e[ipk]),
            "q_at_10pc": float(q[-1]) if abs(e[-1] - 0.10) < 1e-9 else None,
            "band": band, "curve": {"eps11": e.tolist(), "q": q.tolist()},
            "material_point": {"eps11": ref["eps11"].tolist(), "q": ref["q"].tolist()}}


def footing_case(name: str, ell: float, m: float) -> dict:
    kind, mesh = name.split("-")
    reg = None if kind == "footlocal" else f"nonlocal:ell={ell:g},m={m:g}"
    t, c = time.perf_counter(), time.process_time()
    res = footing(FOOT_PARAMS, 1e5, FOOT["settlement"], width=FOOT["width"], layer=FOOT["layer"],
                  mesh=FOOT_MESHES[mesh], element=FOOT["element"], n_steps=FOOT["n_steps"], regularization=reg)
    s, p = res.column("s_B"), res.column("pressure")
    return {"regularization": res.meta["regularization"], "mesh": mesh, "wall_s": time.perf_counter() - t,
            "cpu_s": time.process_time() - c, "stopped": res.stopped, "warnings": res.meta["warnings"],
            "element": FOOT["element"], "n_theta": FOOT_PARAMS.n_theta,
            "s_B": s.tolist(), "pressure": p.tolist(), "peak_pressure": float(p.max()),
            "peak_at_s_B": float(s[np.argmax(p)])}


def summary(cases: dict) -> dict:
    out = {}
    for kind in KINDS:
        q = {m: cases.get(f"{kind}-{m}", {}).get("q_at_10pc") for m in MESHES}
        if q["16x32"] and q["32x64"]:
            out[f"{kind}_q10_change_finest_pc"] = 100 * abs(q["32x64"] - q["16x32"]) / q["32x64"]
        out[f"{kind}_q_at_10pc"] = q
    for kind in FOOT_KINDS:
        peak = {m: cases.get(f"{kind}-{m}", {}).get("peak_pressure") for m in FOOT_MESHES}
        out[f"{kind}_peak_pressure"] = peak
        if peak["40x10"] and peak["80x20"]:
            out[f"{kind}_peak_change_finest_pc"] = 100 * abs(peak["80x20"] - peak["40x10"]) / peak["80x20"]
    for m in MESHES:
        a, b = cases.get(f"local-{m}"), cases.get(f"nonlocal-{m}")
        if a and b:
            out[f"time_ratio_{m}"] = b["wall_s"] / a["wall_s"]
            out[f"cpu_ratio_{m}"] = b["cpu_s"] / a["cpu_s"]
    return out


def plot(cases: dict, only: list | None = None, figure: str = "fem-regularized.png") -> None:
    """The fields and curves of the biaxial kinds (``only``: these) into ``figure``, and the
    footing's curves."""
    kinds = [k for k in KINDS if any(c.startswith(k + "-") for c in cases) and (not only or k in only)]
    fig, axes = plt.subplots(len(kinds), 4, figsize=(15, 4 * len(kinds)), squeeze=False)
    for i, kind in enumerate(kinds):
        for j, m in enumerate(MESHES):
            ax = axes[i, j]
            ax.set_xticks([]), ax.set_yticks([]), ax.set_aspect("equal")
            c, f = cases.get(f"{kind}-{m}"), FIELDS / f"{kind}-{m}.npz"
            if c is None or not f.exists():
                ax.set_title(f"{kind} {m}: not run", fontsize=9)
                continue
            d = np.load(f)
            sc = ax.scatter(d["x"][0], d["x"][1], c=d["inc"], s=2500 / d["dx"].size ** 0.85, marker="s", cmap="viridis")
            fig.colorbar(sc, ax=ax, fraction=0.06)
            b = c["band"]
            ax.set_title(f"{'local' if c['regularization'] == 'local' else c['regularization']}"
                         f"{' (corner)' if KINDS[kind][1] == 'corner' else ''} {m}\n"
                         + (f"band {b['angle_deg']:.0f} deg, {1e3 * b['width_m']:.1f} mm" if b["angle_deg"] else
                            f"no band (max/mean {b['concentration']:.2f})"), fontsize=8)
            axes[i, 3].plot(c["curve"]["eps11"], np.array(c["curve"]["q"]) / 1e3, label=m)
        any_case = next((c for c in cases.values() if "material_point" in c), None)
        if any_case:
            mp = any_case["material_point"]
            axes[i, 3].plot(mp["eps11"], np.array(mp["q"]) / 1e3, "k--", label="material point")
        axes[i, 3].set_title(f"{kind}: q against axial strain", fontsize=9)
        axes[i, 3].set_xlabel("axial strain"), axes[i, 3].set_ylabel("q [kPa]"), axes[i, 3].legend(fontsize=8)
    fig.suptitle("deviatoric strain increment after the peak, one row per model (and imperfection, where not the edge one)")
    fig.tight_layout()
    fig.savefig(FIGURES / figure, dpi=100)
    plt.close(fig)
    feet = [c for k, c in cases.items() if is_foot(k)]
    if feet:
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for c in feet:
            ax.plot(c["s_B"], np.array(c["pressure"]) / 1e3, "o-" if c["regularization"] != "local" else "x--", ms=3,
                label=f"{c['mesh']} {c.get('element', 'q4').upper()} {c['regularization']}")
        ax.set_xlabel("settlement / footing width"), ax.set_ylabel("footing pressure [kPa]"), ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(FIGURES / "fem-regularized-footing.png", dpi=100)
        plt.close(fig)


BAND_KEYS = ("angle_deg", "width_m", "concentration", "peak_step")
THEORY_KEYS = ("phi_peak", "psi_peak", "coulomb", "roscoe", "arthur")


def _flat(name: str, c: dict) -> dict:
    """A case as one table row: scalars only (its curve goes to the CSV)."""
    row = {"case": name, **{k: v for k, v in c.items() if not isinstance(v, (dict, list))}}
    row.update({f"band_{k}": c["band"].get(k) for k in BAND_KEYS} if "band" in c else {})
    row["warnings"] = "; ".join(c.get("warnings") or []) or None
    return row


def _unflat(row: dict, curves: dict) -> dict:
    c = {k: v for k, v in row.items() if k != "case" and not k.startswith("band_")}
    c["warnings"] = [row["warnings"]] if row.get("warnings") else []
    x, y = curves.get(row["case"], ([], []))
    if is_foot(row["case"]):
        c.update(s_B=x, pressure=y)
    else:
        c["band"] = {k: row.get(f"band_{k}") for k in BAND_KEYS}
        c["curve"] = {"eps11": x, "q": y}
        mx, my = curves.get("material-point", ([], []))
        c["material_point"] = {"eps11": mx, "q": my}
    return c


def load(out: Path) -> tuple[dict, dict]:
    """The record and its cases (name -> case), from the working form (``cases``) or the
    published one (``rows``, ``footing`` and the curves' CSV beside the JSON)."""
    data = json.loads(out.read_text()) if out.exists() else {}
    if "cases" in data:
        return data, data["cases"]
    curves: dict = {}
    csv = out.with_name(out.stem + "_curves.csv")
    if csv.exists():
        for line in csv.read_text().splitlines()[1:]:
            name, x, y = line.split(",")
            xs, ys = curves.setdefault(name, ([], []))
            xs.append(float(x)), ys.append(float(y))
    rows = data.get("rows", []) + data.get("footing", [])
    return data, {r["case"]: _unflat(r, curves) for r in rows}


def publish(out: Path, data: dict, cases: dict) -> None:
    """The published form: a table row per case (``rows``, ``footing``), the peak angles and the
    summary in the JSON, every curve (and the material point's) in ``NAME_curves.csv``."""
    lines = ["case,x,y"]
    for name, c in cases.items():
        x, y = (c["s_B"], c["pressure"]) if is_foot(name) else (c["curve"]["eps11"], c["curve"]["q"])
        lines += [f"{name},{a!r},{b!r}" for a, b in zip(x, y)]
    mp = next((c["material_point"] for c in cases.values() if c.get("material_point", {}).get("q")), None)
    if mp:
        lines += [f"material-point,{a!r},{b!r}" for a, b in zip(mp["eps11"], mp["q"])]
    out.with_name(out.stem + "_curves.csv").write_text("\n".join(lines) + "\n")
    band = next((c["band"] for c in cases.values() if "coulomb" in c.get("band", {})), {})
    keep = {k: v for k, v in data.items() if k not in ("cases", "rows", "footing", "summary", "theory")}
    data = {**keep, "summary": summary(cases), "theory": {k: band.get(k) for k in THEORY_KEYS},
            "rows": [_flat(n, c) for n, c in cases.items() if not is_foot(n)],
            "footing": [_flat(n, c) for n, c in cases.items() if is_foot(n)]}
    out.write_text(json.dumps(data, indent=1, default=float) + "\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default="", help="comma list: local-8x16, nonlocal-32x64, partial-16x32, "
                                                "footing-40x10, footlocal-40x10, ...")
    ap.add_argument("--ell", type=float, default=ELL)
    ap.add_argument("--m", type=float, default=PARTIAL_M, help="nonlocal share of the partial cases")
    ap.add_argument("--foot-ell", type=float, default=FOOT_ELL)
    ap.add_argument("--foot-m", type=float, default=FOOT_M, help="nonlocal share of the footing cases")
    ap.add_argument("--plot", action="store_true")
    ap.add_argument("--plot-kinds", default="", help="comma list of the biaxial kinds to draw (default: all run)")
    ap.add_argument("--figure", default="fem-regularized.png", help="file name of the biaxial figure in docs/figures")
    ap.add_argument("--publish", action="store_true", help="write the published form (rows and the curves' CSV)")
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("fem_regularized.json"))
    args = ap.parse_args()
    for name in filter(None, args.cases.split(",")):
        c = (footing_case(name, args.foot_ell, args.foot_m) if is_foot(name)
             else biaxial_case(name, args.ell, args.m))
        print(f"{name}: {c['wall_s']:.1f} s wall, {c['cpu_s']:.1f} s CPU, stopped: {c['stopped']}, "
              + (f"q at 10 %: {c['q_at_10pc']}" if "q_at_10pc" in c else f"peak {c['peak_pressure']:.4g} Pa"),
              flush=True)
        # cases may run in several processes at once: merge under a lock, from the file as it is
        with open(Path(tempfile.gettempdir()) / f"{args.out.stem}.lock", "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            data, cases = load(args.out)  # the working or the published form
            data = {k: v for k, v in data.items() if k not in ("rows", "footing")}
            cases = {**cases, name: c}
            data = {**data, **provenance(__file__, args), "cases": cases, "summary": summary(cases)}
            args.out.write_text(json.dumps(data, indent=1, default=float) + "\n")
    data, cases = load(args.out)
    if args.publish:
        publish(args.out, data, cases)
    if args.plot:
        plot(cases, [k for k in args.plot_kinds.split(",") if k], args.figure)
    print(json.dumps(summary(cases), indent=1))


if __name__ == "__main__":
    main()
