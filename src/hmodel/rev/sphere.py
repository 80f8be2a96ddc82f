"""Directions, weights and cell frames of the 3D H-model on the unit sphere (docs/model3d.md).

Directions **n** come from SciPy's Lebedev rule (:func:`scipy.integrate.lebedev_rule`), one of
each antipodal pair (a bi-hexagon at -n is the same cell as at n) with twice its weight. The
fabric is transversely isotropic about a deposition axis **a**, the 3D analogue of eq. 1.17:

    ω(n) = (1 + α_ω cos 2ψ) / (4π (1 - α_ω/3)),    cos ψ = n·a,

a probability density on the sphere (∫ ω dΩ = 1: cos 2ψ = 2 cos²ψ - 1 averages -1/3 over the
sphere), largest along a for α_ω > 0. The weights w_i = ω(n_i) W_i (W_i the Lebedev weights)
sum to 1 for every α_ω, since a Lebedev rule of order >= 3 integrates quadratics exactly.

Each direction carries ``n_azimuth`` bi-hexagons whose frames (n, t1, t2) are turned about n by
ψ_j = j π / (2 m), j = 0..m-1, from the meridian frame t1 ∝ a - (a·n) n (hexagon A in the plane
through a and n); each gets the weight w_i / m. Azimuths span a quarter turn because a
bi-hexagon turned by π/2 is the same cell with its two hexagons swapped. With m >= 2 the
elastic response of a direction's cells does not depend on the azimuth of the first frame
(docs/model3d.md, "The frame rule"), which is what makes the REV objective up to the Lebedev
rule's error.

>>> s = Sphere(order=5, n_azimuth=2)
>>> frames, w = s.frames()
>>> frames.shape, round(float(w.sum()), 12)
((14, 3, 3), 1.0)
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..errors import InputError

#: Orders of SciPy's Lebedev rules whose weights are all positive (13, 25 and 27 have negative
#: weights, which would give cells negative stiffness in the average).
ORDERS = (3, 5, 7, 9, 11, 15, 17, 19, 21, 23, 29, 31, 35, 41, 47, 53, 59, 65, 71, 77, 83, 89,
          95, 101, 107, 113, 119, 125, 131)

#: The default rule: Lebedev order and bi-hexagons per direction (docs/model3d.md,
#: "Convergence in directions").
#: Measured (benchmarks/model3d/convergence.json, drained triaxial 200 kPa to 10 %): order 23
#: with six azimuths has its peak q 0.3 % below the finest rules' and a lateral asymmetry
#: max |σ22 - σ33|/p0 of 2e-3 (order 17 with two azimuths, the first default: 2 % and 1.8e-2).
DEFAULT_ORDER = 23
DEFAULT_AZIMUTHS = 6
#: The orders offered by default (coarse to fine, all at :data:`DEFAULT_AZIMUTHS`): the peak q of
#: the drained triaxial test changes by less than 1e-3 between the two finest (35 and 59:
#: 6e-4, measured).
OFFERED = (9, 17, 23, 35, 59)


@lru_cache(maxsize=32)
def _hemisphere(order: int) -> tuple[np.ndarray, np.ndarray]:
    """One direction of each antipodal pair of the Lebedev rule of ``order`` (N/2, 3), with the
    pair's summed weights normalized to 1 (N/2,)."""
    from scipy.integrate import lebedev_rule  # here: importing hmodel.rev stays light

    x, w = lebedev_rule(order)
    x = x.T
    # Keep the member of each pair whose first non-zero coordinate is positive.
    sign = np.zeros(len(x))
    for k in range(3):
        undecided = sign == 0
        sign[undecided] = np.where(np.abs(x[undecided, k]) > 1e-12, np.sign(x[undecided, k]), 0)
    keep = sign > 0
    n = x[keep]
    # Lebedev rules are invariant under inversion: each kept point's antipode carries its weight.
    if 2 * keep.sum() != len(x):
        raise AssertionError(f"Lebedev rule {order} is not centrally symmetric")
    return n, 2.0 * w[keep] / w.sum()


