"""Cell descriptions (mesostructures): the grains of a cell and how they are driven.

They live with the cells, below both the DEM solver that runs them in YADE (:mod:`hmodel.dem`)
and the surrogates that learn them (:mod:`hmodel.surrogate.formulations.meso`), which need their geometry
without YADE; the cells' state layout is :mod:`hmodel.cell.geometry`.

A :class:`Mesostructure` lists grains (radius, initial centre in the cell frame n = x, t = y)
and how each is moved when the cell lengths change: ``"n"`` grains are driven along n (their
n-coordinate scales with l1 about the cell centre), ``"t"`` grains along t (t-coordinate
scales with l2), ``"free"`` grains are moved by their contacts only. A driven grain is free in
the other in-plane direction. The standard H-cell (report Fig. 1.2, eq. 1.2 with the geometry
of docs/model.md, "Known slips") is

- grains 1 and 4 (indices 0, 3) at (-/+ l1/2, 0), driven along n;
- grains 2, 3 (indices 1, 2) at (-/+ d2/2, +l2/2), grains 6, 5 (indices 5, 4) at
  (-/+ d2/2, -l2/2), driven along t;
- contacts of type 1: 1-2, 1-6, 4-3, 4-5 (length d1, angle alpha to n); of type 2: 2-3, 5-6.

Meso-volume. :meth:`Mesostructure.volume` is the area of the convex polygon through the centres
of the driven grains. For the standard cell that polygon is the hexagon 1-2-3-4-5-6 and its
area is V = 2 d1 sin(alpha) (d2 + d1 cos(alpha)), the ``hexagon`` volume of
:mod:`hmodel.cell.mesostress` (eq. 1.20); the richer cells here keep the same six driven grains,
so their volume is the same hexagon's area (a free grain inside adds no volume).

Lengths in the unit of the grain radius (m), angles in rad.
"""

from __future__ import annotations

import inspect
import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

#: Local grain indices of the standard cell's contacts of type 1 and type 2, and the sign that
#: maps the tangential component ft = f.(e_y, -e_x) of each type-1 contact onto T1 (mirror
#: images of contact 1-2 about the n or t axis flip the sense of rotation).
TYPE1 = ((0, 1), (0, 5), (2, 3), (3, 4))
TYPE1_SIGN = (1.0, -1.0, -1.0, 1.0)
TYPE2 = ((1, 2), (4, 5))
DRIVES = ("n", "t", "free")


@dataclass(frozen=True)
class Mesostructure:
    """A 2D cell of disks.

    Attributes
    ----------
    name : str
    radii : ndarray, shape (g,)
        Grain radii [m].
    positions : ndarray, shape (g, 2)
        Initial centres (n, t) in the cell frame [m], cell centre at the origin.
    drive : tuple of str, length g
        ``"n"``, ``"t"`` or ``"free"`` for every grain.
    l1, l2 : float
        Reference cell lengths [m]; an increment dl1 moves an ``"n"`` grain by x_n dl1 / l1.
    """

    name: str
    radii: np.ndarray
    positions: np.ndarray
    drive: tuple[str, ...]
    l1: float
    l2: float

    def __post_init__(self) -> None:
        g = len(self.radii)
        if self.positions.shape != (g, 2) or len(self.drive) != g:
            raise InputError(f"mesostructure {self.name!r}: radii, positions and drive differ in length")
        if not all(d in DRIVES for d in self.drive):
            raise InputError(f"mesostructure {self.name!r}: drive must be one of {', '.join(DRIVES)}")
        if np.any(self.radii <= 0) or not np.all(np.isfinite(self.positions)):
            raise InputError(f"mesostructure {self.name!r}: radii must be positive, positions finite")
        diff = self.positions[:, None, :] - self.positions[None, :, :]
        gap = np.hypot(diff[..., 0], diff[..., 1]) - (self.radii[:, None] + self.radii[None, :])
        np.fill_diagonal(gap, np.inf)
        if np.min(gap) < -1e-9 * float(np.max(self.radii)):
            raise InputError(f"mesostructure {self.name!r}: grains overlap in the initial state")

    @property
    def n_grains(self) -> int:
        return len(self.radii)

    @property
    def half_width(self) -> float:
        """Half the extent of the cell along n, grains included [m]."""
        return float(np.max(np.abs(self.positions[:, 0]) + self.radii))

    def volume(self, positions: np.ndarray | None = None) -> np.ndarray:
        """Meso-volume: area of the convex polygon through the driven grains' centres [m^2].

        ``positions`` (..., g, 2) defaults to the initial ones; returns shape (...).
        """
        pos = self.positions if positions is None else np.asarray(positions, float)
        driven = [k for k, d in enumerate(self.drive) if d != "free"]
        p = pos[..., driven, :]
        centre = p.mean(axis=-2, keepdims=True)
        order = np.argsort(np.arctan2(p[..., 1] - centre[..., 1], p[..., 0] - centre[..., 0]), axis=-1)
        p = np.take_along_axis(p, order[..., None], axis=-2)
        x, y = p[..., 0], p[..., 1]
        return 0.5 * np.abs(np.sum(x * np.roll(y, -1, axis=-1) - np.roll(x, -1, axis=-1) * y, axis=-1))


