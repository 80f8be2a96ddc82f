"""The figure of a DEM sample: for disks its packings side by side with their force chains, for
spheres the tests' curves."""

from __future__ import annotations

import math
import os

import numpy as np


def draw_sample(states: list[tuple[str, "SampleState"]], path: "str | os.PathLike") -> None:
    """The packings (title, :class:`~hmodel.dem.sample.state.SampleState`) side by side: disks,
    and contacts as lines from centre to centre whose width and colour follow the normal force
    (force chains); contacts across the periodic boundary are drawn from both ends."""
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.collections import LineCollection, PatchCollection
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle, Rectangle

    n = max(len(states), 1)
    cols = min(n, 3)
    nrows = math.ceil(n / cols)
    fig = Figure(figsize=(5.2 * cols, 5.0 * nrows), layout="constrained")
    axes = np.atleast_1d(fig.subplots(nrows, cols, squeeze=False)).ravel()
    cmap = colormaps["inferno_r"]
    for ax, (title, st) in zip(axes, states):
        lx, ly = st.cell
        ax.add_collection(PatchCollection([Circle(p, r) for p, r in zip(st.positions, st.radii)],
                                          facecolor="#e4e4e4", edgecolor="#aaaaaa", lw=0.2))
        c = st.contacts
        fn = np.clip(c[:, 2], 0.0, None)
        fmean = float(np.mean(fn)) if len(fn) and np.mean(fn) > 0 else 1.0
        i = c[:, 0].astype(int)
        j = c[:, 1].astype(int)
        a = st.positions[i]
        b = st.positions[j]
        segs = np.concatenate([np.stack([a, a + c[:, 4:6]], axis=1),
                               np.stack([b - c[:, 4:6], b], axis=1)])
        crossing = np.concatenate([np.zeros(len(c), bool),
                                   np.linalg.norm(a + c[:, 4:6] - b, axis=1) > 1e-9 * max(lx, ly)])
        keep = np.concatenate([np.ones(len(c), bool), np.zeros(len(c), bool)]) | crossing
        f2 = np.concatenate([fn, fn])[keep]
        norm = Normalize(0.0, 3.0 * fmean)
        thin = min(1.0, max(0.2, 14.0 / math.sqrt(len(st.radii))))  # finer lines for many disks
        lc = LineCollection(segs[keep], colors=cmap(norm(f2)),
                            linewidths=thin * (0.3 + 2.5 * np.clip(f2 / (3 * fmean), 0, 1.5)))
        ax.add_collection(lc)
        ax.add_patch(Rectangle((0, 0), lx, ly, fill=False, ec="k", lw=0.8))
        ax.set_xlim(-0.02 * lx, 1.02 * lx)
        ax.set_ylim(-0.02 * ly, 1.02 * ly)
        ax.set_aspect("equal")
        ax.set_xlabel("x (axis 1) [m]")
        ax.set_ylabel("y (axis 2) [m]")
        ax.set_title(title, fontsize=9)
        fig.colorbar(ScalarMappable(cmap=cmap, norm=norm), ax=ax, shrink=0.8,
                     label="normal contact force [N]")
    for ax in axes[len(states):]:
        ax.set_axis_off()
    fig.savefig(path, dpi=110 if max(len(st.radii) for _, st in states) <= 1000 else 160)


def draw_curves(tests: list[tuple[str, "dict[str, np.ndarray] | None"]], path: "str | os.PathLike") -> None:
    """The triaxial tests of a sphere sample (tables of :data:`~hmodel.dem.sample.result.CSV_COLUMNS_3D`
    by test name; None is left out): q, eps_v, the stress path and the coordination number and
    sliding fraction against the axial strain."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 8), layout="constrained")
    (aq, av), (ap, az) = fig.subplots(2, 2)
    for k, (name, t) in enumerate(tests):
        if t is None:
            continue
        c = f"C{k}"
        ea = 100 * t["eps_a"]
        aq.plot(ea, t["q"] / 1e3, color=c, label=name)
        av.plot(ea, 100 * t["eps_v"], color=c)
        ap.plot(t["p"] / 1e3, t["q"] / 1e3, color=c)
        az.plot(ea, t["coordination"], color=c)
        az.plot(ea, 10 * t["sliding"], color=c, ls="--")
    aq.set(xlabel="axial strain eps_a [%]", ylabel="q = s11 - (s22 + s33)/2 [kPa]")
    av.set(xlabel="axial strain eps_a [%]", ylabel="volumetric strain eps_v [%] (compaction > 0)")
    ap.set(xlabel="p = tr(s)/3 [kPa]", ylabel="q [kPa]", title="stress path")
    az.set(xlabel="axial strain eps_a [%]",
           ylabel="coordination z (solid), 10 x sliding fraction (dashed)")
    aq.legend(fontsize=8)
    for ax in (aq, av, ap, az):
        ax.grid(alpha=0.3)
    fig.savefig(path, dpi=110)
