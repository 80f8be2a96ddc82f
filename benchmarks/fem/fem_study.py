"""FEM verification and studies for docs/fem.md: measured numbers (``fem_study.json``) and the
figures ``docs/figures/fem-*.png``.

(a) homogeneous biaxial (smooth platens, no imperfection), nθ = 360, 5 % in 100 steps: q and
    ε_v of the FEM (reactions) against ``run_biaxial`` with the same increments, drained and
    undrained, on 1x1, 2x4 and 8x16 Q4 meshes; the Newton residuals of the 8x16 drained run;
(b) shear band: an edge imperfection (weaker zone φg = 25°, α0 = 55° at mid-height of the left
    side), smooth platens, nθ = 90, ``sliding_rhs=equilibrium``, to 10 % in 50 steps, on 4x8,
    8x16 and 12x24 Q4 meshes: the band's inclination after the peak, beside Coulomb, Roscoe and
    Arthur from the material point's own peak φ and ψ; the onset against the material point's
    bifurcation (``hmodel.stability.along_biaxial``);
(c) strip footing (rough, 0.2 m on a 1.0 x 0.5 m layer, 100 kPa), nθ = 90,
    ``sliding_rhs=equilibrium``, to s/B = 0.05 in 25 steps on 10x5, 20x10 and 40x20 Q4 meshes.

Usage: ``python -m benchmarks.fem.fem_study [--parts abc]``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from benchmarks.timing import FIGURES, provenance  # noqa: E402
from hmodel import Params  # noqa: E402
from hmodel.fem import biaxial, footing, material_point_curve  # noqa: E402
from hmodel.fem.bands import concentration, peak_angles, shear_band, theory_angles  # noqa: E402
from hmodel.fem.outputs import deviatoric_strain  # noqa: E402


def homogeneous(out: dict) -> None:
    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    rows = []
    for undrained in (False, True):
        for mesh in ((1, 1), (2, 4), (8, 16)):
            t = time.perf_counter()
            res = biaxial(Params(n_theta=360), 2e5, 0.05, mesh=mesh, n_steps=100, undrained=undrained)
            wall = time.perf_counter() - t
            c = material_point_curve(res.reference)
            # rows at the reference's strains (a cut step adds rows between them)
            e, upto = res.column("eps11"), int(np.argmax(c["q"])) + 1
            k = np.searchsorted(c["eps11"][:upto], e)
            hit = (k < upto) & np.isclose(c["eps11"][np.minimum(k, upto - 1)], e, rtol=0, atol=1e-12)
            k = k[hit]
            eq = np.abs(res.column("q")[hit] - c["q"][k]) / c["q"].max()
            ev = np.abs(res.column("eps_v")[hit] - c["eps_v"][k])
            rows.append({"test": "undrained" if undrained else "drained", "mesh": f"{mesh[0]}x{mesh[1]}",
                         "steps": len(res) - 1, "rows_compared": int(hit.sum()),
                         "max_q_dev_to_peak": float(eq.max()),
                         "rows_over_0.5pc": int((eq > 5e-3).sum()), "rows_to_peak": upto,
                         "second_largest_q_dev": float(np.sort(eq)[-2]) if eq.size > 1 else float("nan"),
                         "max_eps_v_dev": float(ev.max()), "seconds": wall})
            ax = axes[int(undrained)]
            if mesh == (8, 16):
                ax.plot(c["eps11"], c["q"] / 1e3, "k-", lw=2, label="material point (run_biaxial)")
                axes[2].semilogy(range(len(res.residuals[0])), res.residuals[0], "o-", ms=3,
                                 label=f"{'undrained' if undrained else 'drained'} step 1")
                if not undrained:
                    for k in (20, 50, 80):
                        axes[2].semilogy(range(len(res.residuals[k])), res.residuals[k], "o-", ms=3,
                                         label=f"drained step {k + 1}")
                    out["newton_8x16_drained"] = [
                        {"step": k + 1, "relative_residuals": ", ".join(f"{r:.1e}" for r in res.residuals[k])}
                        for k in (0, 20, 50, 80) if k < len(res.residuals)]
            ax.plot(res.column("eps11"), res.column("q") / 1e3, "o", ms=3, label=f"FEM {mesh[0]}x{mesh[1]}")
            ax.set_title(f"{'undrained' if undrained else 'drained'}, 200 kPa, ntheta=360")
            ax.set_xlabel("axial strain"), ax.set_ylabel("q [kPa]"), ax.legend(fontsize=8)
    axes[2].set_xlabel("Newton iteration"), axes[2].set_ylabel("residual / reference force")
    axes[2].legend(fontsize=8), axes[2].set_title("global Newton, 8x16 Q4")
    fig.tight_layout()
    fig.savefig(FIGURES / "fem-homogeneous.png", dpi=110)
    plt.close(fig)
    out["homogeneous"] = rows


def band(out: dict) -> None:
    from hmodel.stability import along_biaxial

    params = Params(n_theta=90, sliding_rhs="equilibrium")
    zone = (0.0, 0.05, 0.01)
    imp = f"phi_g=25,alpha0=55@{zone[0]},{zone[1]},{zone[2]}"
    meshes = ((4, 8), (8, 16), (12, 24))
    fig, axes = plt.subplots(1, len(meshes) + 1, figsize=(13, 5))
    rows, curve = [], None
    for j, mesh in enumerate(meshes):
        t = time.perf_counter()
        res = biaxial(params, 2e5, 0.10, mesh=mesh, n_steps=50, imperfection=imp, n_saved=50,
                      reference=curve is None)
        wall = time.perf_counter() - t
        if curve is None:
            curve = material_point_curve(res.reference)
        q = res.column("q")
        ipk = int(np.argmax(q))
        snaps = {s.step: s for s in res.snapshots}
        last = res.snapshots[-1]
        inc = deviatoric_strain(last.eps - snaps[ipk].eps)  # after the peak
        x, dx = res.gauss_x, res.gauss_dx
        far = (x[0] - zone[0]) ** 2 + (x[1] - zone[1]) ** 2 > (2 * zone[2]) ** 2
        band = shear_band(res, zone)  # the same band the CLI reports
        conc = band["concentration"]
        angle = band["angle_deg"] if band["angle_deg"] is not None else float("nan")
        # onset: first step whose deviatoric strain increment is twice its average somewhere
        onset = float("nan")
        for k in range(1, len(res.snapshots)):
            a, b = res.snapshots[k - 1], res.snapshots[k]
            d = deviatoric_strain(b.eps - a.eps)
            if concentration(np.where(far, d, 0.0), dx) > 2:
                onset = float(res.column("eps11")[b.step])
                break
        rows.append({"mesh": f"{mesh[0]}x{mesh[1]}", "gauss_points": int(dx.size), "seconds": wall,
                     "stopped": res.stopped, "peak_strain": float(res.column("eps11")[ipk]),
                     "peak_q": float(q[ipk]), "band_angle_deg": angle, "post_peak_concentration": conc,
                     "localization_onset": onset,
                     "q_end": float(q[-1])})
        ax = axes[j]
        sc = ax.scatter(x[0], x[1], c=inc, s=2500 / dx.size ** 0.85, marker="s", cmap="viridis")
        ax.set_aspect("equal"), ax.set_title(f"{mesh[0]}x{mesh[1]}: " + (f"band {angle:.0f} deg" if angle == angle else "no band"),
                                           fontsize=9)
        ax.set_xticks([]), ax.set_yticks([])
        fig.colorbar(sc, ax=ax, fraction=0.06)
        axes[-1].plot(res.column("eps11"), q / 1e3, label=f"FEM {mesh[0]}x{mesh[1]}")
    axes[-1].plot(curve["eps11"], curve["q"] / 1e3, "k--", label="material point")
    axes[-1].set_xlabel("axial strain"), axes[-1].set_ylabel("q [kPa]"), axes[-1].legend(fontsize=8)
    fig.suptitle("deviatoric strain increment after the peak (edge imperfection at left mid-height)")
    fig.tight_layout()
    fig.savefig(FIGURES / "fem-band.png", dpi=110)
    plt.close(fig)
    phi, psi = peak_angles(curve)
    st = along_biaxial(params, 2e5, 0.10, every=10, step=1e-3)
    out["band"] = {"rows": rows, "phi_peak": phi, "psi_peak": psi, **theory_angles(phi, psi),
                   "material_point_peak_strain": float(curve["eps11"][np.argmax(curve["q"])]),
                   "material_point_bifurcation": st.bifurcation,
                   "material_point_controllability": st.controllability}


def footings(out: dict) -> None:
    params = Params(n_theta=90, sliding_rhs="equilibrium")
    fig, ax = plt.subplots(figsize=(6, 4))
    rows = []
    for mesh in ((10, 5), (20, 10), (40, 20)):
        t = time.perf_counter()
        res = footing(params, 1e5, 0.05, mesh=mesh, n_steps=25)
        s, p = res.column("s_B"), res.column("pressure")
        rows.append({"mesh": f"{mesh[0]}x{mesh[1]}", "seconds": time.perf_counter() - t, "stopped": res.stopped,
                     "s_B_reached": float(s[-1]), "pressure_at_0.01": float(np.interp(0.01, s, p)) if s[-1] >= 0.01 else None,
                     "pressure_at_0.03": float(np.interp(0.03, s, p)) if s[-1] >= 0.03 else None,
                     "pressure_end": float(p[-1])})
        ax.plot(s, p / 1e3, "o-", ms=3, label=f"{mesh[0]}x{mesh[1]} Q4")
    ax.set_xlabel("settlement / footing width"), ax.set_ylabel("footing pressure [kPa]"), ax.legend()
    ax.set_title("rigid rough strip footing, p0 = 100 kPa, ntheta=90")
    fig.tight_layout()
    fig.savefig(FIGURES / "fem-footing.png", dpi=110)
    plt.close(fig)
    out["footing"] = rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", default="abc")
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("fem_study.json"))
    args = ap.parse_args()
    out = json.loads(args.out.read_text()) if args.out.exists() else {}
    for key, fn in (("a", homogeneous), ("b", band), ("c", footings)):
        if key in args.parts:
            fn(out)
            args.out.write_text(json.dumps({**provenance(__file__, args), **out}, indent=1, default=float) + "\n")
    print(json.dumps(out, indent=1, default=float))


if __name__ == "__main__":
    main()
