"""The H-cell: its state, the solver interface and the closed-form solver (eqs. 1.1-1.12)."""

from .base import CellKernel, CellSolver
from .closed_form import ClosedFormSolver
from .mesostress import meso_volume, meso_vsigma
from .state import FIELDS, FLAGS, CellFlags, CellState, initial_cells

__all__ = ["CellKernel", "CellSolver", "ClosedFormSolver", "CellState", "CellFlags", "FIELDS", "FLAGS",
           "initial_cells", "meso_vsigma", "meso_volume"]
