"""What granular matter does in DEM, the judge of the H-model's pressure-dependent contacts and
critical state: assemblies of spheres (and disks) made with ``hmodel dem sample``, with linear
or Hertz-Mindlin contacts.

Parts (``--parts``, each resumable: every sample has its folder under ``--folder``, and a test
whose CSV is there is not run again):

- ``stiffness``: the same dense sample (frictionless compaction) of each contact law consolidated
  to 50, 100, 200 and 400 kPa, a drained triaxial test to a small strain at a small inertial
  number; Young's modulus E = dq/d eps_a (sigma_2, sigma_3 held) as the secant at 1e-5 and at
  1e-4 axial strain; E0 proportional to p0^n fitted by least squares in (ln p0, ln E).
- ``quasi-static``: the dense Hertz-Mindlin sample's drained test at 100 kPa at a tenth of the
  critical-state tests' inertial number, against theirs over its strain (the check that the
  faster rate is quasi-static).
- ``critical``: Hertz-Mindlin, a dense (frictionless compaction) and a loose (compaction at the
  test's friction) sample, drained triaxial compression at 100 and 400 kPa and the loose one
  undrained at 200 kPa, to 25 % axial strain; at the ends (the last 5 % of axial strain):
  M = q/p, e, p, d eps_v / d eps_a (least squares), d ln p / d eps_a; the critical state line
  e = Gamma - lambda ln(p / 1 kPa) fitted to the ends and the issue's measure (every end's q/p
  within 3 % of the mean M, |d eps_v / d eps_a| <= 0.05 in drained tests, every end within 0.01
  of the line in e).
- ``extension``: the same two samples in drained triaxial extension at 100 kPa to 25 %.
- ``disks``: the ``critical`` part with disks (``--dim 2``, biaxial tests).
- ``critical-large``: the ``critical`` part with ``--large-spheres`` spheres (how much of what
  the ends scatter is the sample's size).
- ``critical-linear``: the ``critical`` and ``extension`` parts' tests with linear contacts (the
  published H-model's law: ``--kn``, kt/kn 0.5), so that the variants with linear contacts are
  judged on an assembly with their own contact law. Its samples are kept apart from the others
  (run it with its own ``--folder``, ``--out`` and ``--block``: the collection reads one folder).

Writes ``--out`` (``granular.json``: per test the settings, YADE's wall and CPU time, the load
average when it ended, the end values; the fitted n; the critical-state measures), keeps every
test's CSV with a void-ratio column ``e`` in ``--keep``/SAMPLE/ (the ``--data`` format of
``hmodel calibrate``, with ``:e0=`` from the JSON), and with ``--docs`` rewrites the tables of
docs/dem.md between ``<!-- granular: begin -->`` and ``<!-- granular: end -->`` from the JSON.

Usage: ``python -m benchmarks.dem.granular [--parts stiffness,critical,...] [--spheres 600]
[--disks 1000] [--shear-modulus 2.9e10] [--poisson 0.2] [--inertial-number 1e-3] [--docs]``
(``--parts none``: collect what the folder holds, run nothing; ``--docs-only --docs``: the
tables from the JSON as it is).
"""

from __future__ import annotations

import argparse
import json
import os
import re
from pathlib import Path

import numpy as np

from benchmarks.timing import ROOT, command, provenance
from hmodel.dem.sample import SampleSettings, file_stem, run_sample
from hmodel.dem.sample.result import read_table

HERE = Path(__file__).resolve().parent
DOCS = ROOT / "docs" / "dem.md"
#: The markers of a block of docs/dem.md (``--block``: its name).
MARKERS = "<!-- {}: begin -->", "<!-- {}: end -->"
PARTS = ("stiffness", "quasi-static", "critical", "extension", "disks", "critical-large", "critical-linear")
#: Pressures of the stiffness series [Pa].
STIFFNESS_P0 = (5e4, 1e5, 2e5, 4e5)
#: Axial strains [-] of the two secant moduli of the stiffness series.
SECANTS = (1e-5, 1e-4)
#: Axial strain over which the ends of a test are measured.
END_STRAIN = 0.05
#: An undrained test whose p falls below this fraction of p0 has liquefied.
LIQUEFIED = 0.05
#: The issue's critical-state measure: q/p within this fraction of M, |d eps_v / d eps_a| at
#: most this, e within this of one line.
M_TOL, DILATANCY_TOL, E_TOL = 0.03, 0.05, 0.01


