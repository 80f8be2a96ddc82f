"""Lode dependence of the 3D H-model's strength (issue 34): the failure surface in the π-plane
beside Mohr–Coulomb, Matsuoka–Nakai and Lade–Duncan fitted at triaxial compression, and beside
the 2D model's biaxial strength at the same material. Writes ``pi_plane.json`` and
``docs/figures/pi_plane.png``.

The 3D paths are those of :func:`hmodel.failure_surface.failure_surface` (constant p, fixed
Lode angle, strain control along the ray). The 2D model's strength is the peak of the drained
biaxial test (:func:`hmodel.loading.run_biaxial`) at the same p0 with the same ``Params``, as a
mobilized friction angle sin φ = (σ1 - σ3)/(σ1 + σ3) = q/(2p) (2D p and q). A 2D plane-strain
test has no σ2 to place it in the π-plane, so it is compared by its friction angle.

With ``--kfs TAG [--e0 E]`` the surface is that of a Karlsruhe fine sand calibration
(``benchmarks/calibration/kfs_TAG.json``: its variant, calibrated parameters and sphere) for a
specimen at void ratio E (default: the calibration's reference void ratio), at the α0 the
variant maps E on.

Usage: ``python -m benchmarks.model3d.pi_plane [--p 200e3] [--lode 0,7.5,...,60]
[--order N] [--n-azimuth M] [--max-strain 0.3] [--kfs TAG [--e0 E]] [--out PATH] [--figure PATH]``.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from benchmarks.timing import FIGURES, record
from benchmarks.model3d.critical_state import parse_mechanisms
from hmodel import Params
from hmodel.failure_surface import (
    failure_surface,
    friction_angle,
    full_envelope,
    lade_duncan,
    matsuoka_nakai,
    mohr_coulomb,
    pi_plane_xy,
    principal_stresses,
)
from hmodel.loading import run_biaxial
from hmodel.rev import Sphere


def figure(fs, phi2d: float, out: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(12, 5.6))
    curves = {"Mohr–Coulomb": (lambda t: mohr_coulomb(fs.phi_compression, t), "tab:gray", "-"),
              "Matsuoka–Nakai": (lambda t: matsuoka_nakai(fs.k_matsuoka_nakai, t), "tab:green", "--"),
              "Lade–Duncan": (lambda t: lade_duncan(fs.k_lade_duncan, t), "tab:purple", "-."),
              # σ3 = p (1 + (2/3) r cos(θ + 2π/3)) = 0
              "σ3 = 0 (tension cut-off)": (lambda t: -1.5 / np.cos(np.radians(t) + 2 * math.pi / 3), "k", ":")}
    for name, (f, c, ls) in curves.items():
        xy = full_envelope(f, 121)
        xy = np.vstack([xy, xy[:1]])
        ax[0].plot(xy[:, 0], xy[:, 1], color=c, ls=ls, lw=1.2, label=name)
    # the measured peaks, unfolded by the six-fold symmetry of an isotropic material
    for k in range(6):
        t = fs.lode if k % 2 == 0 else 60.0 - fs.lode
        base = 120.0 * (k // 2) + (0.0 if k % 2 == 0 else 60.0)
        xy = pi_plane_xy(fs.ratio, base + t)
        ax[0].plot(xy[:, 0], xy[:, 1], "o", color="tab:red", ms=4, label="3D H-model (peaks)" if k == 0 else None)
    peaked = np.array([e != "max strain" for e in fs.ended])
    if (~peaked).any():
        xy = pi_plane_xy(fs.ratio[~peaked], fs.lode[~peaked])
        ax[0].plot(xy[:, 0], xy[:, 1], "x", color="k", ms=7, label="no peak before max strain")
    for i, lab in ((0, "σ1"), (1, "σ2"), (2, "σ3")):
        a = math.radians(120 * i)
        ax[0].annotate(lab, (2.0 * math.sin(a), 2.0 * math.cos(a)), ha="center", va="center", color="0.4")
        ax[0].plot([0, 1.9 * math.sin(a)], [0, 1.9 * math.cos(a)], color="0.85", lw=0.8, zorder=0)
    ax[0].set_aspect("equal")
    ax[0].set(xlim=(-2.2, 2.2), ylim=(-2.2, 2.2), title=f"π-plane at p = {fs.p / 1e3:g} kPa: q_eq/p")
    ax[0].legend(fontsize=8, loc="lower left")
    t = np.linspace(0.0, 60.0, 121)
    for name, (f, c, ls) in list(curves.items())[:3]:
        ax[1].plot(t, friction_angle(principal_stresses(1.0, f(t), t)), color=c, ls=ls, label=name)
    ax[1].plot(fs.lode, fs.phi, "o-", color="tab:red", label="3D H-model (peaks)")
    ax[1].axhline(phi2d, color="tab:blue", ls="--", label=f"2D H-model, biaxial (φ = {phi2d:.1f}°)")
    ax[1].set(xlabel="Lode angle θ [deg] (0: compression, 60: extension)",
              ylabel="peak friction angle φ [deg], sin φ = (σ1 − σ3)/(σ1 + σ3)", title="Lode dependence")
    ax[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def specimen_e0(text: str) -> float:
    """``--e0``: a void ratio, or the densest / loosest of Karlsruhe fine sand's 25 tests."""
    if text in ("densest", "loosest"):
        from benchmarks.calibration.kfs import load_tests

        e0s = [t.e0 for t in load_tests(1)[0]]
        return min(e0s) if text == "densest" else max(e0s)
    return float(text)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--p", type=float, default=200e3)
    ap.add_argument("--lode", default="0,7.5,15,22.5,30,37.5,45,52.5,60")
    ap.add_argument("--order", type=int, default=None, help="default: Sphere()'s")
    ap.add_argument("--n-azimuth", type=int, default=None, help="default: Sphere()'s")
    ap.add_argument("--max-strain", type=float, default=0.3)
    ap.add_argument("--sliding-rhs", default="equilibrium")
    ap.add_argument("--mechanisms", default="", help="the cell's mechanisms on, NAME=VALUE,... "
                    "(docs/mechanisms.md); the outputs then carry the tag --tag")
    ap.add_argument("--kfs", default=None, metavar="TAG",
                    help="at the calibration of benchmarks/calibration/kfs_TAG.json (replaces --mechanisms "
                         "and --sliding-rhs)")
    ap.add_argument("--e0", default=None, help="with --kfs: the specimen's void ratio, or densest / loosest "
                    "(the sand's smallest / largest e0 of its 25 tests; default: the calibration's reference)")
    ap.add_argument("--tag", default="", help="suffix of the default JSON and figure names")
    ap.add_argument("--out", type=Path, default=None, help="default: pi_plane[_TAG].json")
    ap.add_argument("--figure", type=Path, default=None, help="default: docs/figures/pi_plane[_TAG].png")
    args = ap.parse_args()
    d = Sphere()
    sphere = Sphere(order=args.order or d.order, n_azimuth=args.n_azimuth or d.n_azimuth)
    suffix = f"_{args.tag}" if args.tag else ""
    args.out = args.out or Path(__file__).with_name(f"pi_plane{suffix}.json")
    args.figure = args.figure or FIGURES / f"pi_plane{suffix}.png"
    mechanisms = parse_mechanisms(args.mechanisms)
    params = Params.from_strings(mechanisms, Params(sliding_rhs=args.sliding_rhs))
    calibration = {}
    if args.kfs is not None:
        from benchmarks.calibration.kfs_long import stored

        variant, fitted, e_ref, kfs_sphere, _, _ = stored(args.kfs)
        e0 = e_ref if args.e0 is None else specimen_e0(args.e0)
        params = variant.initial_params(fitted, 3, e0, e_ref)
        sphere = Sphere(order=args.order or kfs_sphere.order, n_azimuth=args.n_azimuth or kfs_sphere.n_azimuth)
        calibration = {"calibration": {"record": f"kfs_{args.kfs}.json" if args.kfs else "kfs.json",
                                       "variant": variant.name, "e_ref": e_ref, "e0": e0,
                                       "alpha0": math.degrees(params.alpha0), "params": params.to_dict()}}
    t0 = time.perf_counter()
    fs = failure_surface(params, args.p, [float(x) for x in args.lode.split(",")], sphere=sphere,
                         max_strain=args.max_strain)
    wall = time.perf_counter() - t0
    for row in fs.table():
        print(f"θ {row['lode']:5.1f}  q_eq/p {row['q_p']:.4f}  φ {row['phi']:.2f}°  (MC {row['mohr_coulomb']:.4f}, "
              f"MN {row['matsuoka_nakai']:.4f}, LD {row['lade_duncan']:.4f})  θ reached {row['lode_reached']:.6f}  "
              f"{row['ended']}", flush=True)
    # a 2D H-cell has no second hexagon: the 2D comparison runs without cross contacts, affine
    bi = run_biaxial(params.with_(cross_contacts="none", lateral="affine"), [args.p], 0.2).stage("shear")
    k = int(np.argmax(bi["q_p"]))
    phi2d = math.degrees(math.asin(bi["q_p"][k] / 2.0))
    ratios = fs.fit_strength_ratios()
    results = [("M_c = peak q_eq/p, triaxial compression", fs.ratio_compression, "-"),
               ("phi_c [deg] (sin phi = 3M/(6+M))", fs.phi_compression, "-"),
               ("M_e = peak q_eq/p, triaxial extension", float(fs.ratio[-1]), "-"),
               ("phi_e [deg] (sin phi = 3M/(6-M))", fs.phi_extension, "-"),
               ("strength ratio M_e/M_c", fs.strength_ratio, "-"),
               ("Mohr-Coulomb ratio (3 - sin phi)/(3 + sin phi)", ratios["mohr_coulomb"], "-"),
               ("Matsuoka-Nakai ratio", ratios["matsuoka_nakai"], "-"),
               ("Lade-Duncan ratio", ratios["lade_duncan"], "-"),
               ("2D biaxial peak q/p (2D p, q)", float(bi["q_p"][k]), "-"),
               ("2D biaxial phi [deg] (sin phi = q/(2p))", phi2d, "-"),
               ("wall time of the failure surface [s]", wall, "-")]
    for name, value, _ in results:
        print(f"{name}: {value:.4f}")
    rec = record(__file__, args, 1, results, table=fs.table(),
                 sphere={"order": sphere.order, "n_azimuth": sphere.n_azimuth},
                 biaxial_2d={"peak_q_p": float(bi["q_p"][k]), "axial_strain_at_peak": float(bi["eps11"][k]),
                             "phi": phi2d}, **calibration)
    args.out.write_text(json.dumps(rec, indent=2) + "\n")
    figure(fs, phi2d, args.figure)
    print(f"written {args.out}, {args.figure}")


if __name__ == "__main__":
    main()
