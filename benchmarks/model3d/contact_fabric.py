"""The 3D REV's stress split by its contacts' tilt, as the DEM samples' is (issue 54,
docs/notes/2026-12-07-contact-fabric.md).

The fabric probe (``benchmarks.model3d.fabric_turn``) split the REV's stress by the tilt of each
bi-hexagon's axis n and the DEM samples' by the tilt of each contact's branch vector. A
bi-hexagon's contacts do not lie along its axis: its four inclined contacts per hexagon lie at
the opening angle α from n. So the two splits measure different things. This one splits the
REV the DEM's way.

**The decomposition** (Love-Weber, report eq. 1.11, per contact; derived here from the branch
vectors, independently of the closed form's eq. 1.12). Hexagon A lies in the plane (n, t1),
B in (n, t2) (docs/model3d.md); for a hexagon of state (d1, d2, α, N1, N2, T1) and in-plane axis
t, with s_n, s_t = ±1 its four mirror images:

- the four inclined contacts (grains 1-2, 1-6, 4-3, 4-5): branch u = -s_n cos α n + s_t sin α t,
  of length d1, tangential direction τ = -s_n sin α n - s_t cos α t, force N1 u + T1 τ, so
  f ⊗ l = d1 (N1 u ⊗ u + T1 τ ⊗ u);
- the two column contacts (2-3, 5-6): branch n, length d2, N2 d2 n ⊗ n each;
- the extra contacts of docs/model.md step 3 (Fig. 1.6): grains 1-4 once per bi-hexagon,
  F(2r - l1) l1 n ⊗ n when l1 <= 2r; grains 2-6 and 3-5 (A, along t1) and 7-10, 8-9 (B, along
  t2), F(2r - l) l t ⊗ t each when l <= 2r; F linear or Hertz's law as the cell's;
- with ``cross_contacts=frictionless``, the eight contacts between the hexagons
  (:mod:`hmodel.cell.cross`): branch b = (δd2/2, ±l2/2, ±l3/2) in (n, t1, t2), F b ⊗ b / |b|.

The REV's stress is then σ = (1/V) Σ_c w_c Σ_contacts f ⊗ l (eq. 1.15 lifted): the tests check
it against :meth:`hmodel.rev.Rev3D.stress` (eq. 1.12 summed per cell), which is the
decomposition's independent check. A contact's tilt is the angle of its branch from the
compression axis e1; it carries when its normal force is positive; it counts w_c as a DEM contact
counts 1.

**The comparison.** The bands of :data:`benchmarks.model3d.fabric_turn.BANDS` (0-30°, 30-50°,
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
import math
from pathlib import Path

import numpy as np

from benchmarks.model3d.fabric_turn import BANDS, band_split, dem_part, run, sand
from benchmarks.timing import provenance
from hmodel import Params
from hmodel.cell.closed_form import hertz_constants
from hmodel.cell.hertz import extra_force
from hmodel.loading import consolidate
from hmodel.rev import Rev3D, Sphere

#: Mirror images (s_n, s_t) of a hexagon's inclined contacts.
MIRRORS = ((1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0))


def bihex_contacts(params: Params, v: np.ndarray, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every contact of bi-hexagons ``v`` (C, 16) of frames (C, 3, 3) (rows n, t1, t2):
    ``(cell, branch, fn, fl)``, the index of its cell (K,), its unit branch vector (K, 3) in the
    global frame, its normal force (K,) and its f ⊗ l (K, 3, 3) [N m] (the module's
    docstring). Contacts of zero force are kept: the caller decides what carries."""
    v = np.asarray(v, float)
    n, axes = frames[:, 0, :], (frames[:, 1, :], frames[:, 2, :])
    two_r = 2.0 * params.radius
    c = hertz_constants(params)[0] if params.contact == "hertz-mindlin" else 0.0
    force = np.vectorize(lambda gap: extra_force(params.kn, c, gap) if gap > 0.0 else 0.0)
    cells, branch, fn, fl = [], [], [], []
    index = np.arange(len(v))

    def add(u: np.ndarray, f_normal: np.ndarray, tensor: np.ndarray) -> None:
        cells.append(index)
        branch.append(u)
        fn.append(f_normal)
        fl.append(tensor)

    for h, t in enumerate(axes):
        d1, d2, a, n1, n2, t1 = (v[:, 8 * h + k] for k in range(6))
        ca, sa = np.cos(a)[:, None], np.sin(a)[:, None]
        for sn, st in MIRRORS:
            u = -sn * ca * n + st * sa * t
            tau = -sn * sa * n - st * ca * t
            add(u, n1, d1[:, None, None] * (n1[:, None, None] * u[:, :, None] * u[:, None, :]
                                            + t1[:, None, None] * tau[:, :, None] * u[:, None, :]))
        for _ in range(2):
            add(n, n2, (n2 * d2)[:, None, None] * n[:, :, None] * n[:, None, :])
        lt = v[:, 7] if h == 0 else v[:, 15]
        f = force(two_r - lt)
        for _ in range(2):
            add(t, f, (f * lt)[:, None, None] * t[:, :, None] * t[:, None, :])
    l1 = v[:, 6]
    f = force(two_r - l1)
    add(n, f, (f * l1)[:, None, None] * n[:, :, None] * n[:, None, :])
    if params.cross_contacts == "frictionless":
        dd2, l2, l3 = v[:, 1] - v[:, 9], v[:, 7], v[:, 15]
        for s2, s3 in MIRRORS:
            b = 0.5 * (dd2[:, None] * n + s2 * l2[:, None] * axes[0] + s3 * l3[:, None] * axes[1])
            dc = np.linalg.norm(b, axis=1)
            f = force(two_r - dc)
            u = b / dc[:, None]
            add(u, f, (f * dc)[:, None, None] * u[:, :, None] * u[:, None, :])
    return (np.concatenate(cells), np.concatenate(branch), np.concatenate(fn), np.concatenate(fl))


