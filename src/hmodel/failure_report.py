"""The files and the summary of a failure surface (:class:`hmodel.failure_surface.FailureSurface`):
what ``hmodel failure-surface`` writes and prints, for Python callers as for the CLI.

:func:`write_failure_surface` writes, all or none (:func:`hmodel.io.write_outputs`),

- ``failure_surface.csv``: one row per Lode angle, the peak and the three fits
  (:meth:`~hmodel.failure_surface.FailureSurface.table`; a missing value is an empty cell);
- ``paths.csv``: every state of every constant-p path (``point`` = the angle's index);
- ``failure_surface.json``: :func:`summary` and the parameters (null where a path has no peak);
- ``failure_surface.png``: :func:`plot_failure_surface`.

A path that ended on the tension cut-off has no peak: its friction angle and peak ratio are
empty in the CSV and null in the JSON, and :func:`warnings` names it.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from .failure_surface import (
    FailureSurface,
    full_envelope,
    lade_duncan,
    matsuoka_nakai,
    mohr_coulomb,
    pi_plane_xy,
)
from .io import write_outputs
from .params import Params
from .rev import Sphere

#: The criteria fitted at triaxial compression, by their key in
#: :meth:`~hmodel.failure_surface.FailureSurface.fits`, with the names the outputs show.
FITS = {"mohr_coulomb": "Mohr–Coulomb", "matsuoka_nakai": "Matsuoka–Nakai", "lade_duncan": "Lade–Duncan"}
#: The files :func:`write_failure_surface` writes.
FILES = ("failure_surface.csv", "paths.csv", "failure_surface.json", "failure_surface.png")


def summary(fs: FailureSurface) -> dict:
    """The numbers of a failure surface for ``failure_surface.json`` (null where a path has no
    peak: JSON has no NaN)."""
    return _no_nan({"p": fs.p, "lode": fs.lode.tolist(), "q_p": fs.ratio.tolist(), "phi": fs.phi.tolist(),
                    "ended": list(fs.ended), "peak": fs.peak.tolist(), "phi_compression": fs.phi_compression,
                    "phi_extension": fs.phi_extension, "strength_ratio": fs.strength_ratio,
                    "fit_strength_ratios": fs.fit_strength_ratios(),
                    "k_matsuoka_nakai": fs.k_matsuoka_nakai, "k_lade_duncan": fs.k_lade_duncan,
                    "warnings": warnings(fs), **fs.meta})


def _no_nan(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _no_nan(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_no_nan(v) for v in value]
    return value


def warnings(fs: FailureSurface) -> list[str]:
    """One line naming the paths that ended on the tension cut-off, if any."""
    cut = [f"{t:g}°" for t, e in zip(fs.lode, fs.ended) if e == "tension cut-off"]
    if not cut:
        return []
    return [f"Lode {', '.join(cut)}: the path reached the tension cut-off (σ3 ≈ 0) before any peak: no friction "
            "angle or strength ratio there (empty in failure_surface.csv, null in failure_surface.json)"]


def report_lines(fs: FailureSurface) -> list[str]:
    """The run's outcome in words: one line per Lode angle (its peak, or the tension cut-off),
    then the extension/compression strength ratio beside the fits' where there is one."""
    lines = [f"Lode {t:5.1f}°: no peak, σ3 fell to 0 ({how})" if how == "tension cut-off"
             else f"Lode {t:5.1f}°: peak q_eq/p = {r:.4f}, phi = {ph:.2f}° ({how})"
             for t, r, ph, how in zip(fs.lode, fs.ratio, fs.phi, fs.ended)]
    if fs.strength_ratio is not None and math.isfinite(fs.strength_ratio):
        fits = ", ".join(f"{FITS[k]} {v:.3f}" for k, v in fs.fit_strength_ratios().items())
        lines.append(f"extension/compression strength ratio: {fs.strength_ratio:.3f} (fitted at compression: {fits})")
    elif fs.strength_ratio is not None:
        where = " and ".join(f"{t:g}°" for t, e in zip(fs.lode, fs.ended)
                             if t in (0.0, 60.0) and e == "tension cut-off")
        lines.append(f"extension/compression strength ratio: none (no peak at {where}: the tension cut-off)")
    return lines


def _cell(v) -> str:
    if isinstance(v, str):
        return v
    if isinstance(v, bool):
        return "true" if v else "false"
    return repr(float(v)) if math.isfinite(v) else ""