def samples(args) -> dict[str, tuple[str, SampleSettings, list[tuple[str, float]]]]:
    """name -> (part, settings, [(kind, p0)]) of every sample of the benchmark."""
    hertz = dict(contact="hertz-mindlin", shear_modulus=args.shear_modulus, poisson=args.poisson)
    base3 = dict(dim=3, disks=args.spheres, seed=args.seed)
    small = dict(axial_strain=args.stiffness_strain, rows=args.stiffness_rows,
                 inertial_number=args.stiffness_inertial_number)
    long = dict(axial_strain=args.axial_strain, rows=args.rows, inertial_number=args.inertial_number)
    loose = dict(compaction_friction=args.phi_g)
    drained = [("triaxial-drained", 1e5), ("triaxial-drained", 4e5)]
    out = {
        "stiffness-linear": ("stiffness", SampleSettings(**base3, **small),
                             [("triaxial-drained", p) for p in STIFFNESS_P0]),
        "stiffness-hertz": ("stiffness", SampleSettings(**base3, **small, **hertz),
                            [("triaxial-drained", p) for p in STIFFNESS_P0]),
        "quasi-static": ("quasi-static", SampleSettings(
            **base3, **hertz, axial_strain=args.quasi_static_strain,
            rows=round(args.quasi_static_strain / args.axial_strain * args.rows),
            inertial_number=args.inertial_number / 10), [("triaxial-drained", 1e5)]),
        "dense-hertz": ("critical", SampleSettings(**base3, **long, **hertz), drained),
        "loose-hertz": ("critical", SampleSettings(**base3, **long, **hertz, **loose),
                        drained + [("triaxial-undrained", 2e5)]),
    }
    # the extension tests share the critical-state samples' folders
    out["dense-hertz-extension"] = ("extension", out["dense-hertz"][1], [("triaxial-extension", 1e5)])
    out["loose-hertz-extension"] = ("extension", out["loose-hertz"][1], [("triaxial-extension", 1e5)])
    big = dict(base3, disks=args.large_spheres)
    out["dense-hertz-large"] = ("critical-large", SampleSettings(**big, **long, **hertz), drained)
    out["loose-hertz-large"] = ("critical-large", SampleSettings(**big, **long, **hertz, **loose),
                                drained + [("triaxial-undrained", 2e5)])
    linear = dict(base3, **long, kn=args.kn)
    out["dense-linear"] = ("critical-linear", SampleSettings(**linear), drained + [("triaxial-extension", 1e5)])
    out["loose-linear"] = ("critical-linear", SampleSettings(**linear, **loose),
                           drained + [("triaxial-undrained", 2e5), ("triaxial-extension", 1e5)])
    base2 = dict(dim=2, disks=args.disks, seed=args.seed, **long, **hertz)
    out["disks-dense-hertz"] = ("disks", SampleSettings(**base2), [("drained", 1e5), ("drained", 4e5)])
    out["disks-loose-hertz"] = ("disks", SampleSettings(**base2, **loose),
                                [("drained", 1e5), ("drained", 4e5), ("undrained", 2e5)])
    return out


def folder_of(name: str) -> str:
    """The folder of a sample: the extension tests live in their critical-state sample's."""
    return name.removesuffix("-extension")


def run_parts(args, defined) -> None:
    if args.parts:  # the JSON is collected by a later call: remember which calls ran the tests
        runs_path = args.folder / "runs.json"
        runs = json.loads(runs_path.read_text()) if runs_path.exists() else []
        args.folder.mkdir(parents=True, exist_ok=True)
        runs_path.write_text(json.dumps(runs + [command(__file__)], indent=1))
    loads_path = args.folder / "loads.json"
    loads = json.loads(loads_path.read_text()) if loads_path.exists() else {}
    for name, (part, settings, tests) in defined.items():
        if part not in args.parts:
            continue
        folder = args.folder / folder_of(name)
        for kind in dict.fromkeys(k for k, _ in tests):
            pressures = [p for k, p in tests if k == kind]

            def progress(msg, folder=folder):
                print(f"{folder.name}: {msg}", flush=True)
                # the machine's load when the test ended: what ran beside it
                loads[f"{folder.name}/{msg.split(':')[0]}"] = os.getloadavg()
                loads_path.write_text(json.dumps(loads, indent=1))

            args.folder.mkdir(parents=True, exist_ok=True)
            run_sample(settings, pressures, kind, folder, progress=progress)


