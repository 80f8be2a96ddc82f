"""Which bi-hexagons carry: a census of the 3D REV along a drained triaxial test (issue 54,
docs/notes/2026-12-07-box-density-map-learned-loop-rebuild.md).

For each initial opening angle α0 (``--alpha0``, degrees) and each axial strain (``--strains``),
one drained test at ``--p0`` with the cell's mechanisms ``--mechanisms`` (default: the sand
variant's, ``contact=hertz-mindlin,lateral=axisymmetric,renewal=mix``, with
``sliding_rhs=equilibrium`` as the critical-state benchmark's), both sides held at p0 with one
radial strain (``--radial equal``), steps of ``--step``, run from the start to that strain.
At its end: q/p, ε_v, the weight (the directions' share of eq. 1.17) of the bi-hexagons whose
two hexagons both carry (N1 > 0), one, or none, and the opening angle of the carrying hexagons A
(weighted mean, least, largest).

A hexagon "carries" with N1 above 1 % of the REV's weighted mean N1 (an open hexagon's forces are
zero, docs/model.md, step 3; a cell reborn at contact takes forces many orders smaller, which a
threshold at zero would count). ``"w_positive"`` gives the weight with N1 > 0 in both hexagons.

Usage: ``python -m benchmarks.model3d.carrying_census [--alpha0 45,65] [--strains 0.05,0.15,0.3]
[--p0 100e3] [--out PATH]``. Prints a table and writes ``carrying_census.json``.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from benchmarks.model3d.critical_state import parse_mechanisms, segment
from benchmarks.timing import provenance
from hmodel import Params
from hmodel.loading import Recorder, consolidate, run_segment
from hmodel.rev import Rev3D, Sphere

SAND = "contact=hertz-mindlin,lateral=axisymmetric,renewal=mix,sliding_rhs=equilibrium"


def carrying_hexagons(v: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Whether hexagons A and B of one point's bi-hexagons ``v`` (C, 16), of weights ``w`` (C,),
    carry: N1 above 1 % of the REV's weighted mean N1 over both hexagons. Reborn cells at contact
    take forces many orders smaller, which N1 > 0 would count (and which round-off decides,
    docs/notes/2026-12-07-why-the-bihexagon-dilates.md)."""
    mean_n1 = float((w * (v[:, 3] + v[:, 11])).sum() / 2.0 / w.sum())
    return v[:, 3] > 0.01 * mean_n1, v[:, 11] > 0.01 * mean_n1


def carrying(v: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Bi-hexagons ``v`` (C, 16) of weights ``w`` of which a hexagon carries (:func:`carrying_hexagons`)."""
    a, b = carrying_hexagons(v, w)
    return a | b


def census(params: Params, p0: float, strain: float, step: float, radial: str) -> dict:
    """The census of one drained test at its end (see the module's docstring)."""
    rev = Rev3D([params], Sphere())
    p = np.array([p0])
    rec = Recorder()
    end = run_segment(rev, consolidate(rev, p), segment(False, p, strain, round(strain / step), radial), rec).state
    r = rec.result().point(0).columns
    v = end.cells.values[0]
    w = rev.weights / rev.weights.sum()
    a, b = carrying_hexagons(v, w)
    return {"alpha0": math.degrees(params.alpha0), "eps11": float(r["eps11"][-1]),
            "q_p": float(r["q"][-1] / r["p"][-1]), "eps_v": float(r["eps_v"][-1]),
            "w_positive": float(w[(v[:, 3] > 0.0) & (v[:, 11] > 0.0)].sum()), "w_both": float(w[a & b].sum()), "w_one": float(w[a ^ b].sum()), "w_none": float(w[~a & ~b].sum()),
            "alpha_a_mean": math.degrees(float((w[a] * v[a, 2]).sum() / w[a].sum())) if a.any() else None,
            "alpha_a_min": math.degrees(float(v[a, 2].min())) if a.any() else None,
            "alpha_a_max": math.degrees(float(v[a, 2].max())) if a.any() else None}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--alpha0", default="45,65", help="initial opening angles [deg]")
    ap.add_argument("--strains", default="0.05,0.15,0.3")
    ap.add_argument("--p0", type=float, default=100e3)
    ap.add_argument("--step", type=float, default=1e-4)
    ap.add_argument("--radial", default="equal", choices=("free", "equal"))
    ap.add_argument("--mechanisms", default=SAND, help="the cell's options, NAME=VALUE,...")
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("carrying_census.json"))
    args = ap.parse_args()
    base = parse_mechanisms(args.mechanisms)
    rows = [census(Params(alpha0=math.radians(float(a)), **base), args.p0, float(s), args.step, args.radial)
            for a in args.alpha0.split(",") for s in args.strains.split(",")]
    print("alpha0  eps11   q/p    eps_v   w N1>0  w both  w one  w none  alpha A carrying: mean (min-max)")
    for r in rows:
        ang = "-" if r["alpha_a_mean"] is None else \
            f"{r['alpha_a_mean']:.1f} ({r['alpha_a_min']:.1f}-{r['alpha_a_max']:.1f})"
        print(f"{r['alpha0']:6.1f}  {r['eps11']:.3f}  {r['q_p']:.3f}  {r['eps_v']:+.4f}  {r['w_positive']:.2f}    {r['w_both']:.2f}    "
              f"{r['w_one']:.2f}   {r['w_none']:.2f}    {ang}")
    args.out.write_text(json.dumps({**provenance(__file__, args), "rows": rows},
                                   indent=2) + "\n")
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