def write_table(fs: FailureSurface, path: Path) -> None:
    """``failure_surface.csv``: :meth:`~hmodel.failure_surface.FailureSurface.table`, a
    non-finite number as an empty cell."""
    rows = fs.table()
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: _cell(v) for k, v in r.items()})


def plot_failure_surface(fs: FailureSurface, path: Path, subtitle: str = "") -> None:
    """The π-plane (q_eq/p as radius, axis 1's compression meridian up): the model's peaks,
    each criterion fitted at compression, unfolded by symmetry; and q_eq/p against ε_s along
    each path."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 5.6), layout="constrained")
    a, b = fig.subplots(1, 2)
    for key, label in FITS.items():
        crit = {"mohr_coulomb": lambda t: mohr_coulomb(fs.phi_compression, t),
                "matsuoka_nakai": lambda t: matsuoka_nakai(fs.k_matsuoka_nakai, t),
                "lade_duncan": lambda t: lade_duncan(fs.k_lade_duncan, t)}[key]
        xy = full_envelope(crit)
        a.plot(*np.vstack([xy, xy[:1]]).T, lw=1.0, label=f"{label} (fitted at θ = 0)")
    xy = pi_plane_xy(fs.ratio, fs.lode)
    a.plot(*xy.T, "ko", ms=5, label="H-model peaks")
    ended = np.sqrt(0.5 * ((fs.principal - np.roll(fs.principal, 1, axis=1)) ** 2).sum(axis=1)) / fs.p
    cut = np.array([e == "tension cut-off" for e in fs.ended])
    if cut.any():  # where those paths stopped: on σ3 = 0, not a peak
        a.plot(*pi_plane_xy(ended[cut], fs.lode[cut]).T, "kx", ms=7, label="tension cut-off (no peak)")
    for k in range(3):  # the three compression meridians
        ang = math.radians(120 * k)
        r = 1.15 * float(np.nanmax(np.where(cut, ended, fs.ratio)))
        a.plot([0, r * math.sin(ang)], [0, r * math.cos(ang)], color="0.7", lw=0.6)
        a.annotate(f"σ{k + 1}", (r * math.sin(ang), r * math.cos(ang)), fontsize=9, color="0.4")
    a.set(aspect="equal", title=f"π-plane at p = {fs.p / 1e3:g} kPa (radius q_eq/p)")
    a.legend(frameon=False, fontsize=8, loc="upper left")
    a.grid(alpha=0.2)
    paths = fs.paths
    for i, t in enumerate(fs.lode):
        r = paths.point(i).stage("ray")
        if not len(r):
            continue
        # the deviatoric strain along the ray, (2/3) sum_i cos(theta_i) eps_ii
        cos = np.cos(math.radians(float(t)) + np.array([0.0, -2.0 * math.pi / 3.0, 2.0 * math.pi / 3.0]))
        es = (2.0 / 3.0) * np.column_stack([r["eps11"], r["eps22"], r["eps33"]]) @ cos
        b.plot(100 * (es - es[0]), r["q_eq"] / fs.p, lw=1.4, label=f"θ = {t:g}° ({fs.ended[i]})")
    b.set(xlabel=r"deviatoric strain along the ray $\Delta\varepsilon_s$ [%]", ylabel=r"$q_{eq}/p$ [-]",
          title="constant-p paths")
    b.grid(alpha=0.3)
    b.legend(frameon=False, fontsize=8)
    ratio = fs.strength_ratio
    shown = ratio is not None and math.isfinite(ratio)
    fig.suptitle("3D H-model, failure surface" + (f": extension/compression {ratio:.3f}" if shown else "")
                 + (f"\n{subtitle}" if subtitle else ""), fontsize=10)
    fig.savefig(path, dpi=130)


def write_failure_surface(fs: FailureSurface, out: Path, params: Params, sphere: Sphere) -> dict:
    """Write :data:`FILES` into ``out`` (all or none) for the surface ``fs`` of the material
    ``params`` on the direction set ``sphere``; return what ``failure_surface.json`` holds."""
    info = summary(fs)
    info["params"] = params.to_dict()
    subtitle = (f"phi_g={info['params']['phi_g']:g}°, alpha0={info['params']['alpha0']:g}°, "
                f"Lebedev order {sphere.order} × {sphere.n_azimuth} azimuths")
    write_outputs(Path(out), {
        "failure_surface.csv": lambda f: write_table(fs, f),
        "paths.csv": fs.paths.to_csv,
        "failure_surface.json": lambda f: f.write_text(json.dumps(info, indent=2) + "\n"),
        "failure_surface.png": lambda f: plot_failure_surface(fs, f, subtitle),
    })
    return info