# --------------------------------------------------------------------------- measures

def void_ratios(table: dict[str, np.ndarray], e0: float) -> np.ndarray:
    """e of every row: V = V0 exp(-eps_v) over an unchanged solid, so 1 + e = (1 + e0) exp(-eps_v)."""
    return (1.0 + e0) * np.exp(-table["eps_v"]) - 1.0


def secant(table: dict[str, np.ndarray], axial: str, strain: float) -> float:
    """E = (q - q0) / eps_a at the axial strain ``strain`` (q interpolated between rows; q0 the
    consolidated sample's small residual q, a few per cent of q at 1e-5) [Pa]."""
    return float((np.interp(strain, table[axial], table["q"]) - table["q"][0]) / strain)


def ends(table: dict[str, np.ndarray], axial: str, e: np.ndarray) -> dict:
    """The end of a test: means over its last :data:`END_STRAIN` of axial strain, and the slopes
    of eps_v and ln p against the axial strain there (least squares)."""
    a = np.abs(table[axial])
    last = a >= a[-1] - END_STRAIN
    ratio = table["q"][last] / table["p"][last]
    return {"axial_strain": float(table[axial][-1]), "M": float(np.mean(ratio)),
            "M_min": float(np.min(ratio)), "M_max": float(np.max(ratio)),
            "p": float(np.mean(table["p"][last])), "e": float(np.mean(e[last])),
            "q": float(np.mean(table["q"][last])),
            "dilatancy": float(np.polyfit(a[last], table["eps_v"][last], 1)[0]),
            "dlnp_deps": float(np.polyfit(a[last], np.log(table["p"][last]), 1)[0])}


def lowest_p(table: dict[str, np.ndarray], axial: str) -> dict:
    """Where an undrained test's p is lowest: static liquefaction when that is at the end with
    p still falling, a phase transformation when p rises again after it."""
    k = int(np.argmin(table["p"]))
    return {"p": float(table["p"][k]), "q": float(table["q"][k]), "axial_strain": float(table[axial][k]),
            "at_end": k == len(table["p"]) - 1}


def critical_state(tests: dict[str, dict], unit: float) -> dict:
    """The critical state line e = Gamma - lambda ln(p / unit) and the stress ratio M of the
    ``tests``' ends, and the issue's measure."""
    names = list(tests)
    p = np.array([tests[n]["end"]["p"] for n in names])
    e = np.array([tests[n]["end"]["e"] for n in names])
    m = np.array([abs(tests[n]["end"]["M"]) for n in names])
    slope, gamma = np.polyfit(np.log(p / unit), e, 1)
    residual = e - (gamma + slope * np.log(p / unit))
    M = float(np.mean(m))
    drained = [n for n in names if "undrained" not in tests[n]["kind"]]
    dil = max(abs(tests[n]["end"]["dilatancy"]) for n in drained)
    out = {"tests": names, "M": M, "M_spread": float(np.max(np.abs(m / M - 1.0))),
           "Gamma": float(gamma), "lambda": float(-slope), "p_unit": unit,
           "e_residual_max": float(np.max(np.abs(residual))),
           "residuals": {n: float(r) for n, r in zip(names, residual)},
           "dilatancy_max": float(dil)}
    out["measure"] = {"one_M": out["M_spread"] <= M_TOL, "zero_dilatancy": dil <= DILATANCY_TOL,
                      "one_line": out["e_residual_max"] <= E_TOL}
    out["measure"]["critical_state"] = all(out["measure"].values())
    return out


