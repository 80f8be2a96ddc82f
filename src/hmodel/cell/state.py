"""State of many H-cells at once (report Fig. 1.2, eq. 1.2).

Convention: a :class:`CellState` is immutable in spirit. Solvers return a *new* state; the
arrays of a state are never written after it is returned. The leading axes are free, usually
``(material point, direction)``; the last axis of ``values`` holds the fields of :data:`FIELDS`
and that of ``flags`` the diagnostics of :data:`FLAGS`. Packing the fields into one contiguous
array keeps the compiled kernels cheap to call (one argument instead of eight).

Units: lengths in the unit of the grain radius (m), angles in rad, forces in N
(per unit thickness in 2D, i.e. N with kn in N/m).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..params import Params

#: Continuous state of a cell: branch lengths, opening angle, contact forces, cell lengths.
FIELDS = ("d1", "d2", "alpha", "N1", "N2", "T1", "l1", "l2")
#: Diagnostics after an increment: contact 1 sliding, contact 1 open, contact 2 open,
#: extra contact between grains 1-4, extra contacts 2-6 / 3-5 (report Figs. 1.5, 1.6).
FLAGS = ("sliding", "open1", "open2", "contact14", "contact26")
IDX = {name: i for i, name in enumerate(FIELDS)}
FLAG_IDX = {name: i for i, name in enumerate(FLAGS)}


def initial_lengths(radius: float, alpha0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lengths (l10, l20) of unloaded cells with opening angles α0: eq. 1.2 with d1 = d2 = 2r."""
    d = 2.0 * radius
    a = np.asarray(alpha0, float)
    return d + 2 * d * np.cos(a), 2 * d * np.sin(a)


@dataclass(frozen=True)
class CellState:
    """Continuous state of a batch of cells.

    Attributes
    ----------
    values : ndarray, shape (..., 8), float64
        ``d1, d2, alpha, N1, N2, T1, l1, l2`` (see :data:`FIELDS`).
    """

    values: np.ndarray

    def __getattr__(self, name: str) -> np.ndarray:
        try:
            return self.values[..., IDX[name]]
        except KeyError:
            raise AttributeError(name) from None

    @property
    def shape(self) -> tuple[int, ...]:
        return self.values.shape[:-1]

    @classmethod
    def from_fields(cls, **fields: np.ndarray) -> "CellState":
        """Build from named arrays (all of ``FIELDS``), broadcast to a common shape."""
        missing = set(FIELDS) - set(fields)
        if missing:
            raise ValueError(f"missing cell fields: {', '.join(sorted(missing))}")
        arrays = np.broadcast_arrays(*(np.asarray(fields[f], dtype=float) for f in FIELDS))
        return cls(np.ascontiguousarray(np.stack(arrays, axis=-1)))

    @classmethod
    def initial(cls, params: Params, shape: tuple[int, ...] = ()) -> "CellState":
        """Unloaded cells: d1 = d2 = 2r, alpha = alpha0, no force, l1, l2 from eq. 1.2."""
        d = 2.0 * params.radius
        row = np.array([d, d, params.alpha0, 0.0, 0.0, 0.0, params.l10, params.l20])
        return cls(np.ascontiguousarray(np.broadcast_to(row, (*shape, len(FIELDS)))))

    def where(self, mask: np.ndarray, other: "CellState") -> "CellState":
        """Cells of ``self`` where ``mask`` (broadcast on leading axes) is true, else ``other``."""
        return CellState(np.where(np.asarray(mask)[..., None], self.values, other.values))

    def geometric_l1(self) -> np.ndarray:
        """l1 recomputed from d1, d2, alpha (eq. 1.2); equals ``l1`` to first order."""
        return self.d2 + 2 * self.d1 * np.cos(self.alpha)

    def geometric_l2(self) -> np.ndarray:
        """l2 recomputed from d1, alpha (eq. 1.2)."""
        return 2 * self.d1 * np.sin(self.alpha)


@dataclass(frozen=True)
class CellFlags:
    """Per-cell diagnostics after an increment, ``flags`` of shape (..., 5), bool."""

    flags: np.ndarray

    def __getattr__(self, name: str) -> np.ndarray:
        try:
            return self.flags[..., FLAG_IDX[name]]
        except KeyError:
            raise AttributeError(name) from None

    @property
    def hexagons(self) -> np.ndarray:
        """The flags (..., k, 5) of the k hexagons of each cell: one for an H-cell, two for a
        bi-hexagon (whose flags are its hexagons' five each, then its own)."""
        f = self.flags
        k = f.shape[-1] // len(FLAGS)
        return f[..., :k * len(FLAGS)].reshape(*f.shape[:-1], k, len(FLAGS))

    @property
    def broken(self) -> np.ndarray:
        """Cells that carry no force in some hexagon because a contact is open (report Fig. 1.5)."""
        h = self.hexagons
        return np.any(h[..., FLAG_IDX["open1"]] | h[..., FLAG_IDX["open2"]], axis=-1)

    @property
    def open_hexagons(self) -> np.ndarray:
        """Per cell, its hexagons with a contact open (0 or 1 for an H-cell, up to 2 for a
        bi-hexagon): a hexagon that opens beside an open twin changes no cell's ``broken`` but
        drops its forces all the same (the mixed-control Newton's event count)."""
        h = self.hexagons
        return np.sum(h[..., FLAG_IDX["open1"]] | h[..., FLAG_IDX["open2"]], axis=-1)

    @classmethod
    def none(cls, shape: tuple[int, ...] = ()) -> "CellFlags":
        return cls(np.zeros((*shape, len(FLAGS)), dtype=bool))


def initial_cells(params: Params, alpha0: np.ndarray) -> CellState:
    """Unloaded H-cells with their own opening angles α0 (eq. 1.2 with d1 = d2 = 2r)."""
    l10, l20 = initial_lengths(params.radius, alpha0)
    return CellState.from_fields(d1=2.0 * params.radius, d2=2.0 * params.radius, alpha=alpha0,
                                 N1=0.0, N2=0.0, T1=0.0, l1=l10, l2=l20)
