"""Rectangular plane-strain domains meshed for scikit-fem, and their boundary degrees of freedom.

A domain is ``width`` (x) by ``height`` (y) with its lower left corner at the origin and
``nx`` by ``ny`` elements. The vertical axis y is the axial direction of hmodel's
material-point tests (index 1 of the (11, 22, 12) components), x the lateral one (index 2);
:mod:`hmodel.fem.assembly` states the conversion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from skfem import Basis, ElementQuad1, ElementQuadS2, ElementTriP2, ElementVector, MeshQuad

from ..errors import InputError

#: element name -> (scikit-fem element, quadrature order, triangles?, description). The
#: orders integrate the element's stiffness exactly on parallelograms: 2x2 Gauss points for Q4,
#: 3x3 for the 8-node serendipity quadrilateral, 3 points for the 6-node triangle.
ELEMENTS = {
    "q4": (ElementQuad1, 2, False, "4-node bilinear quadrilateral, 2x2 Gauss points"),
    "q4b": (ElementQuad1, 2, False, "4-node bilinear quadrilateral, 2x2 Gauss points, B-bar "
            "volumetric strain (the element's mean, Hughes 1980)"),
    "q8": (ElementQuadS2, 4, False, "8-node serendipity quadrilateral, 3x3 Gauss points"),
    "t6": (ElementTriP2, 2, True, "6-node quadratic triangle, 3 Gauss points"),
}
#: Gauss points per rectangle of the grid (t6: two triangles of 3).
GAUSS_PER_RECTANGLE = {"q4": 4, "q4b": 4, "q8": 9, "t6": 6}
#: elements whose strain operator replaces each point's volumetric strain by its element's mean
BBAR = ("q4b",)


def parse_pair(text: str, name: str, integer: bool) -> tuple:
    """``"8x16"`` -> (8, 16) (positive integers) or ``"0.05x0.1"`` -> (0.05, 0.1) (positive
    lengths), refused with a one-line error otherwise."""
    parts = str(text).lower().replace("×", "x").split("x")
    if len(parts) != 2:
        raise InputError(f"{name} expects AxB (e.g. {'8x16' if integer else '0.05x0.1'}), got {text!r}")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise InputError(f"{name} expects two numbers AxB, got {text!r}") from None
    if not all(np.isfinite(v) and v > 0 for v in values):
        raise InputError(f"{name} must be positive, got {text!r}")
    if integer:
        if not all(v.is_integer() for v in values):
            raise InputError(f"{name} must be whole numbers of elements, got {text!r}")
        return int(values[0]), int(values[1])
    return values[0], values[1]


@dataclass(frozen=True)
class Domain:
    """A meshed rectangle: ``width`` x ``height`` [m], ``nx`` x ``ny`` elements of ``element``."""

    width: float
    height: float
    nx: int
    ny: int
    element: str = "q4"

    def __post_init__(self):
        if self.element not in ELEMENTS:
            raise InputError(f"unknown element {self.element!r} (known: {', '.join(ELEMENTS)})")
        for n, v in (("nx", self.nx), ("ny", self.ny)):
            if not isinstance(v, (int, np.integer)) or v < 1:
                raise InputError(f"mesh size {n} must be a positive integer, got {v!r}")
        if not (np.isfinite(self.width) and np.isfinite(self.height) and self.width > 0 and self.height > 0):
            raise InputError(f"domain size must be positive, got {self.width} x {self.height}")

    @property
    def n_gauss(self) -> int:
        """Gauss points of the mesh (known before it is built)."""
        return self.nx * self.ny * GAUSS_PER_RECTANGLE[self.element]

    def mesh(self):
        """The scikit-fem mesh (quadrilaterals, or each split into two triangles)."""
        m = MeshQuad.init_tensor(np.linspace(0.0, self.width, self.nx + 1),
                                 np.linspace(0.0, self.height, self.ny + 1))
        return m.to_meshtri() if ELEMENTS[self.element][2] else m

    def basis(self) -> Basis:
        """Vector (u_x, u_y) basis with the element's Gauss points."""
        cls, order, _, _ = ELEMENTS[self.element]
        return Basis(self.mesh(), ElementVector(cls()), intorder=order)

    def contains(self, x: float, y: float) -> bool:
        return 0.0 <= x <= self.width and 0.0 <= y <= self.height


def dofs_where(basis: Basis, component: int, where) -> np.ndarray:
    """Degrees of freedom of displacement ``component`` (0: x, 1: y) at the nodes whose
    coordinates (2, n) satisfy ``where`` (vertices and, for quadratic elements, mid-side nodes;
    a single node such as a corner too, which scikit-fem's facet-based ``get_dofs`` misses)."""
    rows = [d for d in (basis.nodal_dofs, basis.facet_dofs, basis.interior_dofs) if d.size]
    # ElementVector interleaves the components: row r of each dof table is component r % 2
    dofs = np.concatenate([d[component::2].ravel() for d in rows])
    return np.sort(dofs[np.asarray(where(basis.doflocs[:, dofs]), bool)])


def gauss_points(basis: Basis) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates (2, B) and integration weights dx (B,) of the Gauss points, element-major
    (point b = element b // nqp, quadrature point b % nqp)."""
    x = basis.mapping.F(basis.X)  # (2, nelems, nqp)
    return x.reshape(2, -1), basis.dx.reshape(-1)
