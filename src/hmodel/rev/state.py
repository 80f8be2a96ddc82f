"""The state of a batch of material points, and the stress and strain invariants of 2D and 3D.

Strains and stresses are ``(B, n)`` arrays: n = 3 in 2D ``(11, 22, 12)``, n = 6 in 3D
``(11, 22, 33, 23, 13, 12)``, tensor components, soil-mechanics signs (compression positive);
stresses in Pa.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..cell import CellFlags, CellState
from ..errors import InputError


def normal_components(n: int) -> int:
    """Normal components of a (..., n) strain or stress, the first ones: 2 in 2D (n = 3), 3 in
    3D (n = 6)."""
    if n not in (3, 6):
        raise InputError(f"a strain or stress has 3 (2D) or 6 (3D) components, got {n}")
    return 2 if n == 3 else 3


def mean_stress(sig: np.ndarray) -> np.ndarray:
    """p (...) of stresses (..., n): the mean of the normal components."""
    if normal_components(sig.shape[-1]) == 2:
        return 0.5 * (sig[..., 0] + sig[..., 1])
    return (sig[..., 0] + sig[..., 1] + sig[..., 2]) / 3.0


def deviatoric_stress(sig: np.ndarray) -> np.ndarray:
    """q (...) of stresses (..., n): sig11 - sig22 in 2D (the report's q, §1.1.2); in 3D
    sig11 - (sig22 + sig33)/2, axis 1 axial: sig_a - sig_r in a triaxial test, negative in
    extension (the contract of DESIGN.md; :func:`equivalent_stress` is the invariant)."""
    if normal_components(sig.shape[-1]) == 2:
        return sig[..., 0] - sig[..., 1]
    return sig[..., 0] - 0.5 * (sig[..., 1] + sig[..., 2])


def equivalent_stress(sig: np.ndarray) -> np.ndarray:
    """sqrt(3 J2) (...) of 3D stresses (..., 6) (tensor shear components 23, 13, 12): |q| in a
    triaxial test, and the same in every frame."""
    s11, s22, s33 = sig[..., 0], sig[..., 1], sig[..., 2]
    shear = sig[..., 3] ** 2 + sig[..., 4] ** 2 + sig[..., 5] ** 2
    return np.sqrt(0.5 * ((s11 - s22) ** 2 + (s22 - s33) ** 2 + (s33 - s11) ** 2) + 3.0 * shear)


def volumetric_strain(eps: np.ndarray) -> np.ndarray:
    """eps_v (...) of strains (..., n): the trace."""
    if normal_components(eps.shape[-1]) == 2:
        return eps[..., 0] + eps[..., 1]
    return eps[..., 0] + eps[..., 1] + eps[..., 2]


@dataclass(frozen=True)
class RevState:
    """State of B material points.

    Attributes
    ----------
    cells : CellState, shape (B, n_theta)
    flags : CellFlags, shape (B, n_theta)
    eps : ndarray (B, n)   cumulative macro strain: (eps11, eps22, eps12) in 2D, n = 3
    sig : ndarray (B, n)   macro stress [Pa], the same components (3D: :mod:`hmodel.rev.rev3d`)
    sets : ndarray (B,) int or None
        Each point's parameter set, an index into :attr:`Rev.sets` (None: the first for all).
    """

    cells: CellState
    flags: CellFlags
    eps: np.ndarray
    sig: np.ndarray
    sets: np.ndarray | None = None

    @property
    def n_points(self) -> int:
        return self.eps.shape[0]

    @property
    def set_index(self) -> np.ndarray:
        """Each point's parameter set (B,), zeros where all share the first."""
        return np.zeros(self.n_points, np.int64) if self.sets is None else self.sets

    @property
    def n_components(self) -> int:
        """Strain and stress components: 3 in 2D (11, 22, 12), 6 in 3D (11, 22, 33, 23, 13, 12)."""
        return self.eps.shape[1]

    @property
    def p(self) -> np.ndarray:
        """Mean stress [Pa]: (sig11 + sig22)/2 in 2D, (sig11 + sig22 + sig33)/3 in 3D."""
        return mean_stress(self.sig)

    @property
    def q(self) -> np.ndarray:
        """Deviatoric stress [Pa]: sig11 - sig22 in 2D, sig11 - (sig22 + sig33)/2 in 3D."""
        return deviatoric_stress(self.sig)

    @property
    def eps_v(self) -> np.ndarray:
        """Volumetric strain, the trace of the strain (compression positive)."""
        return volumetric_strain(self.eps)

    def where(self, mask: np.ndarray, other: "RevState") -> "RevState":
        """Material points of ``self`` where ``mask`` (B,) is true, else those of ``other``."""
        m = np.asarray(mask, dtype=bool)
        return RevState(self.cells.where(m[:, None], other.cells),
                        CellFlags(np.where(m[:, None, None], self.flags.flags, other.flags.flags)),
                        np.where(m[:, None], self.eps, other.eps),
                        np.where(m[:, None], self.sig, other.sig), self.sets)

    def select(self, index) -> "RevState":
        """Sub-batch of material points (index array or slice)."""
        return RevState(CellState(self.cells.values[index]), CellFlags(self.flags.flags[index]),
                        self.eps[index], self.sig[index],
                        None if self.sets is None else self.sets[index])

    def scatter(self, index: np.ndarray, sub: "RevState") -> "RevState":
        """A copy with the material points at ``index`` replaced by those of ``sub``."""
        parts = []
        for mine, theirs in ((self.cells.values, sub.cells.values), (self.flags.flags, sub.flags.flags),
                             (self.eps, sub.eps), (self.sig, sub.sig)):
            arr = mine.copy()
            arr[index] = theirs
            parts.append(arr)
        return RevState(CellState(parts[0]), CellFlags(parts[1]), parts[2], parts[3], self.sets)

    def fractions(self) -> dict[str, np.ndarray]:
        """Weighted-free fraction of hexagons per diagnostic, each (B,) (a bi-hexagon has two
        hexagons; its contact 1-4 is shared, counted once)."""
        h = self.flags.hexagons.astype(float)  # (B, cells, k, 5)
        frac = lambda a: a.mean(axis=(1, 2))  # noqa: E731
        opened = np.maximum(h[..., 1], h[..., 2])
        return {"frac_sliding": frac(h[..., 0]), "frac_open": frac(opened),
                "frac_contact14": h[..., 0, 3].mean(axis=1), "frac_contact26": frac(h[..., 4])}
