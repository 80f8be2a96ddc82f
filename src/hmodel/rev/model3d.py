"""The 3D model's policy, in one place for Python and the command line alike: which cell a
solver makes, the parameters' defaults, and the 2D model's parameters refused.

- **The cell** (:func:`cell_solver_3d`): a bi-hexagon. None is the closed-form one; a 2D H-cell
  solver steps the hexagons of every bi-hexagon (``BiHexSolver(hexagon=solver)``: the closed
  form's is the closed-form bi-hexagon, a surrogate's the learned 3D cell); a solver of three
  lengths (``dem:bihexagon``) is one already. Richer or DEM hexagons are refused by
  :func:`~hmodel.cell.bihex.check_hexagon`, in one line.
- **The parameters' defaults** (:func:`sliding_rhs_3d`, :func:`params_3d`,
  :func:`assignments_3d`): ``sliding_rhs = "equilibrium"`` (with the report's λ the stress of
  the 3D cells jumps where a cell slides with T1 < 0, and until the event loop counted hexagons
  (2026-12-08) the mixed-control driver stopped a drained triaxial test near 1 % axial strain,
  docs/model3d.md; the 3D figures were made with this default), or for a learned hexagon the λ its
  network was trained with (its :attr:`~hmodel.cell.base.CellSolver.trained_params`; it refuses
  any other). A :class:`~hmodel.params.Params` given is used as given: its ``sliding_rhs`` is
  a value like any other (``Params()`` is the report's λ), so the default applies where the
  parameters are built here: from ``NAME=VALUE`` assignments that do not name it (the command
  line, a program's ``[params]``), or where a Python caller gives none (``params=None``).
- **The refusals** (:func:`check_3d_params`, :func:`check_3d_param_sets`): the 2D model's own
  parameters (:data:`PARAMS_2D_ONLY`), naming what takes their place in 3D.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

from ..cell import CellSolver
from ..cell.bihex import BiHexSolver
from ..errors import InputError
from ..params import Params

#: Parameters of the 2D model only, and what takes their place in 3D (:func:`check_3d_params`).
PARAMS_2D_ONLY = {
    "n_theta": "the 3D directions are the Lebedev rule's: --order N (and --azimuths M) on the "
               "command line, [sphere] order in a program, Sphere(order=...) in Python",
    "alpha_omega": "the 3D fabric is the sphere's: --fabric A on the command line, [sphere] "
                   "alpha_omega in a program, Sphere(alpha_omega=...) in Python",
    "beta_omega": "the 3D fabric's axis is the sphere's: the axial axis 1 on the command line, "
                  "[sphere] axis in a program, Sphere(axis=...) in Python",
}
#: The 3D model's sliding closure where neither the parameters nor a learned cell set one.
SLIDING_RHS_3D = "equilibrium"


def check_3d_params(names: Iterable[str], where: str = "--param") -> None:
    """Refuse a 2D-only parameter (:data:`PARAMS_2D_ONLY`) named for a 3D run, naming its 3D
    equivalent (one-line InputError)."""
    for name in names:
        if name in PARAMS_2D_ONLY:
            raise InputError(f"{where}: parameter {name} is the 2D model's and has no meaning in 3D: "
                             f"{PARAMS_2D_ONLY[name]}")


def check_3d_param_sets(params: Params | Sequence[Params]) -> None:
    """Refuse parameter sets of a 3D run that set a 2D-only field away from its default (the
    fabric; n_theta is simply unused), as :func:`check_3d_params`."""
    sets = (params,) if isinstance(params, Params) else tuple(params)
    for name in ("alpha_omega", "beta_omega"):
        if any(isinstance(p, Params) and getattr(p, name) != 0 for p in sets):
            check_3d_params([name], "parameters")


def cell_solver_3d(solver: CellSolver | None = None) -> CellSolver:
    """The 3D cell of ``solver``: the closed-form bi-hexagon for None, a solver of three lengths
    as it is, and a bi-hexagon whose hexagons a 2D H-cell solver steps otherwise (refused in one
    line for richer or DEM cells: :func:`~hmodel.cell.bihex.check_hexagon`).

    >>> cell_solver_3d().n_lengths, cell_solver_3d(cell_solver_3d()).name
    (3, 'closed-form')
    """
    if solver is None:
        return BiHexSolver()
    if not isinstance(solver, CellSolver):
        raise InputError(f"not a cell solver: {solver!r}")
    return solver if solver.n_lengths == 3 else BiHexSolver(hexagon=solver)


def sliding_rhs_3d(solver: CellSolver | None = None) -> str:
    """The 3D model's default ``sliding_rhs`` with the cell ``solver`` (2D or 3D, or None):
    the one a learned cell was trained with, else :data:`SLIDING_RHS_3D`."""
    trained = None if solver is None else solver.trained_params
    return (trained or {}).get("sliding_rhs", SLIDING_RHS_3D)


def params_3d(solver: CellSolver | None = None, **values) -> Params:
    """Parameters of the 3D model for Python callers: ``Params(**values)`` (angles in radians)
    with ``sliding_rhs`` defaulting to :func:`sliding_rhs_3d` of ``solver`` instead of the
    report's λ, the default of :class:`~hmodel.params.Params` (and of the 2D model).

    >>> params_3d().sliding_rhs, params_3d(sliding_rhs="report").sliding_rhs
    ('equilibrium', 'report')
    """
    return Params(**{"sliding_rhs": sliding_rhs_3d(solver), **values})


def assignments_3d(assignments: Sequence[str] | None, solver: CellSolver | None = None,
                   base: Params | None = None, where: str = "--param") -> list[str]:
    """``NAME=VALUE`` assignments of a 3D run (``-p``, a program's ``[params]``): the 2D model's
    own parameters refused (:func:`check_3d_params`, ``where`` naming them), and
    ``sliding_rhs=`` :func:`sliding_rhs_3d` put first where they do not name it and there is no
    ``base`` (a calibrated model's parameters, which keep their own).

    >>> assignments_3d(["phi_g=25"])
    ['sliding_rhs=equilibrium', 'phi_g=25']
    """
    items = list(assignments or [])
    names = [item.partition("=")[0].strip() for item in items]
    check_3d_params(names, where)
    if "sliding_rhs" in names or base is not None:
        return items
    return [f"sliding_rhs={sliding_rhs_3d(solver)}", *items]