@dataclass(frozen=True)
class Sphere:
    """Discretization of the sphere and fabric of a 3D H-model material.

    Attributes
    ----------
    order : int
        Order of the Lebedev rule (:data:`ORDERS`): it integrates polynomials of that degree
        exactly; order 17 has 110 points, 55 directions on the hemisphere.
    n_azimuth : int
        Bi-hexagons per direction, at azimuths j π/(2 n_azimuth) about n (>= 1; 2 makes the
        elastic response independent of the azimuth).
    alpha_omega : float
        Fabric intensity α_ω in [-1, 1] of ω(n) ∝ 1 + α_ω cos 2ψ (0: isotropic; > 0: more
        cells along the deposition axis).
    axis : tuple of 3 floats
        Deposition axis **a** (normalized here), default the third axis.
    """

    order: int = DEFAULT_ORDER
    n_azimuth: int = DEFAULT_AZIMUTHS
    alpha_omega: float = 0.0
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def __post_init__(self) -> None:
        if self.order not in ORDERS:
            raise InputError(f"Lebedev rule order must be one of {', '.join(map(str, ORDERS))}, "
                             f"got {self.order!r}")
        if int(self.n_azimuth) != self.n_azimuth or self.n_azimuth < 1:
            raise InputError(f"n_azimuth must be a positive integer, got {self.n_azimuth!r}")
        if not -1.0 <= self.alpha_omega <= 1.0:
            raise InputError(f"fabric intensity alpha_omega must lie in [-1, 1] in 3D, got {self.alpha_omega}")
        a = np.asarray(self.axis, float)
        if a.shape != (3,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) == 0:
            raise InputError(f"the deposition axis must be a non-zero 3-vector, got {self.axis!r}")
        object.__setattr__(self, "axis", tuple(float(c) for c in a / np.linalg.norm(a)))

    @property
    def n_cells(self) -> int:
        """Bi-hexagons per material point: directions on the hemisphere × azimuths."""
        return len(_hemisphere(self.order)[0]) * self.n_azimuth

    def omega(self, n: np.ndarray) -> np.ndarray:
        """Fabric density ω(n) [1/sr] of unit vectors n (..., 3) (docstring of the module)."""
        c = np.asarray(n, float) @ np.asarray(self.axis)
        return (1.0 + self.alpha_omega * (2.0 * c * c - 1.0)) / (4.0 * np.pi * (1.0 - self.alpha_omega / 3.0))

    def directions(self) -> tuple[np.ndarray, np.ndarray]:
        """Directions n (N, 3) on the hemisphere and their weights (N,), which sum to 1."""
        n, wl = _hemisphere(self.order)
        return n.copy(), 4.0 * np.pi * wl * self.omega(n)

    def frames(self) -> tuple[np.ndarray, np.ndarray]:
        """Cell frames (C, 3, 3), rows (n, t1, t2) right-handed, and cell weights (C,) summing
        to 1; C = N n_azimuth, the azimuths of one direction consecutive."""
        n, w = self.directions()
        a = np.asarray(self.axis)
        t1 = a[None, :] - (n @ a)[:, None] * n
        norm = np.linalg.norm(t1, axis=1)
        pole = norm < 1e-9
        if pole.any():  # n along a: the material's second axis, the global axis least along a
            e = np.eye(3)[np.argmin(np.abs(a))]
            b = e - (e @ a) * a
            t1[pole] = b - (n[pole] @ b)[:, None] * n[pole]
            norm = np.linalg.norm(t1, axis=1)
        t1 = t1 / norm[:, None]
        t2 = np.cross(n, t1)
        m = self.n_azimuth
        psi = np.arange(m) * np.pi / (2 * m)
        c, s = np.cos(psi)[None, :, None], np.sin(psi)[None, :, None]
        e_n = np.broadcast_to(n[:, None, :], (len(n), m, 3))
        e_t1 = c * t1[:, None, :] + s * t2[:, None, :]
        e_t2 = np.cross(e_n, e_t1)
        frames = np.stack([e_n, e_t1, e_t2], axis=2).reshape(-1, 3, 3)
        return np.ascontiguousarray(frames), np.repeat(w / m, m)