def collect(args, defined) -> dict:
    """Every test run so far, its record and end values, the fitted n and the critical states;
    the kept CSVs (with e) written on the way."""
    loads_path = args.folder / "loads.json"
    loads = json.loads(loads_path.read_text()) if loads_path.exists() else {}
    rec: dict = {"samples": {}, "tests": {}}
    for name, (part, settings, tests) in defined.items():
        folder = args.folder / folder_of(name)
        meta_path = folder / "sample.json"
        if not meta_path.exists():
            continue
        meta = json.loads(meta_path.read_text())
        rec["samples"][folder.name] = {"settings": meta["settings"], "yade_version": meta["yade_version"]}
        axial = settings.grains.axial
        for kind, p0 in tests:
            stem = file_stem(kind, p0)
            t = meta["tests"].get(stem)
            table = read_table(folder / f"{stem}.csv")
            if t is None or table is None:
                continue
            e = void_ratios(table, t["consolidated"]["void_ratio"])
            keep = args.keep / folder.name
            keep.mkdir(parents=True, exist_ok=True)
            columns = list(settings.grains.csv_columns) + ["e"]
            with open(keep / f"{stem}.csv", "w") as fh:
                fh.write(",".join(columns) + "\n")
                for k in range(len(e)):
                    fh.write(",".join(repr(float(table[c][k]) if c != "e" else float(e[k])) for c in columns) + "\n")
            entry = {"part": part, "sample": folder.name, "kind": kind, "p0": p0,
                     "csv": str((keep / f"{stem}.csv").relative_to(ROOT)),
                     "data": f"{kind}:{p0 / 1e3:g}kPa:{(keep / f'{stem}.csv').relative_to(ROOT)}"
                             f":e0={t['consolidated']['void_ratio']:.6g}",
                     "contact": meta["settings"]["contact"],
                     "e0": t["consolidated"]["void_ratio"], "porosity0": t["consolidated"]["porosity"],
                     "coordination0": t["consolidated"]["coordination"],
                     "mechanical_coordination0": t["consolidated"]["mechanical_coordination"],
                     "peak_q": t["peak_q"], "dt": t["dt"], "inertial_number": t["inertial_number"],
                     "inertial_number_max": t["inertial_number_max"],
                     "median_unbalanced_shear": t["median_unbalanced_shear"],
                     "consolidation_steps": t["consolidation_steps"], "shear_steps": t["shear_steps"],
                     "wall_s": t["wall_s"], "consolidation_wall_s": t["consolidation_wall_s"],
                     "yade_cpu_s": t["yade_cpu_s"], "load_at_end": loads.get(f"{folder.name}/{stem}")}
            if part == "stiffness":
                entry.update({f"E_secant_{s:g}": secant(table, axial, s) for s in SECANTS})
            else:
                entry["end"] = ends(table, axial, e)
            if kind.endswith("undrained"):
                entry["lowest_p"] = lowest_p(table, axial)
            rec["tests"][f"{folder.name}/{stem}"] = entry
    rec["stiffness"] = {}
    for law in ("linear", "hertz"):
        rows = [t for t in rec["tests"].values() if t["sample"] == f"stiffness-{law}"]
        if len(rows) < 2:
            continue
        p0 = np.array([t["p0"] for t in rows])
        fit = {}
        for s in SECANTS:
            E = np.array([t[f"E_secant_{s:g}"] for t in rows])
            fit[f"n_secant_{s:g}"] = float(np.polyfit(np.log(p0), np.log(E), 1)[0])
        rec["stiffness"][law] = {"p0": p0.tolist(), **fit,
                                 "E_400_over_E_100_secant_1e-4": _ratio(rows, 4e5, 1e5, "E_secant_0.0001")}
    qs = rec["tests"].get("quasi-static/triaxial-drained_100kPa")
    fast = rec["tests"].get("dense-hertz/triaxial-drained_100kPa")
    if qs and fast:
        a = read_table(args.folder / "quasi-static" / "triaxial-drained_100kPa.csv")
        b = read_table(args.folder / "dense-hertz" / "triaxial-drained_100kPa.csv")
        n = len(a["q"])
        rec["quasi_static"] = {
            "strain": float(a["eps_a"][-1]), "I_slow": qs["inertial_number"], "I_fast": fast["inertial_number"],
            "max_dq_over_peak": float(np.max(np.abs(a["q"] - b["q"][:n])) / abs(fast["peak_q"])),
            "rms_dq_over_peak": float(np.sqrt(np.mean((a["q"] - b["q"][:n]) ** 2)) / abs(fast["peak_q"])),
            "peak_q_slow": qs["peak_q"], "peak_q_fast_same_strain": float(np.max(b["q"][:n])),
            "eps_v_end_slow": float(a["eps_v"][-1]), "eps_v_end_fast": float(b["eps_v"][n - 1])}
    rec["critical_state"] = {}
    for label, names in ((f"spheres ({args.spheres})", ("dense-hertz", "loose-hertz")),
                         (f"spheres ({args.large_spheres})", ("dense-hertz-large", "loose-hertz-large")),
                         (f"disks ({args.disks})", ("disks-dense-hertz", "disks-loose-hertz")),
                         (f"spheres ({args.spheres}), linear contacts", ("dense-linear", "loose-linear"))):
        chosen = {k: t for k, t in rec["tests"].items()
                  if t["sample"] in names and "extension" not in t["kind"]}
        if len(chosen) >= 3:
            rec["critical_state"][label] = critical_state(chosen, 1e3)
            # an undrained test that liquefied recovers at a large inertial number: the drained ends alone
            drained = {k: t for k, t in chosen.items() if "undrained" not in t["kind"]}
            rec["critical_state"][label]["drained_only"] = critical_state(drained, 1e3)
    rec["results"] = results(rec)
    return rec


