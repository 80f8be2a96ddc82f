"""Figures of loading paths, in the style of the report (Figs. 1.7, 1.8). PNG via Matplotlib."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from .loading.result import PathResult


def _label(result: PathResult, b: int) -> str:
    p0 = result.meta.get("p0")
    parts = []
    if p0 is not None and len(p0) and (b < len(p0) or len(p0) == 1):
        parts.append(f"$p_0$ = {p0[b if b < len(p0) else 0] / 1e3:g} kPa")
    sets = result.meta.get("point_params")
    if sets and b < len(sets):  # per-point parameter sets: the parameters that differ
        parts += [f"{k}={sets[b][k]:g}" if isinstance(sets[b][k], float) else f"{k}={sets[b][k]}"
                  for k in sets[0] if len({str(s[k]) for s in sets}) > 1]
    return ", ".join(parts) if parts else f"point {b}"


def _subtitle(result: PathResult) -> str:
    p = result.meta.get("params", {})
    sphere = result.meta.get("sphere")
    keys = ("kn", "kt_kn", "phi_g", "alpha0", "alpha_omega", "n_theta", "volume", "g2")
    if sphere is not None:  # 3D: the sphere's directions and fabric, not the 2D ones
        keys = ("kn", "kt_kn", "phi_g", "alpha0", "volume", "g2", "sliding_rhs")
    if p.get("contact") == "hertz-mindlin":  # kn and kt/kn are not read (docs/mechanisms.md)
        keys = ("shear_modulus", "poisson", *(k for k in keys if k not in ("kn", "kt_kn")))
    units = {"phi_g": "°", "alpha0": "°"}
    text = ", ".join(f"{k}={p[k]:g}{units.get(k, '')}" if isinstance(p[k], float) else f"{k}={p[k]}"
                     for k in keys if k in p)
    on = [name for key, value, name in (("contact", "hertz-mindlin", "Hertz–Mindlin contacts"),
                                        ("renewal", "rebirth", "cells reborn"),
                                        ("renewal", "mix", "cells reborn at the mean box"),
                                        ("cross_contacts", "frictionless", "contacts between the hexagons"),
                                        ("lateral", "axisymmetric", "lateral strain about the cell's axis"))
          if p.get(key) == value and (key != "lateral" or sphere is not None)]
    if result.meta.get("radial") == "equal":
        on.append("one radial strain")
    if on:
        text += ", " + ", ".join(on)
    if sphere is not None:
        text += (f", Lebedev order {sphere['order']} × {sphere['n_azimuth']} azimuths, "
                 f"fabric α_ω={sphere['alpha_omega']:g}")
    return text


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


def _stage_runs(stage: np.ndarray) -> list[tuple[str, int, int]]:
    """The contiguous runs of one stage name along a result: (name, first row, end row)."""
    if not len(stage):
        return []
    change = np.flatnonzero(stage[1:] != stage[:-1]) + 1
    starts, ends = np.concatenate([[0], change]), np.concatenate([change, [len(stage)]])
    return [(str(stage[a]), int(a), int(b)) for a, b in zip(starts, ends)]


def _stage_styles(runs: list[tuple[str, int, int]], rows: np.ndarray) -> dict[str, dict]:
    """Per stage name: its colour, line width and legend label. Consolidation is grey; stages
    named earlier are drawn wider, so that a later stage retracing an earlier one's line (a
    drained unloading and reloading on the loading's stress path) shows on top of it; the label
    gives the rows of result.csv the stage holds, or how many times a cycle ran it."""
    from matplotlib import colormaps

    names = list(dict.fromkeys(n for n, _, _ in runs))
    palette = colormaps["tab10"].colors
    others = [n for n in names if n != "consolidation"]
    styles = {}
    for n in names:
        mine = [(a, b) for m, a, b in runs if m == n]
        label = (f"{n} (rows {rows[mine[0][0]]}–{rows[mine[0][1] - 1]})" if len(mine) == 1
                 else f"{n} ({len(mine)} times)")
        if n == "consolidation":
            styles[n] = {"color": "0.55", "lw": 1.5, "label": label}
            continue
        k = others.index(n)
        width = 1.0 + 2.0 * (len(others) - 1 - k) / max(len(others) - 1, 1) if len(others) <= 6 else 0.9
        styles[n] = {"color": palette[k % len(palette)], "lw": width, "label": label}
    return styles


def _plot_by_stage(ax, x: np.ndarray, y: np.ndarray, runs, styles, marker: str = "") -> None:
    """``y`` against ``x`` in the colour of each row's stage, every run joined to the last row
    before it (the curve stays one line), each stage labelled once for the legend."""
    seen = set()
    for name, a, b in runs:
        seg = slice(max(a - 1, 0), b)
        st = styles[name]
        ax.plot(x[seg], y[seg], marker or "-", color=st["color"], lw=st["lw"], ms=1.5,
                label=st["label"] if name not in seen else None)
        seen.add(name)


def program_figure(result: PathResult) -> Figure:
    """A loading program's figure: the stress path (p, q), q against eps11 (the loops of cycles),
    the mean stress by row of result.csv (or the excess pore pressure p0 − p of undrained stages)
    and per cycle the least p/p0 and the double-amplitude strain (or, without cycles, eps_v
    against eps11); every curve coloured by stage, consolidation included, with one legend of
    the stages; titled with the program's file name."""
    from .loading.program import cycle_summary

    fig = Figure(figsize=(12, 8.4), layout="constrained")
    (a, b), (c, d) = fig.subplots(2, 2)
    r = result.point(0)
    rows = np.asarray(r["step"])
    runs = _stage_runs(np.asarray(r["stage"]))
    styles = _stage_styles(runs, rows)
    _plot_by_stage(a, r["p"] / 1e3, r["q"] / 1e3, runs, styles)
    if result.meta.get("dim") == 3:
        a.set(xlabel=r"$p=\mathrm{tr}\,\sigma/3$ [kPa]", ylabel=r"$q=\sigma_{11}-(\sigma_{22}+\sigma_{33})/2$ [kPa]",
              title="stress path")
    else:
        a.set(xlabel=r"$p=(\sigma_{11}+\sigma_{22})/2$ [kPa]", ylabel=r"$q=\sigma_{11}-\sigma_{22}$ [kPa]",
              title="stress path")
    _plot_by_stage(b, 100 * r["eps11"], r["q"] / 1e3, runs, styles)
    b.set(xlabel=r"$\varepsilon_{11}$ [%]", ylabel="q [kPa]", title="q against axial strain")
    p0 = (result.meta.get("p0") or [None])[0]
    und = np.isin(r["stage"], result.meta.get("undrained_stages", []))
    if p0 is not None and und.any():
        excess = np.where(und, (p0 - r["p"]) / 1e3, np.nan)  # drained rows left blank
        _plot_by_stage(c, rows, excess, runs, styles, marker=".")
        c.set(xlabel="row of result.csv", ylabel=r"excess pore pressure $p_0-p$ [kPa]",
              title="undrained stages", xlim=(0, rows[-1] + 1))
    else:
        _plot_by_stage(c, rows, r["p"] / 1e3, runs, styles)
        c.set(xlabel="row of result.csv", ylabel="p [kPa]", title="mean stress")
    cycles = cycle_summary(result)
    if cycles:
        n = [row["cycle"] for row in cycles]
        d.plot(n, [row["p_min_over_p0"] for row in cycles], "o-", ms=3, label=r"least $p/p_0$")
        d.plot(n, [100 * row["double_amplitude_eps11"] for row in cycles], "s-", ms=3,
               label=r"double amplitude $\varepsilon_{11}$ [%]")
        d.set(xlabel="cycle", title=f"{len(cycles)} cycle{'s' if len(cycles) != 1 else ''}")
        d.legend(frameon=False)
    else:
        _plot_by_stage(d, 100 * r["eps11"], 100 * r["eps_v"], runs, styles)
        d.set(xlabel=r"$\varepsilon_{11}$ [%]", ylabel=r"$\varepsilon_v$ [%]", title="volumetric strain")
    if len(runs) <= 8:  # few stages: each one's start marked and named on the by-row panel
        for name, first, _ in runs[1:]:
            c.axvline(rows[first] - 0.5, color="0.6", lw=0.8, ls="--")
            c.annotate(name, (rows[first], 1), xycoords=("data", "axes fraction"), xytext=(2, -2),
                       textcoords="offset points", va="top", rotation=90, fontsize=7, color="0.3")
    for ax in (a, b, c, d):
        ax.grid(alpha=0.3)
    handles, labels = a.get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=min(len(labels), 5), frameon=False,
               title="stages (earlier ones drawn wider, so that a line retraced later stays visible)")
    name = result.meta.get("program", "")
    source = result.meta.get("file") or name
    extra = f" ({name})" if name and Path(source).stem != name else ""
    fig.suptitle(f"H-model, program {source}{extra}\n{_subtitle(result)}", fontsize=10)
    return fig


