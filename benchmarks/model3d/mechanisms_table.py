"""The tables of docs/mechanisms.md, generated from benchmark JSON files:

- ``mechanisms-table``: the critical-state and π-plane figures of the 3D H-model with each cell
  mechanism on and off (``benchmarks.model3d.critical_state`` and ``benchmarks.model3d.pi_plane``
  run with ``--mechanisms ... --tag TAG``; no tag: the published model; tag ``sand_kfs``: with
  ``--kfs axisym_mix``, the sand variant at its Karlsruhe fine sand calibration);
- ``mechanisms-pi-kfs``: the π-plane of the sand variant at its KFS calibration for the sand's
  densest specimen, its reference void ratio and its loosest specimen (``benchmarks.model3d.pi_plane
  --kfs axisym_mix [--e0 densest|loosest] --tag sand_kfs[_densest|_loosest]``);
- ``mechanisms-kfs``: Karlsruhe fine sand, each variant calibrated on TMD12/TMD14 and predicting
  the 25 tests (``benchmarks.calibration.kfs --model NAME --tag TAG``), and the peer
  (``benchmarks.calibration.kfs_peer``);
- ``mechanisms-kfs-long``: each variant's KFS calibration run again at a ten times finer step and
  on to 50 % axial strain (``benchmarks.calibration.kfs_long``);
- ``mechanisms-dem``: the small-strain stiffness of DEM sphere assemblies against pressure
  (``benchmarks.dem.granular``);
- ``mechanisms-dem-fabric``: the coordination number and sliding fraction of the DEM samples'
  drained tests, dense and loose, at the start and the end (``benchmarks.dem.granular``'s kept
  CSVs);
- ``mechanisms-dem-bihex``: the bi-hexagon with and without contacts between its hexagons
  against the DEM bi-hexagon whose hexagons touch, frictionless and frictional
  (``benchmarks.dem.dem_bihex_cross``);
- ``mechanisms-critical-2d``: the 2D REV's critical state with and without ``renewal=mix``
  (``benchmarks.mechanisms.critical_state_2d``);
- ``mechanisms-dem-judge``: each variant calibrated on two drained tests of DEM sphere samples and
  predicting the others (``benchmarks.calibration.calibrate3d_dem ... --model NAME``);
  ``mechanisms-dem-judge-2d``: the same of the 2D model on the DEM disk samples;
- the figures ``hertz-cost-*`` within sentences: a cell's cost with Hertz-Mindlin contacts and
  with the other mechanisms over the published cell's (``benchmarks.engine.engine``,
  ``benchmarks.engine.engine3d``).

Usage: ``python -m benchmarks.model3d.mechanisms_table`` rewrites each block between its markers
``<!-- NAME -->`` and ``<!-- /NAME -->`` in docs/mechanisms.md; ``--check`` exits 1 when a block
of the page differs from what the JSON files give (the test suite runs it, so the page cannot
keep a stale number).
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import sys
from pathlib import Path

HERE = Path(__file__).parent
PAGE = HERE.parents[1] / "docs" / "mechanisms.md"
#: (tag, what is on), in the table's order.
VARIANTS = (("", "published (none)"), ("hertz", "Hertz–Mindlin contacts"), ("rebirth", "rebirth"),
            ("hertz_rebirth", "Hertz–Mindlin + rebirth"), ("mix", "rebirth at the mean box (renewal=mix)"),
            ("cross", "contacts between the hexagons"),
            ("hertz_cross", "Hertz–Mindlin + contacts between the hexagons"),
            ("axisym", "lateral strain about the axis (lateral=axisymmetric)"),
            ("axisym_mix", "lateral=axisymmetric + rebirth at the mean box"),
            ("hertz_axisym_mix", "Hertz–Mindlin + lateral=axisymmetric + rebirth at the mean box (sand)"),
            ("sand_kfs", "the sand variant at its Karlsruhe fine sand calibration"),
            ("kt0889", "control: linear, kt/kn = 0.889 (Mindlin's ratio at ν = 0.2)"))
#: The issue's measure of a critical state: q/p within ±3 % of one M, |dε_v/dε₁| ≤ 0.05.
QP_BAND, RATE_MAX = 0.03, 0.05
#: A phase transformation's fall of p first: to 90 % of p₀ or below (:func:`phase_transformation`).
PT_FALL = 0.9


def _table(head: str, rows) -> str:
    """A Markdown table: the header row ``head`` (``| a | b |``, escaped pipes ``\\|`` inside
    cells), its separator and the ``rows``."""
    columns = head.count("|") - head.count("\\|") - 1
    return "\n".join([head, "|---" * columns + "|", *rows])


def _load(name: str, tag: str) -> dict | None:
    path = HERE / (f"{name}_{tag}.json" if tag else f"{name}.json")
    return json.loads(path.read_text()) if path.exists() else None


def _from_record(rel: str):
    """A block made from one benchmark record, ``benchmarks/REL``: the decorated function takes
    the record; the block says so where it is not written yet."""
    def wrap(make):
        @functools.wraps(make)
        def block() -> str:
            path = HERE.parent / rel
            if not path.exists():
                return f"(benchmarks/{rel} not written yet)"
            return make(json.loads(path.read_text()))
        return block
    return wrap


def _result(rec: dict, start: str) -> float:
    for r in rec["results"]:
        if r["measure"].startswith(start):
            return float(r["value"])
    return math.nan


def _sides(radial: str | None) -> str:
    """What a row's label says of how its drained triaxial tests held their sides: nothing for
    the preset (each lateral stress held), ", one radial strain" for ``radial="equal"``."""
    return ", one radial strain" if radial == "equal" else ""


def phase_transformation(r: dict) -> bool:
    """Whether an undrained test's p fell by at least 10 % of p₀ and then rose again by at
    least 5 % of its lowest value (``critical_state``'s ``p_rises_after_min``, the 2D
    benchmark's criterion): the turn of a loose sand's undrained path; a test that stops
    where Newton fails a few percent of p₀ below its start is not counted."""
    return r["p_min_over_p0"] <= PT_FALL and r["p_rises_after_min"]


def _at_sand(cs: dict) -> str:
    """What a row run at a KFS calibration (``critical_state --kfs``) adds to its label: the
    specimens whose e0 set its dense and loose α0."""
    cal = cs.get("calibration")
    if not cal:
        return ""
    alpha = {r["state"]: r["alpha0"] for r in cs["table"]}
    return (", dense and loose at the sand's densest and loosest specimens ("
            + ", ".join(f"{cal['specimens'][s][0]}: e0 {cal['specimens'][s][1]:.3f}, α0 {alpha[s]:.1f}°"
                        for s in ("dense", "loose")) + ")")


def row(tag: str, label: str) -> str | None:
    cs, pi = _load("critical_state", tag), _load("pi_plane", tag)
    if cs is None and pi is None:
        return None
    ratio = _result(pi, "strength ratio") if pi else math.nan
    mc = _result(pi, "M_c") if pi else math.nan
    if cs is None:
        return f"| {label} | — | — | — | — | — | — | — | {mc:.3f} | {ratio:.3f} |"
    label += _sides(cs.get("radial") or cs["options"].get("radial")) + _at_sand(cs)
    table = cs["table"]
    reached = [r for r in table if not r["newton_failed"]]
    qp = [r["q_p_end"] for r in reached]
    m = sum(qp) / len(qp) if qp else math.nan
    within = sum(abs(q / m - 1) <= QP_BAND for q in qp) if qp else 0
    drained = [r for r in table if r["test"] == "drained"]
    steady = sum(abs(r["deps_v_deps11_end"]) <= RATE_MAX for r in drained if not r["newton_failed"])
    loose_u = [r for r in table if r["test"] == "undrained" and r["state"] == "loose"]
    low = min((r["p_min_over_p0"] for r in loose_u), default=math.nan)
    turned = sum(phase_transformation(r) for r in loose_u)
    return (f"| {label} | {len(reached)} of {len(table)} | {min(qp):.3f}–{max(qp):.3f} | {within} of {len(reached)} "
            f"| {max(abs(r['deps_v_deps11_end']) for r in drained):.3f} | {steady} of {len(drained)} "
            f"| {_result(cs, 'ends off one line in (ln p, nu), macro'):.3f} / "
            f"{_result(cs, 'ends off one line in (ln p, nu), the cells'):.3f} / "
            f"{_result(cs, 'ends off one line in (ln p, nu), box measure'):.3f}"
            f"{'' if len(reached) == len(table) else f' (the {len(reached)} that reached it)'} "
            f"| {low:.2f}; {turned} of {len(loose_u)} | {mc:.3f} | {ratio:.3f} |")


def _median(values) -> float:
    v = sorted(x for x in values if x is not None)
    n = len(v)
    return math.nan if not n else (v[n // 2] if n % 2 else 0.5 * (v[n // 2 - 1] + v[n // 2]))


#: (JSON file, label) of the KFS block, in its order.
KFS = (("kfs.json", "H-model, density (linear contacts)"), ("kfs_hertz.json", "H-model, hertz"),
       ("kfs_rebirth.json", "H-model, rebirth (Hertz–Mindlin + rebirth)"),
       ("kfs_mix.json", "H-model, mix (Hertz–Mindlin + rebirth at the mean box)"),
       ("kfs_cross.json", "H-model, cross (Hertz–Mindlin + contacts between the hexagons)"),
       ("kfs_axisym.json", "H-model, axisym (Hertz–Mindlin + lateral strain about the axis)"),
       ("kfs_axisym_mix.json", "H-model, axisym-mix (axisym + rebirth at the mean box)"),
       ("kfs_peer.json", "Manzari–Dafalias (OpenSees), the peer"))


def kfs_block() -> str:
    rows = []
    for name, label in KFS:
        path = HERE.parent / "calibration" / name
        if not path.exists():
            continue
        rec = json.loads(path.read_text())
        tests = rec["tests"]
        label += _sides(rec.get("calibration", {}).get("model", {}).get("radial"))
        dq = [t["rms_dq"] for t in tests]
        dv = [t["rms_dev"] for t in tests]
        full = [t for t in tests if t["rms_dq"] is not None and t.get("reached", 0.2) >= 0.199]
        both = sum(t["rms_dq"] <= 0.10 and t["rms_dev"] <= 0.005 for t in full)
        within = sum(t["rms_dq"] <= 0.10 for t in full)
        fin = [x for x in dq if x is not None]
        rows.append(f"| {label} | {100 * _median(dq):.1f} | {100 * min(fin):.1f}–{100 * max(fin):.1f} "
                    f"| {within} of {len(tests)} | {100 * _median(dv):.2f} | {both} of {len(tests)} "
                    f"| {len(tests) - len(full)} |")
    return _table("| model | median RMS \\|Δq\\|/peak q [%] | range [%] | within 10 % (to 20 %) | "
                  "median RMS Δε_v [% strain] | within both targets | tests ended early |",
                  rows)


@_from_record("calibration/kfs_long.json")
def kfs_long_block(rec: dict) -> str:
    strain = rec["options"]["strain"]
    rows = []
    for name, v in rec["variants"].items():
        a, b = v["at_step"], v["at_step_over_10"]
        through = [r for r in v["long"] if r["reached"] >= strain - 1e-9]
        rate = [abs(r["deps_v_deps11_end"]) for r in through]
        qp = [r["q_p_end"] for r in through]
        e = [r["e_end"] for r in through]
        rows.append(f"| {name}{_sides(v.get('radial'))} | {100 * a['median_rms_dq']:.1f} / {100 * b['median_rms_dq']:.1f} "
                    f"| {a['within_10']} / {b['within_10']} | {a['ended_early']} / {b['ended_early']} "
                    f"| {100 * v['largest_change_rms_dq']:.1f} | {len(through)} of {len(v['long'])} "
                    f"| {min(rate):.2f}–{max(rate):.2f} | {min(qp):.2f}–{max(qp):.2f} | {min(e):.2f}–{max(e):.2f} |")
    sand = rec["variants"][next(iter(rec["variants"]))]["long"]
    rows.append(f"| the sand, at 20 % (its tests end there) | | | | | | | {min(r['sand_q_p_end'] for r in sand):.2f}–"
                f"{max(r['sand_q_p_end'] for r in sand):.2f} | {min(r['sand_e_end'] for r in sand):.2f}–"
                f"{max(r['sand_e_end'] for r in sand):.2f} |")
    return _table("| variant | median RMS \\|Δq\\|/peak q [%], step / step ÷ 10 | within 10 % | ended early "
                  "| largest change of one test [points] "
                  f"| tests to {100 * strain:.0f} % | \\|dε_v/dε₁\\| at the end | q/p at the end | e at the end |",
                  rows)


#: (label, dense sample, loose sample) of the fabric block: kept CSVs of benchmarks/dem/granular.
FABRIC = (("Hertz–Mindlin, 600 spheres", "dense-hertz", "loose-hertz"),
          ("Hertz–Mindlin, 1,200 spheres", "dense-hertz-large", "loose-hertz-large"),
          ("linear, 600 spheres", "dense-linear", "loose-linear"))
#: Axial strain over which a DEM test's end values are averaged (as benchmarks.dem.granular's).
FABRIC_END = 0.05


def _fabric_ends(path: Path) -> tuple[float, float, float]:
    """(coordination at the start, its mean and the sliding fraction's over the last
    :data:`FABRIC_END` of axial strain) of a kept DEM test."""
    import numpy as np

    t = np.genfromtxt(path, delimiter=",", names=True)
    a = np.abs(t["eps_a"])
    last = a >= a[-1] - FABRIC_END
    return float(t["coordination"][0]), float(t["coordination"][last].mean()), float(t["sliding"][last].mean())


def dem_fabric_block() -> str:
    folder = HERE.parent / "dem" / "granular"
    rows = []
    for label, dense, loose in FABRIC:
        for test in ("triaxial-drained_100kPa", "triaxial-drained_400kPa"):
            d, lo = folder / dense / f"{test}.csv", folder / loose / f"{test}.csv"
            if not (d.exists() and lo.exists()):
                continue
            (z0d, zd, sd), (z0l, zl, sl) = _fabric_ends(d), _fabric_ends(lo)
            rows.append(f"| {label} | {test.rpartition('_')[2].replace('kPa', ' kPa')} | {z0d:.2f} → {zd:.2f} "
                        f"| {z0l:.2f} → {zl:.2f} | {sd:.3f} / {sl:.3f} |")
    return _table("| samples | drained at | dense: coordination z, start → end | loose: the same | "
                  "sliding contacts at the end, dense / loose |", rows)


@_from_record("dem/granular.json")
def dem_block(rec: dict) -> str:
    rows = []
    for law, label in (("linear", "linear (kn, kt)"), ("hertz", "Hertz–Mindlin")):
        st = rec.get("stiffness", {}).get(law)
        if st:
            rows.append(f"| DEM spheres, {label} | {st['n_secant_0.0001']:.3f} "
                        f"| {st['E_400_over_E_100_secant_1e-4']:.3f} |")
    rows += ["| H-model, linear contacts (fixed fabric, by construction) | 0 | 1 |",
             f"| H-model, Hertz–Mindlin (fixed fabric, by construction) | {1 / 3:.3f} | {4 ** (1 / 3):.3f} |"]
    return _table("| assembly / model | n in E₀ ∝ p^n (50–400 kPa) | E₀(400 kPa)/E₀(100 kPa) |",
                  rows)


def _sci(x: float) -> str:
    """x with two significant digits, as 1.3·10⁻⁴ below 10⁻², else 0.061."""
    if x >= 1e-2:
        return f"{x:.2g}" if x < 1 else f"{x:.2f}"
    m, e = f"{x:.1e}".split("e")
    sup = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")
    return f"{m}·10{str(int(e)).translate(sup)}"


@_from_record("dem/dem_bihex_cross.json")
def dem_bihex_block(rec: dict) -> str:
    runs = rec["paths"]
    rows = []
    for friction, label in ((False, "frictionless"), (True, "friction 30°")):
        for name in dict.fromkeys(r["path"] for r in runs):
            got = {r["closed_form_cross_contacts"]: r for r in runs
                   if r["path"] == name and r["dem_cross_friction"] == friction}
            if not got["frictionless"]["cross_steps"]:
                continue
            rows.append(f"| {name} | {label} | {_sci(got['frictionless']['dev_force'])} | "
                        f"{_sci(got['none']['dev_force'])} | {_sci(got['frictionless']['dev_stress'])} | "
                        f"{_sci(got['none']['dev_stress'])} |")
    return _table("| path (cross contacts touch) | DEM's cross contacts | max \\|ΔF\\|/max \\|F\\|, closed form "
                  "with cross contacts | without | max \\|ΔVσ\\|/max \\|Vσ\\|, with | without |",
                  rows)


#: (JSON file, label) of the DEM judge's block, in its order: the Hertz-Mindlin sphere samples
#: (dense and loose, one parameter set), the linear-contact ones (benchmarks/dem/granular_linear.json),
#: and the linear sample of the 3D calibration page.
DEM_JUDGE = (("dem_judge_density.json", "density (linear contacts)"),
             ("dem_judge_density_linear.json", "density, on the linear-contact samples"),
             ("dem_judge_density_axisym_linear.json",
              "density + lateral strain about the axis, on the linear-contact samples"),
             ("dem_judge_density_axisym_mix_linear.json",
              "density + lateral strain about the axis + rebirth at the mean box, on the linear-contact samples"),
             ("dem_judge_hertz.json", "hertz"),
             ("dem_judge_rebirth.json", "rebirth (Hertz–Mindlin + rebirth)"),
             ("dem_judge_mix.json", "mix (Hertz–Mindlin + rebirth at the mean box)"),
             ("dem_judge_cross.json", "cross (Hertz–Mindlin + contacts between the hexagons)"),
             ("dem_judge_axisym.json", "axisym (Hertz–Mindlin + lateral strain about the axis)"),
             ("dem_judge_axisym_mix.json", "axisym-mix (axisym + rebirth at the mean box)"),
             ("calibrate3d_dem.json", "published, on the linear 1,000-sphere sample"))
#: The issue's targets of a prediction: RMS |Δq| / peak q of drained tests, of the others.
DRAINED_TARGET, OTHER_TARGET = 0.10, 0.15


def _pct(values) -> str:
    return ", ".join(f"{100 * v:.0f}" for v in values) if values else "—"


#: The same of the 2D model on the DEM disk samples (Hertz-Mindlin, dense and loose:
#: benchmarks/dem/granular/disks-*-hertz), no extension test there.
DEM_JUDGE_2D = (("dem_judge2d_density.json", "density (linear contacts)"),
                ("dem_judge2d_hertz.json", "hertz"),
                ("dem_judge2d_rebirth.json", "rebirth (Hertz–Mindlin + rebirth)"),
                ("dem_judge2d_mix.json", "mix (Hertz–Mindlin + rebirth at the mean box; the sand variant in 2D)"))


def judged_kind(name: str) -> str:
    """A DEM judge's test (FOLDER/STEM) as the table counts it: ``drained``, ``undrained`` or
    ``extension``, triaxial (3D) or biaxial (2D) alike.

    >>> [judged_kind(n) for n in ("a/triaxial-drained_100kPa", "undrained_200kPa", "b/drained_400kPa")]
    ['drained', 'undrained', 'drained']
    """
    return name.rpartition("/")[2].partition("_")[0].removeprefix("triaxial-")


def dem_judge_rows(judges) -> list[str]:
    rows = []
    for name, label in judges:
        path = HERE.parent / "calibration" / name
        if not path.exists():
            continue
        rec = json.loads(path.read_text())
        label += _sides(rec.get("calibration", {}).get("model", {}).get("radial"))
        errs = rec["errors"]
        failed = [r["measure"] for r in rec["results"] if "the model's test failed" in r["measure"]]
        fit = [e["rms_dq"] for e in errs.values() if e["how"] == "calibrated on"]
        pred = {n: e for n, e in errs.items() if e["how"] == "predicted"}
        kinds = {k: [e["rms_dq"] for n, e in pred.items() if judged_kind(n) == k]
                 for k in ("drained", "undrained", "extension")}
        within = (sum(v <= DRAINED_TARGET for v in kinds["drained"])
                  + sum(v <= OTHER_TARGET for v in kinds["undrained"] + kinds["extension"]))
        dv = [e["rms_deps_v"] for e in errs.values() if "rms_deps_v" in e]
        rows.append(f"| {label} | {_pct(fit)} | {_pct(kinds['drained'])} | {_pct(kinds['undrained'])} "
                    f"| {_pct(kinds['extension'])} | {within} of {len(pred) + len(failed)} "
                    f"| {100 * max(dv):.1f} |")
    return rows


JUDGE_HEAD = ("| variant | RMS \\|Δq\\|/peak q [%]: calibrated on (2 drained) | predicted drained | "
              "predicted undrained | predicted extension | predictions within target (10 %; 15 % undrained "
              "and extension) | largest RMS Δε_v [% strain] |")


def dem_judge_block() -> str:
    return _table(JUDGE_HEAD, dem_judge_rows(DEM_JUDGE))


def dem_judge_2d_block() -> str:
    return _table(JUDGE_HEAD, dem_judge_rows(DEM_JUDGE_2D))


@_from_record("mechanisms/critical_state_2d.json")
def critical_2d_block(rec: dict) -> str:
    from hmodel import Params
    from hmodel.cell.renewal import NEUTRAL_2D, box_at_contact

    # the box measure against the largest unloaded cell's (at the neutral angle)
    neutral = box_at_contact(NEUTRAL_2D, 2.0 * rec["base"].get("radius", Params().radius), 2) / rec["box_ref"]
    rows = []
    for name, v in rec["verdicts"].items():
        renewal, _, strain = name.partition(" to ")
        mine = [r for r in rec["table"]
                if r["renewal"] == renewal and r["strain"] == float(strain) and not r["newton_failed"]]
        qp = [r["q_p_end"] for r in mine]
        box = [r["nu_box_end"] / neutral for r in mine]
        drop = [f"{100 * p:.0f}" for p in v["loose_undrained_p_min_over_p0"]]
        rows.append(f"| {renewal} | {100 * float(strain):.0f} % | {v['tests_at_end']} of {v['tests']} | "
                    f"{min(qp):.2f}–{max(qp):.2f} | {v['M']:.3f} | {100 * v['q_p_end_max_off_M']:.1f} % | "
                    f"{v['deps_v_deps11_max']:.3f} | {v['line_box']:.4f} | {min(box):.3f}–{max(box):.3f} | "
                    f"{v['line_macro']:.3f} | "
                    f"{', '.join(drop)} % | "
                    f"{'yes' if all(v['loose_undrained_p_rises_after_min']) else 'no'} |")
    return _table("| renewal | axial strain | tests to the end | q/p at the end | M (their mean) | largest "
                  f"\\|q/p / M − 1\\| (target {100 * QP_BAND:.0f} %) | largest drained \\|dε_v/dε₁\\| "
                  f"(target {RATE_MAX}) | ends off one line in (ln p, ν), box measure (target 0.01) | "
                  "box measure at the end / the neutral cell's | "
                  "the same, macro volume | loose undrained: lowest p / p₀ | p rises again |",
                  rows)


def table_block() -> str:
    head = ("| mechanisms on | tests to 30 % | q/p at the end | within ±3 % of their mean | "
            "largest drained \\|dε_v/dε₁\\| at the end | drained with \\|dε_v/dε₁\\| ≤ 0.05 | "
            "ends off one line in (ln p, ν), macro volume / the cells' / box measure (target 0.01) | "
            "loose undrained: lowest p/p₀ along the test; phase transformations (p falls by 10 % or more, "
            "then rises by 5 % or more) | M_c (π-plane) | M_e/M_c (M_e: largest q_eq/p in extension) |")
    return _table(head, [r for r in (row(tag, label) for tag, label in VARIANTS) if r is not None])


#: The π-plane of the sand variant at its KFS calibration, one record per density (tag, which).
PI_KFS = (("sand_kfs_densest", "the densest specimen"), ("sand_kfs", "the calibration's reference"),
          ("sand_kfs_loosest", "the loosest specimen"))


def pi_kfs_block() -> str:
    """M_e/M_c of the sand variant over the sand's densities, beside Mohr–Coulomb's ratio at the
    same compression friction angle (φ_e = φ_c) and the issue's band for sands."""
    head = ("| e0 (α0) | M_c | φ_c [°] | φ_e [°] | M_e/M_c (a sand: 0.65–0.80) | Mohr–Coulomb at φ_c (φ_e = φ_c) "
            "| every Lode angle past its peak |")
    rows = []
    for tag, which in PI_KFS:
        pi = _load("pi_plane", tag)
        if pi is None:
            continue
        cal = pi["calibration"]
        peaked = all(r["ended"] != "max strain" for r in pi["table"])
        rows.append(f"| {cal['e0']:.3f} ({cal['alpha0']:.1f}°), {which} | {_result(pi, 'M_c'):.3f} "
                    f"| {_result(pi, 'phi_c'):.1f} | {_result(pi, 'phi_e'):.1f} "
                    f"| {_result(pi, 'strength ratio'):.3f} | {_result(pi, 'Mohr-Coulomb ratio'):.3f} "
                    f"| {'yes' if peaked else 'no'} |")
    return _table(head, rows)


def drained_ends_block() -> str:
    """The drained ends alone: their distance from one line in (ln p, ν) on the three volume
    measures, where their mean box lies against the neutral bi-hexagon's (at contact at α_n, the
    largest box of a closed cell), and their q/p."""
    from benchmarks.model3d.critical_state import MEASURES, line_offset
    from hmodel.cell.renewal import NEUTRAL_3D, box_at_contact

    neutral = box_at_contact(NEUTRAL_3D, 1.0, 3) / box_at_contact(math.radians(45.0), 1.0, 3)
    head = ("| mechanisms on | drained tests to the end (30 %, the last row 80 %) | drained ends off one line in (ln p, ν), macro volume / "
            "the cells' / box measure (target 0.01) | their box / the neutral bi-hexagon's | their q/p |")
    rows = []
    for tag, label in (*VARIANTS, ("sand_kfs_80", "the same, to 80 %")):
        cs = _load("critical_state", tag)
        if cs is None:
            continue
        if tag != "sand_kfs_80":
            label += _sides(cs.get("radial") or cs["options"].get("radial")) + _at_sand(cs)
        drained = [r for r in cs["table"] if r["test"] == "drained" and not r["newton_failed"]]
        box = [r["nu_box_end"] / neutral for r in drained]
        qp = [r["q_p_end"] for r in drained]
        offsets = " / ".join(f"{line_offset(drained, key):.4f}" for key, _ in MEASURES)
        rows.append(f"| {label} | {len(drained)} of 6 | {offsets} | {min(box):.3f}–{max(box):.3f} "
                    f"| {min(qp):.3f}–{max(qp):.3f} |")
    return _table(head, rows)


BLOCKS = {"mechanisms-table": table_block, "mechanisms-pi-kfs": pi_kfs_block, "mechanisms-kfs": kfs_block,
          "mechanisms-kfs-long": kfs_long_block, "mechanisms-dem": dem_block,
          "mechanisms-dem-judge": dem_judge_block, "mechanisms-dem-judge-2d": dem_judge_2d_block,
          "mechanisms-dem-fabric": dem_fabric_block,
          "mechanisms-dem-bihex": dem_bihex_block,
          "mechanisms-critical-2d": critical_2d_block, "mechanisms-drained-ends": drained_ends_block}


def _cost(rel: str, measure: str):
    """An inline figure: the cost ratio ``measure`` (the start of its row) of the engine record
    ``benchmarks/REL``, to two decimals (one from 10 on)."""
    @_from_record(rel)
    def figure(rec: dict) -> str:
        value = _result(rec, measure)
        return f"{value:.1f}" if value >= 10 else f"{value:.2f}"
    return figure


#: Figures within sentences (no line breaks around them): the cell's cost with each mechanism.
INLINE = {
    "hertz-cost-2d": _cost("engine/engine.json", "cost of a cell update, Hertz-Mindlin over linear"),
    "hertz-cost-all": _cost("engine/engine.json", "cost of a cell update, every mechanism on"),
    "hertz-cost-sand": _cost("engine/engine.json", "cost of a cell update, the sand variant's"),
    "hertz-cost-3d": _cost("engine/engine3d.json", "cost of a bi-hexagon update, Hertz-Mindlin contacts over"),
    "hertz-cost-3d-sand": _cost("engine/engine3d.json", "cost of a bi-hexagon update, the sand variant's"),
    "hertz-cost-3d-cross": _cost("engine/engine3d.json",
                                 "cost of a bi-hexagon update, Hertz-Mindlin contacts and contacts between"),
    "prepared-cost-2d": _cost("engine/engine.json", "prepared trials' cost of a cell update, Hertz-Mindlin"),
    "prepared-cost-sand": _cost("engine/engine.json", "prepared trials' cost of a cell update, the sand"),
    "prepared-cost-3d": _cost("engine/engine3d.json", "prepared trials' cost of a bi-hexagon update, Hertz-Mindlin contacts over"),
    "prepared-cost-3d-sand": _cost("engine/engine3d.json", "prepared trials' cost of a bi-hexagon update, the sand"),
    "prepared-cost-3d-cross": _cost("engine/engine3d.json",
                                    "prepared trials' cost of a bi-hexagon update, Hertz-Mindlin contacts and"),
}


def render(text: str) -> str:
    """``text`` with every block between its markers generated again."""
    for blocks, sep in ((BLOCKS, "\n"), (INLINE, "")):
        for name, make in blocks.items():
            begin, end = f"<!-- {name} -->", f"<!-- /{name} -->"
            i, j = text.index(begin), text.index(end) + len(end)
            text = text[:i] + sep.join([begin, make(), end]) + text[j:]
    return text


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="compare the page with the JSON files")
    args = ap.parse_args()
    text = PAGE.read_text()
    new = render(text)
    if args.check:
        if new != text:
            print("docs/mechanisms.md: the mechanisms table differs from the benchmarks' JSON files; "
                  "run python -m benchmarks.model3d.mechanisms_table")
            return 1
        return 0
    PAGE.write_text(new)
    return 0


if __name__ == "__main__":
    sys.exit(main())
