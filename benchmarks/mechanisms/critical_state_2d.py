"""Critical state of the 2D H-model with and without ``renewal="mix"`` (docs/mechanisms.md,
"Rebirth at the mean box area"): drained biaxial tests from a dense and a loose state at three
pressures and loose undrained ones, to 25 % and to 60 % axial strain; are the issue's criteria
met (one stress ratio M, no volume change, one line in (ln p, ν), a loose undrained test that
loses and regains p)? Writes ``critical_state_2d.json`` and
``docs/figures/critical_state_2d_[STRAIN %].png`` (ν: the box measure).

Every test is one material point of one batched run per drainage condition and setting:

- drained: σ22 = p0, ε11 in increments of ``--step``, ε12 held;
- undrained: ε11 increments with ε11 + ε22 = 0, ε12 held.

Measures, for the tests that reached the end (Newton can stop a test early):

- ``M``: the mean q/p at the end; the largest |q/p / M - 1| at the end and of the mean over
  the last ``--window`` of axial strain (the target: 3 %);
- the largest |dε_v/dε11| of the drained tests over that window (target 0.05);
- the largest distance of the ends from their least-squares line in (ln p, ν), on two volume
  measures (target 0.01): the REV's macro volume V0(α0) det(I - ε) (as the 3D benchmark,
  ``benchmarks.model3d.critical_state``) and the cells' box measure Σ w l1·l2, the one the
  localization carries as exp(-tr ε); each over the α0 = ``--dense`` REV's initial value;
- loose undrained: the lowest p over p0 and whether p rose again after it (a phase
  transformation) or ended below 10 % of p0 (static liquefaction).

Usage: ``python -m benchmarks.mechanisms.critical_state_2d [--strains 0.25,0.6] [--step 1e-3]
[--n-theta 72] [--out PATH]``.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from benchmarks.model3d.critical_state import figure, summary
from benchmarks.timing import FIGURES, record, write_table
from hmodel import Params
from hmodel.loading import Recorder, Segment, consolidate, run_segment
from hmodel.rev import Rev

#: The cells' settings of the notes (docs/notes/2026-12-06-critical-state-*.md).
BASE = dict(kn=1.4e8, kt_kn=0.5, sliding_rhs="equilibrium", volume="hexagon")
RENEWALS = ("none", "mix")


def segment(undrained: bool, p0: np.ndarray, strain: float, steps: int) -> Segment:
    M = np.eye(3)
    if undrained:
        M[1, :2] = (1.0, 1.0)  # eps_v = 0
        values = np.column_stack([np.full(len(p0), strain), np.zeros((len(p0), 2))])
        return Segment((False, False, False), M, values, steps, "shear")
    values = np.column_stack([np.full(len(p0), strain), p0, np.zeros(len(p0))])
    return Segment((False, True, False), M, values, steps, "shear")


def box_area(rev: Rev, values: np.ndarray) -> np.ndarray:
    """Σ w l1·l2 of each point's cells (B,)."""
    return (values[..., 6] * values[..., 7]) @ rev.weights[0]


def run(sets, p0, undrained, strain, steps):
    rev = Rev(sets)
    state = consolidate(rev, p0)
    rec = Recorder()
    failures: dict = {}
    boxes = []  # the box measure before each increment and after the last (run_segment's chunk)
    watch = lambda st, k: boxes.append(box_area(rev, st.cells.values)) or 1  # noqa: E731
    run_segment(rev, state, segment(undrained, p0, strain, steps), rec, failures=failures, chunk=watch)
    res = rec.result()
    start, boxes = boxes[0], np.array(boxes[1:])  # before the first increment; (steps, B) after each
    out = []
    for b in range(len(sets)):
        r = res.point(b).columns
        eps = np.column_stack([r["eps11"], r["eps22"], r["eps12"]])
        box = boxes[:len(eps), b]
        out.append({"eps11": r["eps11"], "p": r["p"], "q": r["q"], "eps_v": r["eps_v"],
                    "volume": rev.macro_volume(eps, np.full(len(eps), b)), "volume0": float(rev.volumes0[b]),
                    "box": box, "box_end": float(box[-1]), "box_ratio": float(box[-1] / start[b]),
                    "failed": failures.get(b)})
    return out


def line_distance(p: np.ndarray, nu: np.ndarray) -> float:
    """Largest distance in ν of the points (ln p, ν) from their least-squares line."""
    if len(p) < 3:
        return math.nan
    x = np.log(p)
    fit = np.polyval(np.polyfit(x, nu, 1), x)
    return float(np.max(np.abs(nu - fit)))