def plot_program(result: PathResult, path: "str | os.PathLike") -> None:
    """The figure of :func:`program_figure`, written to ``path``."""
    program_figure(result).savefig(path, dpi=130)


def plot_triaxial(result: PathResult, path: "str | os.PathLike") -> None:
    """A 3D test (triaxial, true triaxial, oedometer) against the axial strain since the end of
    consolidation: q = σ11 − (σ22 + σ33)/2, the volumetric strain (undrained: the stress path),
    q/p, and the quantity the test is about: K0 = σr/σa (oedometer), the Lode angle (true
    triaxial), the excess pore pressure p0 − p (undrained) or the stress path (drained)."""
    test = result.meta.get("test", "")
    undrained = "undrained" in test
    fig = Figure(figsize=(12, 8.4), layout="constrained")
    (a, b), (c, d) = fig.subplots(2, 2)
    for k in range(result.n_points):
        r, cons = result.point(k).stage("shear"), result.point(k).stage("consolidation")
        if not len(cons):
            continue
        last = {n: cons[n][-1] for n in ("eps11", "eps_v", "q", "p", "q_p", "sig11", "sig22", "sig33")}
        ea = np.concatenate([[0.0], r["eps11"] - last["eps11"]]) * 100
        col = lambda n: np.concatenate([[last[n]], r[n]])  # noqa: E731
        kw = dict(label=_label(result, k), lw=1.6)
        a.plot(ea, col("q") / 1e3, **kw)
        if undrained:
            b.plot(col("p") / 1e3, col("q") / 1e3, **kw)
        else:
            b.plot(ea, (col("eps_v") - last["eps_v"]) * 100, **kw)
        c.plot(ea, col("q_p"), **kw)
        if test == "oedometer":
            d.plot(ea, 0.5 * (col("sig22") + col("sig33")) / col("sig11"), **kw)
        elif test == "true triaxial":
            d.plot(ea[1:], r["lode"], **kw)
        elif undrained:
            d.plot(ea, (last["p"] - col("p")) / 1e3, **kw)
        else:
            d.plot(col("p") / 1e3, col("q") / 1e3, **kw)
    xlabel = r"axial strain after consolidation $\Delta\varepsilon_{11}$ [%]"
    a.set(xlabel=xlabel, ylabel=r"$q=\sigma_{11}-(\sigma_{22}+\sigma_{33})/2$ [kPa]")
    if undrained:
        b.set(xlabel=r"$p=\mathrm{tr}\,\sigma/3$ [kPa]", ylabel="q [kPa]", title="stress path")
    else:
        b.set(xlabel=xlabel, ylabel=r"volumetric strain $\Delta\varepsilon_v$ [%] (compression > 0)")
        b.axhline(0.0, color="0.6", lw=0.8)
    c.set(xlabel=xlabel, ylabel="stress ratio $q/p$ [-]")
    if test == "oedometer":
        d.set(xlabel=xlabel, ylabel=r"$K_0=\sigma_r/\sigma_a$ [-]", title="coefficient of earth pressure")
    elif test == "true triaxial":
        d.set(xlabel=xlabel, ylabel="Lode angle [°]", title=f"b = {result.meta.get('b', float('nan')):g}",
              ylim=(-2, 62), yticks=(0, 15, 30, 45, 60))
    elif undrained:
        d.set(xlabel=xlabel, ylabel=r"excess pore pressure $p_0-p$ [kPa]")
    else:
        d.set(xlabel=r"$p=\mathrm{tr}\,\sigma/3$ [kPa]", ylabel="q [kPa]", title="stress path")
    for ax in (a, b, c, d):
        ax.grid(alpha=0.3)
    a.legend(frameon=False)
    fig.suptitle(f"3D H-model, {test} test\n{_subtitle(result)}", fontsize=10)
    fig.savefig(path, dpi=130)


