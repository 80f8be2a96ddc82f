"""The figures of a path's stability: the d²W along the path and the response envelopes
(matplotlib, imported when a figure is drawn)."""

from __future__ import annotations

import math

import numpy as np

from .locate import PathStability
from .work import section


def plot_envelopes(envelopes: dict, path, title: str) -> None:
    """Strain-probe response envelopes, stress-probe strain responses and polar plots of the
    normalized d²W with the instability cone, in the plane of :func:`section`: (dσ11, dσ22) and
    (dε11, dε22) in 2D; in 3D the Rendulic plane (dσ11, √2 dσr) and (dε11, √2 dεr), r the
    lateral (radial) mean (σ22 + σ33)/2 of an axisymmetric state."""
    from matplotlib.figure import Figure

    three_d = any(se.deps.shape[1] == 6 for se, _ in envelopes.values())
    lat = ("√2 dσr", "√2 dεr") if three_d else ("dσ22", "dε22")
    fig = Figure(figsize=(15, 4.8), layout="constrained")
    a = fig.add_subplot(1, 3, 1)
    b = fig.add_subplot(1, 3, 2)
    c = fig.add_subplot(1, 3, 3, projection="polar")
    for strain, (se, te) in sorted(envelopes.items()):
        lab = f"ε11 = {100 * strain:.2f} %"
        ds = section(np.vstack([se.dsig, se.dsig[:1]])) / 1e3
        a.plot(ds[:, 0], ds[:, 1], "-", label=lab)
        de = section(np.vstack([te.deps, te.deps[:1]])) * 1e6
        b.plot(de[:, 0], de[:, 1], ".-", ms=3, label=lab)
        u = section(se.deps)
        t = np.arctan2(u[:, 1], u[:, 0])
        order = np.argsort(t)
        line, = c.plot(np.r_[t[order], t[order][:1]], np.r_[se.normalized[order], se.normalized[order][:1]], label=lab)
        neg = se.normalized[order] <= 0
        c.fill_between(t[order], -1, 1, where=neg, color=line.get_color(), alpha=0.15, step="mid")
    plane = "\nin the Rendulic plane, σr = (σ22 + σ33)/2" if three_d else ""
    a.set(xlabel="dσ11 [kPa]", ylabel=f"{lat[0]} [kPa]",
          title=f"strain probes: stress response envelopes{plane}")
    b.set(xlabel="dε11 [10⁻⁶]", ylabel=f"{lat[1]} [10⁻⁶]", title="stress probes: strain responses")
    c.set_title("normalized d²W against strain-probe direction\n(shaded: instability cone, d²W ≤ 0)", fontsize=9)
    c.set_ylim(-1, 1)
    a.legend(fontsize=8)
    for ax in (a, b):
        ax.axhline(0, color="k", lw=0.5)
        ax.axvline(0, color="k", lw=0.5)
    fig.suptitle(title)
    fig.savefig(path, dpi=130)


def plot_path(ps: PathStability, path, title: str) -> None:
    """Normalized d²W of the loading increments and its minimum over probes along the path,
    with the entry into the bifurcation domain and the loss of controllability marked; against
    the axial strain since consolidation, or the row of the table where it goes back (cycles)."""
    from matplotlib.figure import Figure

    r = ps.result
    sh = {k: v[r["stage"] != "consolidation"] for k, v in r.columns.items()}
    d = np.diff(ps.shear_strain)
    monotonic = bool(np.all(d >= 0) or np.all(d <= 0))  # compression or extension
    if monotonic:
        x, xc, xb, xl = (100 * ps.shear_strain, 100 * ps.check_strain, 100 * ps.bifurcation,
                         100 * ps.controllability)
        label = "axial strain since consolidation [%]"
    else:
        x, xc, xb, xl = sh["step"], ps.check_step, ps.bifurcation_step, ps.controllability_step
        label = "row of the result table (step)"
    fig = Figure(figsize=(12, 4.5), layout="constrained")
    a, b = fig.subplots(1, 2)
    a.plot(x, sh["q"] / 1e3, label="q")
    a.plot(x, sh["sig11"] / 1e3, label="σ11")
    a.set(xlabel=label, ylabel="stress [kPa]")
    b.plot(x, ps.loading_w, lw=1, label="loading increment")
    b.plot(xc, ps.check_min_w, "o-", ms=3, label="minimum over probes")
    b.axhline(0, color="k", lw=0.8)
    for ax in (a, b):
        if math.isfinite(xb):
            ax.axvline(xb, color="tab:orange", ls="--", label=f"bifurcation domain ({ps.bifurcation_by})")
        if math.isfinite(xl):
            ax.axvline(xl, color="tab:red", ls=":", label="loss of controllability")
    b.set(xlabel=label, ylabel="normalized d²W = dσ:dε / (|dσ||dε|)", ylim=(-1.05, 1.05))
    a.legend(fontsize=8)
    b.legend(fontsize=8)
    fig.suptitle(title)
    fig.savefig(path, dpi=130)