def results(rec: dict) -> list[dict]:
    """The main figures as (measure, value, target) records: the benchmarks page's table. The
    issue's critical-state measure is the model's target; here it describes the DEM samples, so
    it is written as text (no verdict counted on the page; docs/dem.md says met or missed)."""
    rows = []
    for law, label in (("linear", "linear contacts"), ("hertz", "Hertz-Mindlin")):
        for s in SECANTS:
            if law in rec["stiffness"]:
                rows.append((f"stiffness, {label}: n of E0 ~ p0^n (secant at {s:g})",
                             rec["stiffness"][law][f"n_secant_{s:g}"], "-"))
    if "quasi_static" in rec:
        rows.append(("quasi-static check: RMS |dq| / peak q, I and I/10, drained 100 kPa",
                     rec["quasi_static"]["rms_dq_over_peak"], "-"))
    for label, cs in rec["critical_state"].items():
        rows += [(f"critical state, {label}: M (mean q/p at the ends)", cs["M"], "-"),
                 (f"critical state, {label}: largest |q/p / M - 1| at the ends", cs["M_spread"], f"issue's measure <= {M_TOL:g}"),
                 (f"critical state, {label}: largest drained |d eps_v / d eps_a| at the ends",
                  cs["dilatancy_max"], f"issue's measure <= {DILATANCY_TOL:g}"),
                 (f"critical state, {label}: largest |e - (Gamma - lambda ln p)| at the ends",
                  cs["e_residual_max"], f"issue's measure <= {E_TOL:g}"),
                 (f"critical state, {label}: lambda", cs["lambda"], "-")]
    rows.append(("YADE CPU time of every test [s]", sum(t["yade_cpu_s"] for t in rec["tests"].values()), "-"))
    rows.append(("YADE wall time of every test [s]", sum(t["wall_s"] for t in rec["tests"].values()), "-"))
    return [{"measure": m, "value": v, "target": t} for m, v, t in rows]


def _ratio(rows, a, b, key):
    by = {t["p0"]: t[key] for t in rows}
    return by[a] / by[b] if a in by and b in by else None


# --------------------------------------------------------------------------- docs

def _f(x, digits=3):
    return "—" if x is None else f"{x:.{digits}g}"


def _line(cs: dict) -> str:
    """The critical state line e = Gamma - lambda ln(p / kPa), written with the sign lambda has."""
    lam = cs["lambda"]
    return f"{cs['Gamma']:.3f} {'−' if lam >= 0 else '+'} {abs(lam):.4f} ln(p/kPa)"