def verdicts(rows: list[dict]) -> dict:
    ok = [r for r in rows if not r["newton_failed"]]
    qp = np.array([r["q_p_end"] for r in ok])
    qw = np.array([r["q_p_window"] for r in ok])
    m = float(qp.mean()) if len(qp) else math.nan
    drained = [r for r in ok if r["test"] == "drained"]
    loose_u = [r for r in rows if r["test"] == "undrained"]
    return {"M": m, "tests_at_end": len(ok), "tests": len(rows),
            "q_p_end_max_off_M": float(np.max(np.abs(qp / m - 1))) if len(qp) else math.nan,
            "q_p_window_max_off_mean": float(np.max(np.abs(qw / qw.mean() - 1))) if len(qw) else math.nan,
            "deps_v_deps11_max": max((abs(r["deps_v_deps11_end"]) for r in drained), default=math.nan),
            "line_macro": line_distance(np.array([r["p_end"] for r in ok]), np.array([r["nu_end"] for r in ok])),
            "line_box": line_distance(np.array([r["p_end"] for r in ok]), np.array([r["nu_box_end"] for r in ok])),
            "loose_undrained_p_min_over_p0": [r["p_min_over_p0"] for r in loose_u],
            "loose_undrained_p_rises_after_min": [r["p_rises_after_min"] for r in loose_u]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dense", type=float, default=40.0)
    ap.add_argument("--loose", type=float, default=55.0)
    ap.add_argument("--pressures", default="100e3,200e3,400e3")
    ap.add_argument("--strains", default="0.25,0.6")
    ap.add_argument("--step", type=float, default=1e-3)
    ap.add_argument("--window", type=float, default=0.025, help="axial strain window of the end means and rates")
    ap.add_argument("--n-theta", type=int, default=72)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("critical_state_2d.json"))
    args = ap.parse_args()
    pressures = [float(x) for x in args.pressures.split(",")]
    ref = Rev(Params(**BASE, n_theta=args.n_theta, alpha0=math.radians(args.dense)))
    v_ref, box_ref = ref.volume0, float(box_area(ref, ref.initial(1).cells.values[0]))
    table, verdict = [], {}
    t = time.perf_counter()
    for strain in (float(s) for s in args.strains.split(",")):
        steps = int(round(strain / args.step))
        for renewal in RENEWALS:
            rows, paths, labels = [], [], []
            for test in ("drained", "undrained"):
                states = (("dense", args.dense), ("loose", args.loose)) if test == "drained" else (("loose", args.loose),)
                sets, p0, labs = [], [], []
                for state, a0 in states:
                    for k, p in enumerate(pressures):
                        sets.append(Params(**BASE, n_theta=args.n_theta, alpha0=math.radians(a0), renewal=renewal))
                        p0.append(p)
                        labs.append({"state": state, "alpha0": a0, "p0": p, "k": k})
                for path, lab in zip(run(sets, np.array(p0), test == "undrained", strain, steps), labs):
                    s = summary(path, v_ref, args.window, lab["p0"], box_ref)
                    e, p, q = path["eps11"], path["p"], path["q"]
                    win = e >= e[-1] - args.window
                    row = {"strain": strain, "renewal": renewal, "test": test,
                           **{k: v for k, v in lab.items() if k != "k"}, **s,
                           "q_p_window": float(np.mean(q[win] / p[win]))}
                    rows.append(row)
                    paths.append({**path, "volume": path["box"]})  # the figure: the box measure
                    labels.append({**lab, "test": test, "v_ref": box_ref})
                    print(f"{strain:.2f} {renewal:4s} {test:9s} {lab['state']:5s} {lab['p0'] / 1e3:3.0f} kPa: "
                          f"to {s['axial_strain_end']:.3f} q/p {s['q_p_end']:.3f} (window {row['q_p_window']:.3f}) "
                          f"dev/de1 {s['deps_v_deps11_end']:+.3f} p {s['p_end'] / 1e3:6.1f} nu {s['nu_end']:.4f} "
                          f"box {row['nu_box_end']:.4f}{' (Newton failed)' if s['newton_failed'] else ''}", flush=True)
            table += rows
            verdict[f"{renewal} to {strain:g}"] = verdicts(rows)
            print(json.dumps(verdict[f"{renewal} to {strain:g}"]), flush=True)
            if renewal == "mix":
                figure(paths, labels, FIGURES / f"critical_state_2d_{round(strain * 100)}.png",
                       nu_label=f"ν_box = Σ w l1 l2 / its α0 = {args.dense:g}° start")
    wall = time.perf_counter() - t
    results = []
    for name, v in verdict.items():
        results += [(f"{name}: tests that reached the end (of {v['tests']})", v["tests_at_end"], str(v["tests"])),
                    (f"{name}: largest |q/p / M - 1| at the end", v["q_p_end_max_off_M"], "<= 0.03"),
                    (f"{name}: largest |dev/de11|, drained", v["deps_v_deps11_max"], "<= 0.05"),
                    (f"{name}: ends off one line in (ln p, nu), macro volume", v["line_macro"], "<= 0.01"),
                    (f"{name}: ends off one line in (ln p, nu), box measure", v["line_box"], "<= 0.01")]
    results.append(("wall time of every run [s]", wall, "-"))
    rec = record(__file__, args, 1, results, verdicts=verdict, table=table, base=BASE, v_ref=v_ref,
                 box_ref=box_ref)
    write_table(results, args.out, rec)


if __name__ == "__main__":
    main()
