"""Finite elements with the H-model at every Gauss point (plane strain, small strain).

Every Gauss point of a scikit-fem mesh is one material point of one batched
:class:`~hmodel.rev.Rev` (its own state and parameter set); a global Newton-Raphson on the
nodal displacements uses the REV's consistent tangent, from batched finite differences.
:func:`biaxial` and :func:`footing` are the two boundary-value problems of ``hmodel fem``;
:func:`write_result` writes their files. Conventions: :mod:`hmodel.fem.assembly`. The
regularized model (nonlocal inelastic stress over a length ell): :mod:`hmodel.fem.regularization`.
"""

from .mesh import ELEMENTS, Domain, parse_pair
from .newton import GlobalNewtonSettings
from .outputs import write_result
from .problems import biaxial, footing, parse_imperfection
from .regularization import Regularization, parse_regularization
from .result import FemResult, Snapshot, material_point_curve

__all__ = ["biaxial", "footing", "write_result", "FemResult", "Snapshot", "GlobalNewtonSettings",
           "Domain", "ELEMENTS", "parse_pair", "parse_imperfection", "material_point_curve",
           "Regularization", "parse_regularization"]
