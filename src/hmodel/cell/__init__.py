"""The H-cell: its state, the solver interface and the closed-form solver (eqs. 1.1-1.12)."""

from .base import CellSolver, get_solver
from .closed_form import ClosedFormSolver
from .mesostress import meso_volume, meso_vsigma
from .state import FIELDS, FLAGS, CellFlags, CellState

__all__ = ["CellSolver", "ClosedFormSolver", "CellState", "CellFlags", "FIELDS", "FLAGS",
           "get_solver", "meso_vsigma", "meso_volume"]
