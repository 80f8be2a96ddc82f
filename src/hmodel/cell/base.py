"""The cell-solver interface that the REV and the loading drivers use.

Any implementation (closed form, neural surrogate, DEM) advances a batch of cells by given
increments of their lengths and returns the new state with its diagnostics. The REV and the
loading drivers see only this interface: solver specs (``closed-form``, ``surrogate:…``,
``dem:…``) are resolved above them, by :func:`hmodel.solvers.get_solver`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from ..params import Params
from .state import CellFlags, CellState

#: Index, in a learned kernel's packed parameters (after the closed form's seven), of the law
#: its trials apply to the response rows: :data:`LAW_MESO` or :data:`LAW_COMPLIANCE`.
P_LAW = 7
#: A ``meso`` response (:func:`hmodel.cell.meso_kernel.meso_increment`), whose trials also
#: give their exact stress slope.
LAW_MESO = 1.0
#: Learned compliances of eq. 1.7 (:func:`hmodel.cell.compliance_kernel.compliance_increment`).
LAW_COMPLIANCE = 2.0


@dataclass(frozen=True)
class CellKernel:
    """A cell solver's increment in compiled form, for the compiled loading path.

    Attributes
    ----------
    params : ndarray
        Packed parameters of the trial kernel: the closed form's
        (:func:`hmodel.cell.closed_form.kernel_params`) or, for a learned response, those
        followed by the law (index :data:`P_LAW`) and its constants
        (:func:`hmodel.cell.meso_kernel.kernel_params`; none for compliances).
    responses : callable or None
        None: every trial is the closed form's cell increment (eq. 1.7). Otherwise
        ``responses(values)`` maps cell states (n, n_fields) to the packed learned responses
        (n, R) that every trial increment from those states applies
        (:func:`hmodel.cell.meso_kernel.meso_increment`,
        :func:`hmodel.cell.compliance_kernel.compliance_increment`): evaluated once per
        increment, it may raise :class:`~hmodel.errors.SolverError` (cells outside a training
        domain).
    """

    params: np.ndarray
    responses: Callable[[np.ndarray], np.ndarray] | None = None

    @property
    def learned(self) -> bool:
        """Whether trials apply a learned response (the law at :data:`P_LAW` of ``params``) or
        eq. 1.7."""
        return self.responses is not None


@runtime_checkable
class CellSolver(Protocol):
    """Everything the engine asks of a cell solver, over arrays of any leading shape S.

    Attributes
    ----------
    name : str
        The solver's spec, as results record it.
    stress_rtol : float
        Newton's relative stress tolerance floor for REVs of these cells (0 for a solver whose
        response is exact to round-off; larger where cells are converged iteratively or jump).
    bytes_per_cell : int
        Working memory of one cell in a running REV [bytes], state, buffers and the solver's
        own arrays together: the work-size guard (:mod:`hmodel.limits`) multiplies it by the
        cells of a request before anything is allocated.
    n_lengths : int
        Length increments one cell takes in :meth:`step`: 2 for the H-cells of the 2D model
        (dl1, dl2), 3 for the bi-hexagons of the 3D model (dl1, dl2, dl3).
    """

    name: str
    stress_rtol: float
    bytes_per_cell: int
    n_lengths: int

    def initial(self, params: Params, shape: tuple[int, ...] = ()) -> CellState:
        """Unloaded cells of shape S = ``shape``, in this solver's state layout."""
        ...

    def initial_cells(self, params: Params, alpha0: np.ndarray) -> CellState:
        """Unloaded cells with their own opening angles ``alpha0`` [rad] (shape S)."""
        ...

    def meso(self, params: Params, state: CellState) -> tuple[np.ndarray, np.ndarray] | None:
        """(V σ_nn, V σ_tt, V σ_nt) (S, 3) in the cell frame and meso-volumes (S,) of cells
        whose stress is not eq. 1.12 of their eight H-cell fields; None for H-cells."""
        ...

    def step(self, params: Params, state: CellState, dl1: np.ndarray,
             dl2: np.ndarray) -> tuple[CellState, CellFlags]:
        """One increment of every cell by length increments dl1, dl2 [m] (broadcast to S)."""
        ...

    def kernel(self, params: Params) -> CellKernel | None:
        """The compiled form of :meth:`step` for the compiled loading path, or None (the
        generic driver then calls :meth:`step`)."""
        ...

    def fractions(self, params: Params, state: CellState) -> dict[str, np.ndarray]:
        """Diagnostics of this solver beyond the cells' flags: name -> boolean array (S) of the
        cells it holds for, recorded as fractions of each point's cells (a gated surrogate's
        ``gated``: the cells its next increment sends to the exact solver); {} for most."""
        ...
