"""Cyclic and static liquefaction of a loose and a dense material (alpha0 = 60° and 45°).

Cyclic: consolidation to p0 = 200 kPa, then undrained (isochoric) cycles of q between +q_cyc
and -q_cyc, 100 increments per half cycle, at cyclic stress ratios CSR = q_cyc / (2 p0) (the
2D τ_cyc/p0), up to 100 cycles. Each run records the cycle where

- the mean effective stress first falls to 5 % of p0 (``until = "p <= 0.05 * p0"``),
- the double-amplitude axial strain of a cycle first reaches 0.5 %,
- the q target can no longer be carried (the mixed-control Newton finds no strain increment:
  flow; ``stop_on_failure``), with the reason; where it happens, the run is repeated with
  ``max_events = 30`` (instead of 6) cell events per increment to tell a flow of the material
  from a limit of the Newton.

Static: undrained biaxial compression to 2 % axial strain, with the stability indicators of
``hmodel.stability.along_biaxial`` (default settings: probes tied to the increment, loading
increments counted); and the same indicators along two cyclic programs (``along_program``).

Usage: ``python -m benchmarks.liquefaction.liquefaction [--n-theta 360]``; writes ``liquefaction.json`` and
the figures ``docs/figures/liquefaction-csr-n.png``, ``docs/figures/liquefaction-static.png``.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from benchmarks.timing import FIGURES, record
from hmodel import Params
from hmodel.loading import NewtonSettings, Program
from hmodel.loading.program import cycle_summary
from hmodel.stability import along_biaxial, along_program

MATERIALS = {"loose": 60.0, "dense": 45.0}
CSR = {"loose": [0.28, 0.30, 0.31, 0.315, 0.32, 0.33, 0.35],
       "dense": [0.25, 0.26, 0.27, 0.275, 0.2775, 0.28, 0.29, 0.30, 0.32, 0.35]}
DA = 0.005
CYCLES = 100


def cyclic(alpha0: float, csr: float, n_theta: int) -> Program:
    half = [{"name": name, "preset": "undrained", "q": f"{sign}{2 * csr} * p0", "steps": 100}
            for name, sign in (("load", ""), ("unload", "-"))]
    return Program.from_dict({"name": f"cyclic undrained CSR {csr}",
                              "params": {"alpha0": alpha0, "n_theta": n_theta},
                              "stage": [{"preset": "iso", "p": "200kPa"},
                                        {"name": "cycles", "repeat": CYCLES, "until": "p <= 0.05 * p0",
                                         "stop_on_failure": True, "stages": half}]})


def _flow_cycle(res) -> int | None:
    stop = res.meta["stopped"][0] if res.meta["stopped"] else {}
    return stop.get("cycle") if "failure" in stop else None


def cyclic_row(material: str, csr: float, n_theta: int) -> dict:
    prog = cyclic(MATERIALS[material], csr, n_theta)
    res = prog.run(prog.with_params([]))
    cycles = cycle_summary(res)
    stop = res.meta["stopped"][0] if res.meta["stopped"] else {}
    # the same with 5x the cell events an increment may commit: a flow that is the Newton's
    # limit, not the material's, moves
    more = prog.run(prog.with_params([]), settings=NewtonSettings(max_events=30)) \
        if _flow_cycle(res) is not None else None
    return {"material": material, "alpha0_deg": MATERIALS[material], "CSR": csr,
            "cycles_run": len(cycles),
            "N_p_5pct": stop.get("cycle") if "until" in stop else None,
            "N_DA_0.5pct": next((c["cycle"] for c in cycles if c["double_amplitude_eps11"] >= DA), None),
            "N_flow": _flow_cycle(res),
            "N_flow_30_events": _flow_cycle(more) if more is not None else None,
            "least_p_over_p0": min(c["p_min_over_p0"] for c in cycles),
            "largest_DA_pct": 100 * max(c["double_amplitude_eps11"] for c in cycles),
            "ended_by": stop.get("failure", stop.get("until", f"{CYCLES} cycles"))}


def _num(v) -> float | None:
    """A number for JSON (None for NaN: no such point)."""
    return None if v is None or not math.isfinite(v) else float(v)


def static_row(material: str, n_theta: int):
    ps = along_biaxial(Params(alpha0=math.radians(MATERIALS[material]), n_theta=n_theta), 2e5, 0.02,
                       undrained=True)
    sh = ps.result.stage("shear")
    i = int(np.argmax(sh["q"]))
    return {"material": material, "alpha0_deg": MATERIALS[material],
            "peak_q_kPa": _num(sh["q"][i] / 1e3), "axial_strain_at_peak_pct": _num(100 * ps.shear_strain[i]),
            "q_at_2pct_kPa": _num(sh["q"][-1] / 1e3), "p_at_2pct_kPa": _num(sh["p"][-1] / 1e3),
            "bifurcation_entry_pct": _num(100 * ps.bifurcation), "entry_found_by": ps.bifurcation_by,
            "loss_of_controllability_pct": _num(100 * ps.controllability)}, ps


def cyclic_stability_row(material: str, csr: float, n_theta: int) -> dict:
    """The stability indicators along one cyclic program (rows of the result table)."""
    prog = cyclic(MATERIALS[material], csr, n_theta)
    ps = along_program(prog, prog.with_params([]))
    stop = ps.result.meta["stopped"]
    return {"material": material, "CSR": csr, "rows": len(ps.result),
            "bifurcation_entry_row": _num(ps.bifurcation_step), "entry_found_by": ps.bifurcation_by,
            "loss_of_controllability_row": _num(ps.controllability_step),
            "controllability_by": ps.controllability_by,
            "ended_by": stop[0].get("failure", stop[0].get("until")) if stop else f"{CYCLES} cycles",
            "last_row": int(ps.result["step"][-1]),
            "cycle_of_entry": int(ps.result["cycle"][ps.result["step"] == ps.bifurcation_step][0])
            if math.isfinite(ps.bifurcation_step) else None}


def plot_csr_n(rows, path):
    fig = Figure(figsize=(7.5, 4.8), layout="constrained")
    ax = fig.subplots()
    for material, color in (("loose", "tab:red"), ("dense", "tab:blue")):
        mine = [r for r in rows if r["material"] == material]
        for key, marker, label in (("N_DA_0.5pct", "o", "DA ε11 ≥ 0.5 %"), ("N_flow", "x", "q target not carried"),
                                   ("N_p_5pct", "s", "p ≤ 5 % p0")):
            pts = [(r[key], r["CSR"]) for r in mine if r[key] is not None]
            if pts:
                n, c = zip(*pts)
                ax.plot(n, c, marker, color=color, ls="-" if key == "N_DA_0.5pct" else "none",
                        mfc="none" if key != "N_flow" else None,
                        label=f"{material} (α0 = {MATERIALS[material]:g}°): {label}")
        none = [r["CSR"] for r in mine if r["N_DA_0.5pct"] is None and r["N_flow"] is None and r["N_p_5pct"] is None]
        if none:
            ax.plot([CYCLES] * len(none), none, ">", color=color, label=f"{material}: nothing in {CYCLES} cycles")
    ax.set_xscale("log")
    ax.set(xlabel="number of cycles N", ylabel="CSR = q_cyc / (2 p0)",
           title="Cyclic undrained loading, p0 = 200 kPa")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7, frameon=False)
    fig.savefig(path, dpi=130)


def plot_static(paths, path):
    fig = Figure(figsize=(12, 4.5), layout="constrained")
    a, b = fig.subplots(1, 2)
    for (material, ps), color in zip(paths.items(), ("tab:red", "tab:blue")):
        sh = ps.result.stage("shear")
        x = 100 * ps.shear_strain
        a.plot(sh["p"] / 1e3, sh["q"] / 1e3, color=color, label=f"{material} (α0 = {MATERIALS[material]:g}°)")
        b.plot(x, sh["q"] / 1e3, color=color, label=material)
        for v, ls, what in ((ps.bifurcation, "--", "bifurcation domain"), (ps.controllability, ":", "loss of controllability")):
            if math.isfinite(v):
                b.axvline(100 * v, color=color, ls=ls, lw=1, label=f"{material}: {what} ({100 * v:.3f} %)")
    a.set(xlabel="p [kPa]", ylabel="q [kPa]", title="undrained stress paths from p0 = 200 kPa")
    b.set(xlabel="axial strain since consolidation [%]", ylabel="q [kPa]", title="q and the stability indicators")
    b.set_xscale("symlog", linthresh=0.1)
    for ax in (a, b):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, frameon=False)
    fig.savefig(path, dpi=130)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-theta", type=int, default=360)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("liquefaction.json"))
    args = ap.parse_args()
    rows = []
    for material, grid in CSR.items():
        for csr in grid:
            rows.append(cyclic_row(material, csr, args.n_theta))
            print({k: (round(v, 4) if isinstance(v, float) else v) for k, v in rows[-1].items()
                   if k != "ended_by"}, flush=True)
    static, paths = [], {}
    for material in MATERIALS:
        row, paths[material] = static_row(material, args.n_theta)
        static.append(row)
        print(row, flush=True)
    along = [cyclic_stability_row("loose", 0.33, args.n_theta), cyclic_stability_row("dense", 0.28, args.n_theta)]
    for row in along:
        print(row, flush=True)
    figures = FIGURES
    plot_csr_n(rows, figures / "liquefaction-csr-n.png")
    plot_static(paths, figures / "liquefaction-static.png")
    rec = record(__file__, args, 1, [], n_theta=args.n_theta, p0_kPa=200, cycles_max=CYCLES,
                 double_amplitude_criterion_pct=100 * DA, cyclic=rows, static=static,
                 cyclic_stability=along)
    rec.pop("results")
    args.out.write_text(__import__("json").dumps(rec, indent=2) + "\n")
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
