"""The one registry of cell solvers: a spec such as ``closed-form``, ``surrogate:FILE`` or
``dem:hexagon-center:tol=1e-7`` names a solver by its first word.

Each solver registers a factory ``spec -> CellSolver`` under the ``hmodel.cell_solvers``
entry-point group (hmodel's own three in its ``pyproject.toml``; another package can add its
own the same way). The registry imports a solver's package only when a spec names it, so the
engine below (``cell``, ``rev``, ``loading``) never depends on a concrete solver, and importing
hmodel does not load PyTorch, YADE's client or a model file.
"""

from __future__ import annotations

from importlib import import_module
from importlib.metadata import entry_points

from .cell import CellSolver
from .errors import InputError
from .rev.model3d import cell_solver_3d

GROUP = "hmodel.cell_solvers"
#: Solvers of hmodel's own named by a longer prefix than their entry point's first word, looked up
#: first (``module:factory``, imported only when a spec names it): the DEM bi-hexagon is a cell of
#: its own under the ``dem`` solvers (``dem:bihexagon[:K=V,...]``, 3D, three lengths).
PREFIXED = {"dem:bihexagon": "hmodel.dem.bihex:DEMBiHexSolver"}
#: Specs that name another solver in the 3D model: the 3D model runs with the equilibrium λ
#: (:data:`hmodel.rev.model3d.SLIDING_RHS_3D`), so its shipped learned cell is the network
#: trained with it.
SPECS_3D = {"surrogate": "surrogate:equilibrium"}


def available() -> list[str]:
    """Names of the registered solvers (the first word of their specs)."""
    return sorted(ep.name for ep in entry_points(group=GROUP))


def get_solver(spec: "str | CellSolver") -> CellSolver:
    """The solver a spec names, or a solver instance passed through.

    >>> get_solver("closed-form").name
    'closed-form'
    """
    if not isinstance(spec, str):
        if not isinstance(spec, CellSolver):
            raise InputError(f"not a cell solver: {spec!r}")
        return spec
    if any(not field.strip() for field in spec.split(":")[1:]):  # else its default would run unasked
        raise InputError(f"cell solver {spec!r} names nothing after a colon: give "
                         f"{spec.split(':', 1)[0]!r} alone for its default, or a value after the colon")
    for prefix, target in PREFIXED.items():
        if spec == prefix or spec.startswith(prefix + ":"):
            module, _, factory = target.partition(":")
            return getattr(import_module(module), factory)(spec)
    name = spec.split(":", 1)[0]
    found = [ep for ep in entry_points(group=GROUP) if ep.name == name]
    if not found:
        raise InputError(f"unknown cell solver {spec!r} (available: closed-form, "
                         f"surrogate[:MODEL_FILE], dem:MESOSTRUCTURE, dem:bihexagon)")
    return found[0].load()(spec)


def get_solver_3d(spec: "str | CellSolver") -> CellSolver:
    """The 3D model's cell of a spec (:data:`SPECS_3D` first) or a solver: the closed-form
    bi-hexagon for ``closed-form``, a bi-hexagon whose hexagons a 2D H-cell solver steps, a
    3D solver (``dem:bihexagon``) as it is (:func:`hmodel.rev.model3d.cell_solver_3d`).

    >>> get_solver_3d("closed-form").n_lengths
    3
    """
    if isinstance(spec, str):
        spec = SPECS_3D.get(spec, spec)
    return cell_solver_3d(get_solver(spec))
