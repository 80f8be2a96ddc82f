"""Figures of loading paths, in the style of the report (Figs. 1.7, 1.8). PNG via Matplotlib."""

from __future__ import annotations

import os

import numpy as np
from matplotlib.figure import Figure

from .loading.result import PathResult


def _label(result: PathResult, b: int) -> str:
    p0 = result.meta.get("p0")
    if p0 is not None and b < len(p0):
        return f"$p_0$ = {p0[b] / 1e3:g} kPa"
    return f"point {b}"


def _subtitle(result: PathResult) -> str:
    p = result.meta.get("params", {})
    keys = ("kn", "kt_kn", "phi_g", "alpha0", "alpha_omega", "n_theta", "volume", "g2")
    units = {"phi_g": "°", "alpha0": "°"}
    return ", ".join(f"{k}={p[k]:g}{units.get(k, '')}" if isinstance(p[k], float) else f"{k}={p[k]}"
                     for k in keys if k in p)


def plot_biaxial(result: PathResult, path: "str | os.PathLike") -> None:
    """Stress ratio and volumetric strain against axial strain (Fig. 1.7) and q (Fig. 1.8)."""
    fig = Figure(figsize=(14, 4.4), layout="constrained")
    axes = fig.subplots(1, 3)
    undrained = "undrained" in result.meta.get("test", "")
    for b in range(result.n_points):
        r, c = result.point(b).stage("shear"), result.point(b).stage("consolidation")
        # Strains from the end of consolidation, as in the report's Fig. 1.7.
        e0 = (c["eps11"][-1], c["eps_v"][-1]) if len(c) else (0.0, 0.0)
        q0 = c["q"][-1] if len(c) else 0.0
        e1 = np.concatenate([[0.0], r["eps11"] - e0[0]]) * 100
        qp = np.concatenate([[q0 / c["p"][-1] if len(c) else 0.0], r["q_p"]])
        ev = np.concatenate([[0.0], r["eps_v"] - e0[1]]) * 100
        q = np.concatenate([[q0], r["q"]]) / 1e3
        kw = dict(label=_label(result, b), lw=1.6)
        axes[0].plot(e1, qp, **kw)
        if undrained:  # eps_v is constant: show the stress path instead
            axes[1].plot(np.concatenate([[c["p"][-1] if len(c) else 0.0], r["p"]]) / 1e3, q, **kw)
        else:
            axes[1].plot(e1, ev, **kw)
        axes[2].plot(e1, q, **kw)
    axes[0].set_ylabel("stress ratio $q/p$ [-]")
    axes[1].set_ylabel(r"volumetric strain $\Delta\varepsilon_v$ [%] (compression > 0)")
    axes[2].set_ylabel(r"deviatoric stress $q=\sigma_{11}-\sigma_{22}$ [kPa]")
    for ax in axes:
        ax.set_xlabel(r"axial strain after consolidation $\Delta\varepsilon_{11}$ [%]")
        ax.grid(alpha=0.3)
    if undrained:
        axes[1].set_xlabel(r"mean stress $p=(\sigma_{11}+\sigma_{22})/2$ [kPa]")
        axes[1].set_ylabel(r"deviatoric stress $q$ [kPa]")
    else:
        axes[1].axhline(0.0, color="0.6", lw=0.8)
    axes[0].legend(frameon=False)
    fig.suptitle(f"H-model, {result.meta.get('test', 'biaxial')} test\n{_subtitle(result)}", fontsize=10)
    fig.savefig(path, dpi=150)


def plot_isotropic(result: PathResult, path: "str | os.PathLike") -> None:
    """Mean stress against volumetric strain."""
    fig = Figure(figsize=(6, 4.4), layout="constrained")
    ax = fig.subplots()
    for b in range(result.n_points):
        r = result.point(b)
        ax.plot(np.concatenate([[0.0], r["eps_v"]]) * 100, np.concatenate([[0.0], r["p"]]) / 1e3,
                label=_label(result, b), lw=1.6)
    ax.set_xlabel(r"volumetric strain $\varepsilon_v$ [%]")
    ax.set_ylabel(r"mean stress $p=(\sigma_{11}+\sigma_{22})/2$ [kPa]")
    ax.grid(alpha=0.3)
    ax.legend(frameon=False)
    fig.suptitle(f"H-model, isotropic compression\n{_subtitle(result)}", fontsize=10)
    fig.savefig(path, dpi=150)


