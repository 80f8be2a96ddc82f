"""Shear bands: the inclination measured from a strain field, and the classical predictions.

The band angle is measured from the horizontal (the direction of the minor principal stress
of the biaxial test, whose major one is the vertical axial stress): Coulomb 45° + φ/2, Roscoe
45° + ψ/2, Arthur (45° + (φ + ψ)/4), with φ the peak friction angle and ψ the dilatancy angle
at the peak of the material-point test of the same parameters (2D: sin φ = q / 2p,
sin ψ = -dε_v / dγ with dγ = dε1 - dε3, compression positive).
"""

from __future__ import annotations

import math

import numpy as np

from .outputs import deviatoric_strain
from .result import FemResult, material_point_curve

#: A band is reported where the deviatoric strain increment after the peak reaches this many
#: times its volume average somewhere (1 for a homogeneous field).
LOCALIZED = 2.0


def peak_angles(curve: dict) -> tuple[float, float]:
    """(φ, ψ) [deg] at the peak of q of a material-point curve
    (:func:`hmodel.fem.result.material_point_curve`); ψ from the increments around the peak."""
    i = int(np.argmax(curve["q"]))
    phi = math.degrees(math.asin(curve["q"][i] / (2 * curve["p"][i])))
    j0, j1 = max(i - 1, 0), min(i + 1, len(curve["q"]) - 1)
    de1 = curve["eps11"][j1] - curve["eps11"][j0]
    dev = curve["eps_v"][j1] - curve["eps_v"][j0]
    psi = math.degrees(math.asin(float(np.clip(-dev / (2 * de1 - dev), -1, 1))))
    return phi, psi


def theory_angles(phi: float, psi: float) -> dict[str, float]:
    """Band inclinations [deg] from the horizontal after Coulomb, Roscoe and Arthur."""
    return {"coulomb": 45 + phi / 2, "roscoe": 45 + psi / 2, "arthur": 45 + (phi + psi) / 4}


def concentration(values: np.ndarray, dx: np.ndarray) -> float:
    """Largest value over the volume average: 1 for a homogeneous field."""
    return float(np.max(values) / (dx @ values / dx.sum()))


def band_inclination(x: np.ndarray, values: np.ndarray, dx: np.ndarray, top: float = 0.2,
                     mask: np.ndarray | None = None) -> float:
    """Inclination [deg, 0..90] from the horizontal of the band formed by the Gauss points
    (coordinates (2, B)) holding the ``top`` fraction of the specimen's volume with the
    largest ``values`` (e.g. the deviatoric strain increment after the peak): the major axis
    of their volume-weighted second moment. Meaningful for one straight band (not for a
    cross of two conjugate ones, whose second moment has no single direction: ``mask`` (B,)
    keeps one branch, e.g. the half above an edge imperfection, without its disc)."""
    if mask is not None:
        x, values, dx = x[:, mask], values[mask], dx[mask]
    order = np.argsort(values)[::-1]
    keep = order[: max(2, int(np.searchsorted(np.cumsum(dx[order]), top * dx.sum())) + 1)]
    w = dx[keep] * values[keep]
    c = (x[:, keep] * w).sum(axis=1) / w.sum()
    d = x[:, keep] - c[:, None]
    cov = (d * w) @ d.T / w.sum()
    vals, vecs = np.linalg.eigh(cov)
    v = vecs[:, np.argmax(vals)]
    return float(np.degrees(np.arctan2(abs(v[1]), abs(v[0]))))


def band_width(x: np.ndarray, values: np.ndarray, dx: np.ndarray, angle_deg: float, level: float = 0.5,
               mask: np.ndarray | None = None) -> float:
    """Width [m] of a straight band inclined at ``angle_deg`` from the horizontal: the Gauss
    points (coordinates (2, B), weights ``dx``) whose ``values`` reach ``level`` times the
    largest, their volume-weighted spread across the band (distance d to the line through
    their centroid), width = sqrt(12 <d^2>). For a top-hat profile across the band this is its
    width; for a bell-shaped one at ``level`` 0.5, its full width at half maximum (the points
    above half the maximum fill |d| < FWHM/2 uniformly). ``mask`` as in :func:`band_inclination`."""
    if mask is not None:
        x, values, dx = x[:, mask], values[mask], dx[mask]
    keep = values >= level * values.max()
    x, dx = x[:, keep], dx[keep]
    a = math.radians(angle_deg)
    # the band's direction (cos a, sin a) up to its sign: try both and keep the narrower
    widths = []
    for s in (1.0, -1.0):
        n = np.array([-s * math.sin(a), math.cos(a)])
        d = n @ x
        d = d - (dx @ d) / dx.sum()
        widths.append(math.sqrt(12.0 * (dx @ d**2) / dx.sum()))
    return float(min(widths))


def shear_band(res: FemResult, zone: tuple[float, float, float] | None = None, top: float = 0.2) -> dict:
    """The shear band of a biaxial run after its peak of q: the inclination [deg] from the
    horizontal of :func:`band_inclination` on the deviatoric strain increment between the first
    saved state at or after the peak and the last one (``angle_deg``; None where the field has
    not localized: its :func:`concentration` below :data:`LOCALIZED`), its :func:`band_width`
    (``width_m``, at half the largest increment), that concentration, the
    steps it spans, and with a material-point reference, its peak angles (:func:`peak_angles`)
    and the classical predictions (:func:`theory_angles`). With an imperfection ``zone``
    (x, y, R), the Gauss points within 2R of it are left out and the branch above it kept (a
    band from an edge imperfection and its mirror form a cross)."""
    q = res.column("q")
    peak = int(np.argmax(q))
    after = [s for s in res.snapshots if s.step >= peak]
    out: dict = {"angle_deg": None, "width_m": None, "concentration": None, "peak_step": peak,
                 "from_step": after[0].step if after else None, "to_step": res.snapshots[-1].step}
    if len(after) >= 2:
        inc = deviatoric_strain(after[-1].eps - after[0].eps)
        x, dx = res.gauss_x, res.gauss_dx
        mask = None
        if zone is not None:
            far = (x[0] - zone[0]) ** 2 + (x[1] - zone[1]) ** 2 > (2 * zone[2]) ** 2
            mask = far & (x[1] > zone[1])
        conc = concentration(inc, dx)
        out["concentration"] = conc
        if conc > LOCALIZED and (mask is None or mask.sum() >= 2):
            out["angle_deg"] = band_inclination(x, inc, dx, top=top, mask=mask)
            out["width_m"] = band_width(x, inc, dx, out["angle_deg"], mask=mask)
    if res.reference is not None:
        phi, psi = peak_angles(material_point_curve(res.reference))
        out.update(phi_peak=phi, psi_peak=psi, **theory_angles(phi, psi))
    return out

