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
