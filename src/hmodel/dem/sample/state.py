"""A state of a DEM sample and its measures: porosity, void ratio, coordination numbers,
rattlers, contact forces, their fabric and the Love-Weber stress.

Stresses are (1/V) sum f (x) l over the contacts, V the cell's volume: for disks its area, and
the stress in N/m (Pa m: Pa for a sample of unit thickness), as hmodel's DEM cells
(:meth:`hmodel.cell.geometry.CellGeometry.love_weber`); for spheres in Pa.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...rev.contacts import fabric, grain_contacts
from .geometry import CONTACT_COLUMNS, CONTACT_COLUMNS_3D, Grains, grains  # noqa: F401 (columns' first home)


def contact_columns(dim: int) -> tuple[str, ...]:
    return grains(dim).contact_columns


@dataclass(frozen=True)
class SampleState:
    """A state of the sample: cell size (Lx, Ly) or (Lx, Ly, Lz), radii, centres wrapped into the
    cell, contacts (columns :data:`CONTACT_COLUMNS` or :data:`CONTACT_COLUMNS_3D`)."""

    cell: tuple[float, ...]
    radii: np.ndarray
    positions: np.ndarray
    contacts: np.ndarray = field(repr=False)

    @classmethod
    def from_json(cls, d: dict) -> "SampleState":
        dim = len(d["cell"])
        return cls(cell=tuple(float(v) for v in d["cell"]),
                   radii=np.asarray(d["radii"], float),
                   positions=np.asarray(d["pos"], float).reshape(-1, dim),
                   contacts=np.asarray(d["contacts"], float).reshape(-1, len(contact_columns(dim))))

    @classmethod
    def from_npz(cls, path: Path, state: str = "final") -> "SampleState | None":
        """A state (``final`` or ``consolidated``) in a test's npz file (None where it was removed)."""
        if not path.exists():
            return None
        with np.load(path) as z:
            return cls(cell=tuple(float(v) for v in z[f"{state}_cell"]), radii=z["radii"],
                       positions=z[f"{state}_positions"], contacts=z[f"{state}_contacts"])

    @property
    def dim(self) -> int:
        return len(self.cell)

    @property
    def grains(self) -> Grains:
        return grains(self.dim)

    @property
    def volume(self) -> float:
        """The cell's area (disks) or volume (spheres)."""
        return math.prod(self.cell)

    @property
    def porosity(self) -> float:
        r = self.radii
        solid = self.grains.solid(r)
        return 1.0 - float(np.sum(solid)) / self.volume

    @property
    def void_ratio(self) -> float:
        n = self.porosity
        return n / (1.0 - n)

    def contact_counts(self) -> np.ndarray:
        """Contacts of every grain."""
        c = self.contacts[:, :2].astype(int).ravel()
        return np.bincount(c, minlength=len(self.radii))

    @property
    def coordination(self) -> float:
        """z = 2 C / N over all disks."""
        return 2.0 * len(self.contacts) / len(self.radii)

    @property
    def rattlers(self) -> float:
        """Fraction of grains with fewer than 2 contacts."""
        return float(np.mean(self.contact_counts() < 2))

    @property
    def mechanical_coordination(self) -> float:
        """z without the rattlers (grains with 0 or 1 contact) and their contacts."""
        counts = self.contact_counts()
        keep = counts >= 2
        i, j = self.contacts[:, 0].astype(int), self.contacts[:, 1].astype(int)
        both = keep[i] & keep[j]
        return 2.0 * int(np.sum(both)) / max(int(np.sum(keep)), 1)

    def branches(self) -> np.ndarray:
        """Branch vectors l from i to j, (c, dim) [m]."""
        return self.contacts[:, -self.dim:]

    def forces(self) -> np.ndarray:
        """Contact forces on j by i, (c, dim) [N]."""
        fn, l = self.contacts[:, 2], self.branches()
        e = l / np.linalg.norm(l, axis=1)[:, None]
        return self.grains.forces(fn, e, self.contacts)

    def fabric(self) -> dict | None:
        """The fabric of the carrying contacts relative to axis 1 (:func:`hmodel.rev.contacts.fabric`,
        the measure of a REV's cells, ``hmodel run ... --contact-fabric``), as plain numbers; None
        where no contact carries."""
        if not len(self.contacts) or not np.any(self.contacts[:, 2] > 0.0):
            return None
        return fabric(grain_contacts(self.branches(), self.forces())).as_dict()

    def stress(self) -> np.ndarray:
        """Love-Weber stress (1/V) sum f (x) l, compression positive, (dim, dim) [N/m for disks,
        Pa for spheres] (report's homogenization, as the cells'; the sum is over the contacts)."""
        return np.einsum("ca,cb->ab", self.forces(), self.branches()) / self.volume

    def summary(self) -> dict:
        return {"porosity": self.porosity, "void_ratio": self.void_ratio,
                "coordination": self.coordination,
                "mechanical_coordination": self.mechanical_coordination,
                "rattlers": self.rattlers, "contacts": len(self.contacts),
                "cell": list(self.cell), "fabric": self.fabric()}

    def arrays(self, prefix: str) -> dict[str, np.ndarray]:
        return {f"{prefix}_cell": np.asarray(self.cell), f"{prefix}_positions": self.positions,
                f"{prefix}_contacts": self.contacts}