def plot_strain_path(result: PathResult, path: "str | os.PathLike") -> None:
    """Stresses along the path (by row) and the stress path in the (p, q) plane."""
    fig = Figure(figsize=(11, 4.4), layout="constrained")
    axes = fig.subplots(1, 2)
    r = result.point(0)
    row = np.arange(1, len(r) + 1)
    for name, lab in (("sig11", r"$\sigma_{11}$"), ("sig22", r"$\sigma_{22}$"), ("sig12", r"$\sigma_{12}$")):
        axes[0].plot(row, r[name] / 1e3, label=lab, lw=1.4)
    axes[0].set_xlabel("row of the strain path")
    axes[0].set_ylabel("stress [kPa] (compression > 0)")
    axes[0].legend(frameon=False)
    axes[1].plot(r["p"] / 1e3, r["q"] / 1e3, lw=1.4)
    axes[1].set_xlabel(r"$p=(\sigma_{11}+\sigma_{22})/2$ [kPa]")
    axes[1].set_ylabel(r"$q=\sigma_{11}-\sigma_{22}$ [kPa]")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle(f"H-model, prescribed strain path\n{_subtitle(result)}", fontsize=10)
    fig.savefig(path, dpi=150)


def plot_program(result: PathResult, path: "str | os.PathLike") -> None:
    """A loading program: the stress path (p, q), q against eps11 (the loops of cycles), the
    excess pore pressure p0 − p of undrained stages by increment, and per cycle the least
    p/p0 and the double-amplitude strain (or, without cycles, eps_v against eps11)."""
    from .loading.program import cycle_summary

    fig = Figure(figsize=(12, 8.4), layout="constrained")
    (a, b), (c, d) = fig.subplots(2, 2)
    r = result.point(0)
    r = PathResult({k: v[r["stage"] != "consolidation"] for k, v in r.columns.items()}, r.meta)
    a.plot(r["p"] / 1e3, r["q"] / 1e3, lw=0.8)
    a.set(xlabel=r"$p=(\sigma_{11}+\sigma_{22})/2$ [kPa]", ylabel=r"$q=\sigma_{11}-\sigma_{22}$ [kPa]",
          title="stress path")
    b.plot(100 * r["eps11"], r["q"] / 1e3, lw=0.8)
    b.set(xlabel=r"$\varepsilon_{11}$ [%]", ylabel="q [kPa]", title="q against axial strain")
    p0 = (result.meta.get("p0") or [None])[0]
    und = np.isin(r["stage"], result.meta.get("undrained_stages", []))
    if p0 is not None and und.any():
        c.plot(r["step"][und], (p0 - r["p"][und]) / 1e3, ".", ms=1.5)
        c.set(xlabel="increment (row of result.csv)", ylabel=r"excess pore pressure $p_0-p$ [kPa]",
              title="undrained stages")
    else:
        c.plot(r["step"], r["p"] / 1e3, lw=0.8)
        c.set(xlabel="increment (row of result.csv)", ylabel="p [kPa]", title="mean stress")
    cycles = cycle_summary(result)
    if cycles:
        n = [row["cycle"] for row in cycles]
        d.plot(n, [row["p_min_over_p0"] for row in cycles], "o-", ms=3, label=r"least $p/p_0$")
        d.plot(n, [100 * row["double_amplitude_eps11"] for row in cycles], "s-", ms=3,
               label=r"double amplitude $\varepsilon_{11}$ [%]")
        d.set(xlabel="cycle", title=f"{len(cycles)} cycles")
        d.legend(frameon=False)
    else:
        d.plot(100 * r["eps11"], 100 * r["eps_v"], lw=0.8)
        d.set(xlabel=r"$\varepsilon_{11}$ [%]", ylabel=r"$\varepsilon_v$ [%]", title="volumetric strain")
    for ax in (a, b, c, d):
        ax.grid(alpha=0.3)
    fig.suptitle(f"H-model, program {result.meta.get('program', '')}\n{_subtitle(result)}", fontsize=10)
    fig.savefig(path, dpi=130)


def plot_result(result: PathResult, path: "str | os.PathLike") -> None:
    """The figure that fits the result's test."""
    test = result.meta.get("test", "")
    if test == "program":
        plot_program(result, path)
    elif "biaxial" in test:
        plot_biaxial(result, path)
    elif test == "iso":
        plot_isotropic(result, path)
    else:
        plot_strain_path(result, path)
