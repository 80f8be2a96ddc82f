"""A state of a DEM sample and its measures: porosity, void ratio, coordination numbers,
rattlers, contact forces and the 2D Love-Weber stress.

Stresses are (1/A) sum f (x) l over the contacts, A the cell's area, in N/m (Pa m: Pa for a
sample of unit thickness), as hmodel's DEM cells
(:meth:`hmodel.cell.geometry.CellGeometry.love_weber`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

#: Columns of a contact row: grain indices, normal force (compression positive), tangential
#: force f.(e_y, -e_x), branch vector l from i to j (across the periodic boundary if need be);
#: f is the force on j by i, e = l / |l|.
CONTACT_COLUMNS = ("i", "j", "fn", "ft", "lx", "ly")


@dataclass(frozen=True)
class SampleState:
    """A state of the sample: cell size (Lx, Ly), radii, centres wrapped into the cell, contacts
    (columns :data:`CONTACT_COLUMNS`)."""

    cell: tuple[float, float]
    radii: np.ndarray
    positions: np.ndarray
    contacts: np.ndarray = field(repr=False)

    @classmethod
    def from_json(cls, d: dict) -> "SampleState":
        return cls(cell=(float(d["cell"][0]), float(d["cell"][1])),
                   radii=np.asarray(d["radii"], float),
                   positions=np.asarray(d["pos"], float).reshape(-1, 2),
                   contacts=np.asarray(d["contacts"], float).reshape(-1, len(CONTACT_COLUMNS)))

    @property
    def area(self) -> float:
        return self.cell[0] * self.cell[1]

    @property
    def porosity(self) -> float:
        return 1.0 - float(np.sum(math.pi * self.radii ** 2)) / self.area

    @property
    def void_ratio(self) -> float:
        n = self.porosity
        return n / (1.0 - n)

    def contact_counts(self) -> np.ndarray:
        """Contacts of every disk."""
        c = self.contacts[:, :2].astype(int).ravel()
        return np.bincount(c, minlength=len(self.radii))

    @property
    def coordination(self) -> float:
        """z = 2 C / N over all disks."""
        return 2.0 * len(self.contacts) / len(self.radii)

    @property
    def rattlers(self) -> float:
        """Fraction of disks with fewer than 2 contacts."""
        return float(np.mean(self.contact_counts() < 2))

    @property
    def mechanical_coordination(self) -> float:
        """z without the rattlers (disks with 0 or 1 contact) and their contacts."""
        counts = self.contact_counts()
        keep = counts >= 2
        i, j = self.contacts[:, 0].astype(int), self.contacts[:, 1].astype(int)
        both = keep[i] & keep[j]
        return 2.0 * int(np.sum(both)) / max(int(np.sum(keep)), 1)

    def forces(self) -> np.ndarray:
        """Contact forces on j by i, (c, 2) [N]."""
        fn, ft, l = self.contacts[:, 2], self.contacts[:, 3], self.contacts[:, 4:6]
        e = l / np.linalg.norm(l, axis=1)[:, None]
        t = np.stack([e[:, 1], -e[:, 0]], axis=1)
        return fn[:, None] * e + ft[:, None] * t

    def stress(self) -> np.ndarray:
        """2D Love-Weber stress (1/A) sum f (x) l, compression positive, (2, 2) [N/m]."""
        return np.einsum("ca,cb->ab", self.forces(), self.contacts[:, 4:6]) / self.area

    def summary(self) -> dict:
        return {"porosity": self.porosity, "void_ratio": self.void_ratio,
                "coordination": self.coordination,
                "mechanical_coordination": self.mechanical_coordination,
                "rattlers": self.rattlers, "contacts": len(self.contacts),
                "cell": list(self.cell)}

    def arrays(self, prefix: str) -> dict[str, np.ndarray]:
        return {f"{prefix}_cell": np.asarray(self.cell), f"{prefix}_positions": self.positions,
                f"{prefix}_contacts": self.contacts}