def plot_result(result: PathResult, path: "str | os.PathLike") -> None:
    """The figure that fits the result's test."""
    test = result.meta.get("test", "")
    if test == "program":
        plot_program(result, path)
    elif "triaxial" in test or test == "oedometer":
        plot_triaxial(result, path)
    elif "biaxial" in test:
        plot_biaxial(result, path)
    elif test == "iso":
        plot_isotropic(result, path)
    else:
        plot_strain_path(result, path)


def plot_contact_fabric(rows: list[dict], path: "str | os.PathLike", dim: int, title: str = "") -> None:
    """Bars of a contact-fabric table (:func:`hmodel.rev.contacts.fabric_rows`): per band of tilt
    from the axis, the shares of the carrying contacts, of the axial and of the lateral stress,
    one bar per (point, state) of the rows, and an isotropic fabric's shares of the contacts
    (``dim`` 2 or 3)."""
    from .rev.contacts import isotropic_shares

    groups = list(dict.fromkeys((r.get("point", 0), r["state"]) for r in rows))
    bands = list(dict.fromkeys((r["tilt_lo"], r["tilt_hi"]) for r in rows))
    fig = Figure(figsize=(11, 3.6), layout="constrained")
    axes = fig.subplots(1, 3, sharey=True)
    x = np.arange(len(bands))
    width = 0.8 / len(groups)
    for ax, key, label in zip(axes, ("contacts", "sig_axial", "sig_lateral"),
                              ("carrying contacts", "axial stress", "lateral stress")):
        for g, (point, state) in enumerate(groups):
            vals = [next(r[key] for r in rows if (r.get("point", 0), r["state"]) == (point, state)
                         and (r["tilt_lo"], r["tilt_hi"]) == band) for band in bands]
            ax.bar(x - 0.4 + width * (g + 0.5), vals, width, label=f"point {point}, {state}")
        if key == "contacts":
            iso = isotropic_shares(bands, dim)
            ax.plot(x, iso, "k_", markersize=18, mew=2, label="isotropic")
        ax.set_xticks(x, [f"{lo:g}–{hi:g}°" for lo, hi in bands])
        ax.set(title=f"share of the {label}", xlabel="tilt of the contact from axis 1")
        ax.grid(alpha=0.3, axis="y")
    axes[0].set_ylabel("share")
    axes[0].legend(frameon=False, fontsize=8)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.savefig(path, dpi=130)
