"""The H-cell: its state, the solver interface and the closed-form solver (eqs. 1.1-1.12)."""

from .base import CellKernel, CellSolver
from .bihex import BIHEX_FIELDS, BIHEX_FLAGS, BiHexSolver
from .closed_form import ClosedFormSolver
from .mesostress import meso_volume, meso_vsigma
from .state import FIELDS, FLAGS, CellFlags, CellState, initial_cells

__all__ = ["BIHEX_FIELDS", "BIHEX_FLAGS", "FIELDS", "FLAGS", "BiHexSolver", "CellFlags", "CellKernel",
           "CellSolver", "CellState", "ClosedFormSolver", "initial_cells", "meso_volume", "meso_vsigma"]
