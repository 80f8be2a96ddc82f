"""A specimen's void ratio and the REV's initial state: one parameter set across densities.

Derived here (docs/calibration.md, "One parameter set across densities"). Specimens of one sand
at different void ratios e0 are made of the same grains, so their volumes per unit solid volume
are in the ratio of (1 + e0). The REV represents the specimen and its initial cells are unloaded
with rigid grains in contact (d1 = d2 = 2r, eq. 1.2), so the only freedom of its initial
geometry is the opening angle α0, and its initial volume V0(α0) is the (weighted) mean
meso-volume of its cells (eqs. 1.18–1.21, and their 3D lifts for the bi-hexagon). Asking the
REV's volume to follow the specimen's,

    V0(α0) / V0(α_ref) = (1 + e0) / (1 + e_ref),

gives α0 at any e0 from the α_ref calibrated at a reference void ratio e_ref, with no new
parameter. V0 grows with α0 up to the loosest cell (2D hexagon: 60°, 3D bi-hexagon: 70.5°) and
falls beyond; the map takes the branch below it, where α0 falls as the specimen densifies.

>>> from hmodel.params import Params
>>> p = Params(alpha0=math.radians(54.5))
>>> round(math.degrees(alpha0_for_void_ratio(p, 3, e0=0.815, e_ref=0.815)), 6)
54.5
>>> round(math.degrees(loosest_alpha0(p, 3)), 2)
70.53
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from ..cell.bihex import bihex_volume, initial_bihex
from ..cell.mesostress import meso_volume
from ..cell.state import initial_cells
from ..errors import InputError
from ..params import Params
from .directions import opening_angles

#: Gauss-Legendre points of the 3D mean volume over a spread of α0 (:func:`initial_volume`).
GAUSS_POINTS = 32
#: The H-cell's opening angles (eq. 1.2 needs α in (30°, 90°)) [rad].
ALPHA_RANGE = (math.pi / 6, math.pi / 2)


def initial_volume(params: Params, dim: int, alpha0: float | None = None) -> float:
    """The mean meso-volume of the REV's unloaded cells at opening angle ``alpha0`` [rad]
    (default ``params.alpha0``), for ``params.volume``; over the cells' own α0 when
    ``alpha0_spread`` > 0 (2D: the n_theta quantiles; 3D: the uniform distribution's mean).
    Proportional to the REV's initial volume V0."""
    p = params if alpha0 is None else replace(params, alpha0=float(alpha0))
    if dim == 3:
        if p.alpha0_spread == 0:
            return float(bihex_volume(p, initial_bihex(p, np.array([p.alpha0])).values)[0])
        # the mean over the uniform distribution of α0 (Gauss-Legendre), of which the REV's
        # weighted cells are the midpoint rule (weighted_opening_angles)
        x, wq = np.polynomial.legendre.leggauss(GAUSS_POINTS)
        a = p.alpha0 + p.alpha0_half_width * x
        return float(0.5 * wq @ bihex_volume(p, initial_bihex(p, a).values))
    return float(np.mean(meso_volume(p, initial_cells(p, opening_angles(p)))))


def loosest_alpha0(params: Params, dim: int) -> float:
    """The opening angle [rad] of the REV's largest initial volume (the loosest packing its
    cells can have)."""
    res = minimize_scalar(lambda a: -initial_volume(params, dim, a), bounds=ALPHA_RANGE, method="bounded",
                          options={"xatol": 1e-10})
    return float(res.x)


def alpha0_for_void_ratio(params: Params, dim: int, e0: float, e_ref: float) -> float:
    """The opening angle α0 [rad] of a specimen at void ratio ``e0`` whose sand has
    ``params.alpha0`` at ``e_ref``: V0(α0) = V0(α_ref) (1 + e0) / (1 + e_ref), on the branch
    below the loosest cell. A one-line InputError when no cell of this geometry is that loose
    or that dense."""
    for name, e in (("e0", e0), ("e_ref", e_ref)):
        if not (math.isfinite(e) and e > 0):
            raise InputError(f"{name} must be a positive void ratio, got {e:g}")
    loosest = loosest_alpha0(params, dim)
    if params.alpha0 > loosest + 1e-9:
        raise InputError(f"alpha0 = {math.degrees(params.alpha0):.4g} deg lies beyond the loosest cell "
                         f"({math.degrees(loosest):.4g} deg): the density map needs alpha0 below it")
    target = initial_volume(params, dim) * (1 + e0) / (1 + e_ref)
    lo = ALPHA_RANGE[0] + 1e-9
    f = lambda a: initial_volume(params, dim, a) - target  # noqa: E731
    if f(loosest) < 0:
        e_max = (1 + e_ref) * initial_volume(params, dim, loosest) / initial_volume(params, dim) - 1
        raise InputError(f"e0 = {e0:g} is looser than the loosest cell can carry from alpha0 = "
                         f"{math.degrees(params.alpha0):.4g} deg at e_ref = {e_ref:g} (e0 <= {e_max:.4g})")
    if f(lo) > 0:
        e_min = (1 + e_ref) * initial_volume(params, dim, lo) / initial_volume(params, dim) - 1
        raise InputError(f"e0 = {e0:g} is denser than the densest cell can carry from alpha0 = "
                         f"{math.degrees(params.alpha0):.4g} deg at e_ref = {e_ref:g} (e0 >= {e_min:.4g})")
    if abs(e0 - e_ref) == 0:
        return params.alpha0
    return float(brentq(f, lo, loosest, xtol=1e-13, rtol=1e-13))


def largest_alpha0(params: Params, dim: int, e_max: float, e_ref: float) -> float:
    """The largest α0 [rad] at ``e_ref`` from which a specimen at ``e_max`` (>= ``e_ref``) is
    still within the loosest cell: V0(α) = V0(loosest) (1 + e_ref) / (1 + e_max)."""
    loosest = loosest_alpha0(params, dim)
    target = initial_volume(params, dim, loosest) * (1 + e_ref) / (1 + max(e_max, e_ref))
    lo = ALPHA_RANGE[0] + 1e-9
    if initial_volume(params, dim, lo) >= target:
        return lo
    return float(brentq(lambda a: initial_volume(params, dim, a) - target, lo, loosest, xtol=1e-13))
