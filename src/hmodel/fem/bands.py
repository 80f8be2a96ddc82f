"""Shear bands: the inclination measured from a strain field, and the classical predictions.

The band angle is measured from the horizontal (the direction of the minor principal stress
of the biaxial test, whose major one is the vertical axial stress): Coulomb 45° + φ/2, Roscoe
45° + ψ/2, Arthur (45° + (φ + ψ)/4), with φ the peak friction angle and ψ the dilatancy angle
at the peak of the material-point test of the same parameters (2D: sin φ = q / 2p,
sin ψ = -dε_v / dγ with dγ = dε1 - dε3, compression positive). Each of these is the angle
of a conjugate pair (±θ, symmetric about the axial direction): a specimen may form one band or
both (:func:`band_lines` tells them apart).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .outputs import deviatoric_strain
from .result import FemResult, material_point_curve

#: A band is reported where the deviatoric strain increment after the peak reaches this many
#: times its volume average somewhere (1 for a homogeneous field).
LOCALIZED = 2.0
#: Inclinations [deg] tried by :func:`band_lines`, from the horizontal, positive rising to the
#: right.
LINE_ANGLES = np.arange(-89.5, 90.5, 0.5)
#: A second band is reported at least this far [deg] from the first (nearer lines are the first
#: band's own fringe) ...
SEPARATION = 20.0
#: ... and where the field along it exceeds its median by at least this share of the first
#: band's excess (a line that merely crosses one band holds about its width over its length).
SECOND_BAND = 0.5
#: A band's inclination is the middle of the tilts whose lines score within this share of its
#: best one.
PLATEAU = 0.02


class BandLine(NamedTuple):
    """A straight band: its inclination from the horizontal [deg, (-90, 90], positive rising
    to the right] and its line, the points x with -x sin(angle) + y cos(angle) = offset [m]."""

    angle_deg: float
    offset: float


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


def _weighted_median(values: np.ndarray, dx: np.ndarray) -> float:
    order = np.argsort(values)
    cum = np.cumsum(dx[order])
    return float(values[order][np.searchsorted(cum, 0.5 * cum[-1])])


def _line_scores(x: np.ndarray, excess: np.ndarray, dx: np.ndarray, strip: float,
                 min_length: float) -> np.ndarray:
    """For each of :data:`LINE_ANGLES`, the best strip of width ``strip`` at that inclination:
    (its mean excess, its offset); strips covering less than ``strip`` × ``min_length`` of the
    specimen are not counted (a short chord through a hot corner is no band)."""
    out = np.empty((len(LINE_ANGLES), 2))
    for i, a in enumerate(np.radians(LINE_ANGLES)):
        d = -math.sin(a) * x[0] + math.cos(a) * x[1]
        order = np.argsort(d, kind="stable")
        ds = d[order]
        mass = np.concatenate([[0.0], np.cumsum((excess * dx)[order])])
        area = np.concatenate([[0.0], np.cumsum(dx[order])])
        lo = np.searchsorted(ds, ds - strip / 2, "left")
        hi = np.searchsorted(ds, ds + strip / 2, "right")
        covered = area[hi] - area[lo]
        mean = np.where(covered >= strip * min_length, (mass[hi] - mass[lo]) / np.maximum(covered, 1e-300),
                        -np.inf)
        k = int(np.argmax(mean))
        out[i] = mean[k], ds[k]
    return out


def band_lines(x: np.ndarray, values: np.ndarray, dx: np.ndarray,
               mask: np.ndarray | None = None) -> list[BandLine]:
    """The straight bands of a field at Gauss points (coordinates (2, B), weights ``dx``):
    none where it has not localized (its :func:`concentration` at most :data:`LOCALIZED`), one,
    or two (a conjugate pair: a cross, or a wedge from an edge imperfection).

    Each line is scored by the mean excess of ``values`` over their (volume-weighted) median
    in a strip two point spacings wide along it, over strips crossing at least the specimen's
    smaller side (a Radon transform of the excess, normalized by the chord); the best line is
    the first band, and the best line at least :data:`SEPARATION` degrees from it is a second
    one where its score reaches :data:`SECOND_BAND` of the first's. A second moment of the
    localized points (:func:`band_inclination`) has a single major axis and, given a cross or a
    wedge, fits one line through both branches. ``mask`` (B,) leaves points out (the
    imperfection's disc); the specimen's extent is that of all points."""
    span = float(np.min(x.max(axis=1) - x.min(axis=1)))
    if mask is not None:
        x, values, dx = x[:, mask], values[mask], dx[mask]
    if len(values) < 2 or not concentration(values, dx) > LOCALIZED:
        return []
    excess = values - _weighted_median(values, dx)
    scores = _line_scores(x, excess, dx, 2.0 * math.sqrt(float(dx.mean())), span)
    first = int(np.argmax(scores[:, 0]))
    if not scores[first, 0] > 0:
        return []
    lines = [BandLine(_refined(scores[:, 0], first), float(scores[first, 1]))]
    apart = np.abs((LINE_ANGLES - LINE_ANGLES[first] + 90.0) % 180.0 - 90.0) >= SEPARATION
    other = np.where(apart, scores[:, 0], -np.inf)
    second = int(np.argmax(other))
    if other[second] >= SECOND_BAND * scores[first, 0]:
        lines.append(BandLine(_refined(scores[:, 0], second), float(scores[second, 1])))
    return sorted(lines, reverse=True)


def _refined(score: np.ndarray, k: int) -> float:
    """The inclination of the best line, ``k``, as the middle of its plateau: the tried
    inclinations next to it (periodic over 180°) that score within :data:`PLATEAU` of it. A
    strip narrower than the band scores the same at every tilt that keeps it inside the band;
    the band's own inclination is the middle of those."""
    n, top = len(LINE_ANGLES), score[k]
    step = float(LINE_ANGLES[1] - LINE_ANGLES[0])
    ends = []
    for direction in (-1, 1):
        j = 0
        while j < n // 2 and score[(k + direction * (j + 1)) % n] >= (1.0 - PLATEAU) * top:
            j += 1
        ends.append(direction * j)
    return float((LINE_ANGLES[k] + step * 0.5 * (ends[0] + ends[1]) + 90.0) % 180.0 - 90.0)


def _nearest_line(x: np.ndarray, lines: list[BandLine]) -> np.ndarray:
    """Index of the line of ``lines`` nearest to each point (2, B)."""
    dist = [np.abs(-math.sin(math.radians(a)) * x[0] + math.cos(math.radians(a)) * x[1] - c) for a, c in lines]
    return np.argmin(np.stack(dist), axis=0)


def shear_band(res: FemResult, zone: tuple[float, float, float] | None = None, top: float = 0.2) -> dict:
    """The shear band of a biaxial run after its peak of q: the inclination [deg] from the
    horizontal of :func:`band_inclination` on the deviatoric strain increment between the first
    saved state at or after the peak and the last one (``angle_deg``; None where the field has
    not localized: its :func:`concentration` below :data:`LOCALIZED`), its :func:`band_width`
    (``width_m``, at half the largest increment), that concentration, the
    steps it spans, and with a material-point reference, its peak angles (:func:`peak_angles`)
    and the classical predictions (:func:`theory_angles`). With an imperfection ``zone``
    (x, y, R), the Gauss points within 2R of it are left out and the branch above it kept.

    ``bands``: how many bands :func:`band_lines` finds (0, 1 or 2). Two form a conjugate pair
    (a cross, or a wedge from an edge imperfection), which one second moment would fit with
    one line through both: ``conjugate`` then lists each band (``angle_deg`` signed, positive
    rising to the right, and ``width_m`` over the points nearer to it than to the other) and
    ``angle_deg``, ``width_m`` are their means (the inclination ±θ the classical angles
    predict); else ``conjugate`` is None."""
    q = res.column("q")
    peak = int(np.argmax(q))
    after = [s for s in res.snapshots if s.step >= peak]
    out: dict = {"angle_deg": None, "width_m": None, "concentration": None, "peak_step": peak,
                 "from_step": after[0].step if after else None, "to_step": res.snapshots[-1].step,
                 "bands": 0, "conjugate": None}
    if len(after) >= 2:
        inc = deviatoric_strain(after[-1].eps - after[0].eps)
        x, dx = res.gauss_x, res.gauss_dx
        mask = far = None
        if zone is not None:
            far = (x[0] - zone[0]) ** 2 + (x[1] - zone[1]) ** 2 > (2 * zone[2]) ** 2
            mask = far & (x[1] > zone[1])
        conc = concentration(inc, dx)
        out["concentration"] = conc
        lines = band_lines(x, inc, dx, mask=far) if conc > LOCALIZED else []
        if len(lines) == 2:
            near = _nearest_line(x, lines)
            kept = np.ones(dx.size, bool) if far is None else far
            pair = [{"angle_deg": a, "width_m": band_width(x, inc, dx, a, mask=kept & (near == k))}
                    for k, (a, _) in enumerate(lines)]
            out.update(bands=2, conjugate=pair, angle_deg=float(np.mean([abs(b["angle_deg"]) for b in pair])),
                       width_m=float(np.mean([b["width_m"] for b in pair])))
        elif conc > LOCALIZED and (mask is None or mask.sum() >= 2):
            out["bands"] = 1
            out["angle_deg"] = band_inclination(x, inc, dx, top=top, mask=mask)
            out["width_m"] = band_width(x, inc, dx, out["angle_deg"], mask=mask)
    if res.reference is not None:
        phi, psi = peak_angles(material_point_curve(res.reference))
        out.update(phi_peak=phi, psi_peak=psi, **theory_angles(phi, psi))
    return out