def render(rec: dict) -> str:
    """The markdown tables of docs/dem.md's Hertz-Mindlin section, from the JSON."""
    lines = []
    st = rec.get("stiffness", {})
    if st:
        lines += ["| contacts | E at 1e-5, 50 / 100 / 200 / 400 kPa [MPa] | n (1e-5) | "
                  "E at 1e-4 [MPa] | n (1e-4) | E(400) / E(100) at 1e-4 |", "|---|---|---|---|---|---|"]
        for law, label in (("linear", "linear"), ("hertz", "Hertz–Mindlin")):
            if law not in st:
                continue
            rows = sorted((t for t in rec["tests"].values() if t["sample"] == f"stiffness-{law}"),
                          key=lambda t: t["p0"])
            e5 = " / ".join(f"{t['E_secant_1e-05'] / 1e6:.0f}" for t in rows)
            e4 = " / ".join(f"{t['E_secant_0.0001'] / 1e6:.0f}" for t in rows)
            s = st[law]
            lines.append(f"| {label} | {e5} | {s['n_secant_1e-05']:.3f} | {e4} | {s['n_secant_0.0001']:.3f} "
                         f"| {_f(s['E_400_over_E_100_secant_1e-4'])} |")
        lines.append("")
    qs = rec.get("quasi_static")
    if qs:
        lines += [f"Quasi-static check: the dense sample's drained test at 100 kPa at I = {qs['I_slow']:.2g} "
                  f"against I = {qs['I_fast']:.2g} over its first {100 * qs['strain']:.0f} %: q differs by "
                  f"{100 * qs['rms_dq_over_peak']:.1f} % of peak q (RMS; at most "
                  f"{100 * qs['max_dq_over_peak']:.1f} %), "
                  f"εv at {100 * qs['strain']:.0f} % {100 * qs['eps_v_end_slow']:.2f} % against "
                  f"{100 * qs['eps_v_end_fast']:.2f} %.", ""]
    for label, cs in rec.get("critical_state", {}).items():
        lines += [f"| {label}: test | e0 | at the end: q/p | e | p [kPa] | dεv/dε1 | d ln p/dε1 | "
                  f"e − CSL | YADE wall (CPU) [s] |", "|---|---|---|---|---|---|---|---|---|"]
        for n in cs["tests"]:
            t, end = rec["tests"][n], rec["tests"][n]["end"]
            lines.append(f"| {t['sample']} {t['kind']} {t['p0'] / 1e3:g} kPa | {t['e0']:.3f} | {end['M']:.3f} "
                         f"| {end['e']:.3f} | {end['p'] / 1e3:.0f} | {end['dilatancy']:+.3f} | "
                         f"{end['dlnp_deps']:+.2f} | {cs['residuals'][n]:+.4f} | "
                         f"{t['wall_s']:.0f} ({t['yade_cpu_s']:.0f}) |")
        for n in cs["tests"]:
            low = rec["tests"][n].get("lowest_p")
            if low:
                t = rec["tests"][n]
                what = ("p still falling at the end" if low["at_end"] else
                        "static liquefaction (p below 5 % of p0), then p rising again"
                        if low["p"] < LIQUEFIED * t["p0"] else "p rising again after it (a phase transformation)")
                lines += ["", f"{t['sample']} {t['kind']} {t['p0'] / 1e3:g} kPa: lowest p {low['p'] / 1e3:.1f} kPa "
                              f"(q {low['q'] / 1e3:.1f} kPa) at ε1 = {100 * abs(low['axial_strain']):.1f} %, {what}; "
                              f"the inertial number there {t['inertial_number_max']:.2g} (at p0 "
                              f"{t['inertial_number']:.2g})."]
        m = cs["measure"]
        lines += ["", f"{label.capitalize()}: M = {cs['M']:.3f} (ends within ±{100 * cs['M_spread']:.1f} %, "
                      f"target ±{100 * M_TOL:g} %: {'met' if m['one_M'] else 'missed'}); critical state line "
                      f"e = {_line(cs)}, ends within "
                      f"{cs['e_residual_max']:.4f} (target {E_TOL:g}: {'met' if m['one_line'] else 'missed'}); "
                      f"largest drained |dεv/dε1| {cs['dilatancy_max']:.3f} (target {DILATANCY_TOL:g}: "
                      f"{'met' if m['zero_dilatancy'] else 'missed'})."]
        d = cs["drained_only"]
        lines += [f"The drained ends alone: M = {d['M']:.3f} (within ±{100 * d['M_spread']:.1f} %), "
                  f"e = {_line(d)} (within {d['e_residual_max']:.4f}).", ""]
    ext = [t for t in rec["tests"].values() if t["kind"] == "triaxial-extension"]
    if ext:
        lines += ["| extension test | e0 | at the end: q/p | e | p [kPa] | dεv/dε1 | YADE wall (CPU) [s] |",
                  "|---|---|---|---|---|---|---|"]
        for t in ext:
            end = t["end"]
            lines.append(f"| {t['sample']} {t['p0'] / 1e3:g} kPa | {t['e0']:.3f} | {end['M']:.3f} | {end['e']:.3f} "
                         f"| {end['p'] / 1e3:.0f} | {end['dilatancy']:+.3f} | "
                         f"{t['wall_s']:.0f} ({t['yade_cpu_s']:.0f}) |")
        lines.append("")
    return "\n".join(lines).rstrip() + "\n"