def rev_stress_by_contacts(params: Params, v: np.ndarray, frames: np.ndarray, weights: np.ndarray,
                           volume: float) -> np.ndarray:
    """σ (3, 3) [Pa] of one point's bi-hexagons ``v`` (C, 16) summed over their contacts
    (:func:`bihex_contacts`): (1/V) Σ_c w_c Σ f ⊗ l."""
    cell, _, _, fl = bihex_contacts(params, v, frames)
    return np.einsum("k,kij->ij", weights[cell], fl) / volume


def contact_split(params: Params, v: np.ndarray, frames: np.ndarray, weights: np.ndarray) -> dict:
    """The split of one point's stress by its carrying contacts' tilt from e1
    (:func:`benchmarks.model3d.fabric_turn.band_split`), each contact counting its cell's
    weight, with the contacts' fabric F11 = <u1²> and its normal-force-weighted twin."""
    cell, u, fn, fl = bihex_contacts(params, v, frames)
    on = fn > 0.0
    w, u, fn, fl = weights[cell][on], u[on], fn[on], fl[on]
    s11, sr = w * fl[:, 0, 0], 0.5 * w * (fl[:, 1, 1] + fl[:, 2, 2])
    return {"contacts_weight": float(w.sum()), "sig11_over_sig_r": float(s11.sum() / sr.sum()),
            "F11": float((w * u[:, 0] ** 2).sum() / w.sum()),
            "F11_force": float((w * fn * u[:, 0] ** 2).sum() / (w * fn).sum()),
            "bands": band_split(np.degrees(np.arccos(np.clip(np.abs(u[:, 0]), 0.0, 1.0))), w, s11, sr)}


def distance(a: list[dict], b: list[dict], key: str) -> float:
    """Total variation ½ Σ |a - b| of two splits' shares ``key`` (``weight``, ``sig11``,
    ``sig_r``) over their bands: 0 the same, 1 no band in common."""
    return 0.5 * sum(abs(x[key] - y[key]) for x, y in zip(a, b, strict=True))


def rev_part(alpha0: float, strain: float, rule: str, kappa: float, p0: float = 100e3) -> dict:
    """The REV's contact split (:func:`contact_split`) at consolidation to ``p0`` and at the end of
    the fabric probe's drained test (:func:`benchmarks.model3d.fabric_turn.run`: sand variant's
    mechanisms, defaults, α0 [deg], steps of 1e-4), with its q/p and εv."""
    params = sand(alpha0)
    rev = Rev3D([params], Sphere())
    first = consolidate(rev, np.array([p0]))
    w0 = rev.weights / rev.weights.sum()
    path = run(params, p0, strain, 1e-4, rule, kappa)
    end = path["state"]
    w = path["rev"].weights / path["rev"].weights.sum()
    return {"alpha0": alpha0, "eps11": strain, "rule": rule, "kappa": kappa,
            "q_p": float(path["q"][-1] / path["p"][-1]), "eps_v": float(path["eps_v"][-1]),
            "consolidated": contact_split(params, first.cells.values[0], rev.frames, w0),
            "final": contact_split(params, end.cells.values[0], rev.frames, w)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dem-folder", type=Path, default=Path("results/fabric-dem"),
                    help="the fabric probe's DEM tests (reused when there)")
    ap.add_argument("--kappa", type=float, default=20.0, help="rate of the turning rule")
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("contact_fabric.json"))
    args = ap.parse_args()
    result = {**provenance(__file__, args), "bands": [list(b) for b in BANDS]}
    result["dem"] = dem_part(args.dem_folder)
    result["rev"] = [rev_part(a0, 0.25, rule, k) for rule, k in (("off", 0.0), ("turn", args.kappa))
                     for a0 in (45.0, 65.0)]
    dem = {r["sample"]: r for r in result["dem"]}
    for r in result["rev"]:
        for state in ("consolidated", "final"):
            ref = dem["dense-hertz" if r["alpha0"] < 55.0 else "loose-hertz"][state]
            r[state]["distance_to_dem"] = {k: distance(r[state]["bands"], ref["bands"], k)
                                           for k in ("weight", "sig11", "sig_r")}
    for label, x in [*((f"DEM {r['sample']} {s}", r[s]) for r in result["dem"] for s in ("consolidated", "final")),
                     *((f"REV α0 {r['alpha0']:g} {r['rule']} {s} (q/p {r['q_p']:.3f}, εv {r['eps_v']:.3f})", r[s])
                       for r in result["rev"] for s in ("consolidated", "final"))]:
        print(f"{label}: σ11/σr {x['sig11_over_sig_r']:.3f}, F11 {x['F11']:.3f} (force {x['F11_force']:.3f}); "
              + "; ".join(f"{b['theta'][0]:g}-{b['theta'][1]:g}°: n {b['weight']:.2f} σ11 {b['sig11']:.2f} "
                          f"σr {b['sig_r']:.2f}" for b in x["bands"])
              + (f"; TV to DEM n {x['distance_to_dem']['weight']:.2f} σ11 {x['distance_to_dem']['sig11']:.2f} "
                 f"σr {x['distance_to_dem']['sig_r']:.2f}" if "distance_to_dem" in x else ""))
    args.out.write_text(json.dumps(result, indent=2, default=float) + "\n")
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