def _hexagon(r_axis: float, r_side: float, alpha0: float) -> tuple[np.ndarray, float, float, float]:
    """Centres of the six grains: axis grains of radius r_axis, side grains of radius r_side."""
    d1 = r_axis + r_side
    d2 = 2.0 * r_side
    l1 = d2 + 2.0 * d1 * math.cos(alpha0)
    l2 = 2.0 * d1 * math.sin(alpha0)
    pos = np.array([[-l1 / 2, 0.0], [-d2 / 2, l2 / 2], [d2 / 2, l2 / 2],
                    [l1 / 2, 0.0], [d2 / 2, -l2 / 2], [-d2 / 2, -l2 / 2]])
    return pos, l1, l2, d1


def _check_alpha(alpha0: float) -> None:
    if not math.pi / 6 < alpha0 < math.pi / 2:
        raise InputError(f"alpha0 must lie in (30, 90) deg, got {math.degrees(alpha0):g}")


HEX_DRIVE = ("n", "t", "t", "n", "t", "t")


def standard(radius: float = 1.0, alpha0: float = math.radians(45.0)) -> Mesostructure:
    """The H-cell: six disks of radius r, d1 = d2 = 2r, opening angle alpha0 (eq. 1.2).

    >>> m = standard(1.0, math.radians(45))
    >>> round(float(m.volume()), 6) == round(2 * 2 * math.sin(math.pi / 4) * (2 + 2 * math.cos(math.pi / 4)), 6)
    True
    """
    _check_alpha(alpha0)
    pos, l1, l2, _ = _hexagon(radius, radius, alpha0)
    return Mesostructure("standard", np.full(6, float(radius)), pos, HEX_DRIVE, l1, l2)


def hexagon_center(radius: float = 1.0, alpha0: float = math.radians(45.0),
                   ratio: float | None = None) -> Mesostructure:
    """The standard hexagon plus a free grain of radius ``ratio * r`` at its centre.

    ``ratio`` defaults to the value at which the centre grain just touches grains 2, 3, 5, 6
    (sqrt(1 + 4 sin^2 alpha0) - 1); a smaller one leaves it loose until the cell closes on it.
    """
    _check_alpha(alpha0)
    pos, l1, l2, _ = _hexagon(radius, radius, alpha0)
    touching = math.hypot(radius, l2 / 2) / radius - 1.0
    ratio = touching if ratio is None else float(ratio)
    if not 0 < ratio <= touching * (1 + 1e-12):
        raise InputError(f"hexagon-center: radius ratio must lie in (0, {touching:.4g}], got {ratio:g}")
    radii = np.append(np.full(6, float(radius)), min(ratio, touching) * radius)
    return Mesostructure("hexagon-center", radii, np.vstack([pos, [0.0, 0.0]]),
                         HEX_DRIVE + ("free",), l1, l2)


def hexagon_unequal(radius: float = 1.0, alpha0: float = math.radians(45.0),
                    ratio: float = 0.7) -> Mesostructure:
    """The hexagon with grains 1 and 4 of radius ``ratio * r``, the four others of radius r.

    All eight contacts touch initially: d1 = (1 + ratio) r, d2 = 2r, l1 = d2 + 2 d1 cos alpha0,
    l2 = 2 d1 sin alpha0.
    """
    _check_alpha(alpha0)
    if not 0 < ratio <= 10:
        raise InputError(f"hexagon-unequal: radius ratio must lie in (0, 10], got {ratio:g}")
    pos, l1, l2, _ = _hexagon(ratio * radius, radius, alpha0)
    radii = np.array([ratio, 1, 1, ratio, 1, 1], float) * radius
    return Mesostructure("hexagon-unequal", radii, pos, HEX_DRIVE, l1, l2)


CONSTRUCTORS = {"standard": standard, "hexagon-center": hexagon_center,
                "hexagon-unequal": hexagon_unequal}


def option_names(name: str) -> tuple[str, ...]:
    """The keyword options of the mesostructure ``name`` beyond radius and alpha0 (``ratio``).

    >>> option_names("hexagon-center"), option_names("standard")
    (('ratio',), ())
    """
    params = inspect.signature(_constructor(name)).parameters
    return tuple(k for k in params if k not in ("radius", "alpha0"))


def _constructor(name: str):
    try:
        return CONSTRUCTORS[name]
    except KeyError:
        raise InputError(f"unknown mesostructure {name!r} (available: {', '.join(CONSTRUCTORS)})") from None


def build(name: str, radius: float = 1.0, alpha0: float = math.radians(45.0),
          **options) -> Mesostructure:
    """A mesostructure by name (``standard``, ``hexagon-center``, ``hexagon-unequal``)."""
    return _constructor(name)(radius, alpha0, **options)