def write_docs(rec: dict, block: str = "granular", path: Path = DOCS) -> None:
    begin, end = (m.format(block) for m in MARKERS)
    text = path.read_text()
    pattern = re.compile(re.escape(begin) + r".*?" + re.escape(end), re.S)
    if not pattern.search(text):
        raise SystemExit(f"{path}: no {begin} ... {end} block")
    path.write_text(pattern.sub(lambda m: f"{begin}\n{render(rec)}{end}", text))


def parser() -> argparse.ArgumentParser:
    """The benchmark's options; ``parser().parse_args([])`` gives the defaults that define its
    samples (:func:`samples`), for another script that reruns one of them."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", default=",".join(PARTS), help="comma list of " + ", ".join(PARTS) + ", or none")
    ap.add_argument("--spheres", type=int, default=600)
    ap.add_argument("--large-spheres", type=int, default=1200, help="spheres of part critical-large")
    ap.add_argument("--disks", type=int, default=1000)
    ap.add_argument("--shear-modulus", type=float, default=2.9e10, help="G of the grains [Pa] (quartz)")
    ap.add_argument("--poisson", type=float, default=0.2)
    ap.add_argument("--phi-g", type=float, default=30.0, help="the loose samples' compaction friction [deg]")
    ap.add_argument("--axial-strain", type=float, default=0.25)
    ap.add_argument("--rows", type=int, default=250)
    ap.add_argument("--inertial-number", type=float, default=1e-3)
    ap.add_argument("--quasi-static-strain", type=float, default=0.05)
    ap.add_argument("--stiffness-strain", type=float, default=2e-4)
    ap.add_argument("--stiffness-rows", type=int, default=20)
    ap.add_argument("--stiffness-inertial-number", type=float, default=1e-5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--folder", type=Path, default=ROOT / "results" / "dem-granular",
                    help="working folder (npz files included; not kept in the repository)")
    ap.add_argument("--keep", type=Path, default=HERE / "granular")
    ap.add_argument("--out", type=Path, default=HERE / "granular.json")
    ap.add_argument("--kn", type=float, default=2e8, help="kn of the linear samples of part critical-linear [N/m]")
    ap.add_argument("--docs", action="store_true", help="rewrite docs/dem.md's tables from the JSON")
    ap.add_argument("--block", default="granular", help="the docs/dem.md block --docs rewrites "
                    "(<!-- BLOCK: begin --> ... <!-- BLOCK: end -->)")
    ap.add_argument("--docs-only", action="store_true", help="run and collect nothing: the tables "
                                                               "from --out as it is (with --docs)")
    return ap


def main() -> None:
    ap = parser()
    args = ap.parse_args()
    args.parts = [] if args.parts == "none" else [p.strip() for p in args.parts.split(",")]
    unknown = set(args.parts) - set(PARTS)
    if unknown:
        ap.error(f"unknown part(s) {', '.join(sorted(unknown))}")
    if args.docs_only:
        rec = json.loads(args.out.read_text())
    else:
        defined = samples(args)
        run_parts(args, defined)
        rec = {**provenance(__file__, args), **collect(args, defined)}
        runs_path = args.folder / "runs.json"
        if runs_path.exists():
            rec["command_note"] = "tests run by " + "; ".join(json.loads(runs_path.read_text()))
        args.out.write_text(json.dumps(rec, indent=1) + "\n")
        print(f"written {args.out}")
    print(render(rec))
    if args.docs:
        write_docs(rec, args.block)
        print(f"rewrote {DOCS}'s tables")


if __name__ == "__main__":
    main()
