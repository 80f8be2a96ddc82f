"""The cell-solver interface that the REV and the loading drivers use.

Any implementation (closed form, neural surrogate, DEM) advances a batch of cells by given
increments of their lengths and returns the new state with its diagnostics. The REV never
knows which one runs.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from ..errors import InputError
from ..params import Params
from .state import CellFlags, CellState


@runtime_checkable
class CellSolver(Protocol):
    """``step(params, state, dl1, dl2) -> (state, flags)`` over arrays of any leading shape."""

    name: str

    def step(self, params: Params, state: CellState, dl1: np.ndarray,
             dl2: np.ndarray) -> tuple[CellState, CellFlags]:
        ...


def get_solver(spec: "str | CellSolver") -> CellSolver:
    """Resolve a solver from its CLI spelling or pass an instance through.

    ``closed-form`` (eq. 1.7), ``surrogate`` (the shipped neural surrogate),
    ``surrogate:NAME`` (another shipped one) or ``surrogate:MODEL_FILE``.
    """
    if not isinstance(spec, str):
        return spec
    name = spec.split(":", 1)[0]
    if name == "closed-form":
        from .closed_form import ClosedFormSolver
        return ClosedFormSolver()
    if name == "surrogate":
        from ..surrogate.solver import load_solver
        return load_solver(spec)
    if name == "dem":
        from ..dem.solver import DEMSolver
        return DEMSolver(spec)
    raise InputError(f"unknown cell solver {spec!r} (available: closed-form, surrogate[:MODEL_FILE], "
                     f"dem:MESOSTRUCTURE)")
