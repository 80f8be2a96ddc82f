"""The cell-solver interface that the REV and the loading drivers use.

Any implementation (closed form, neural surrogate, DEM) advances a batch of cells by given
increments of their lengths and returns the new state with its diagnostics. The REV and the
loading drivers see only this interface: solver specs (``closed-form``, ``surrogate:…``,
``dem:…``) are resolved above them, by :func:`hmodel.solvers.get_solver`.

A solver subclasses :class:`CellSolver` and declares what it can do as class (or instance)
attributes, each with the default of a plain 2D H-cell solver (as scikit-learn's estimators
declare their tags): the code that uses a solver reads these declarations and never probes it
for an attribute nor compares its name. :func:`hmodel.cell.conformance.check_cell_solver` runs a
solver through the contract.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError
from ..params import Params
from .state import FIELDS, CellFlags, CellState

if TYPE_CHECKING:
    from .geometry import CellGeometry

#: Index, in a learned kernel's packed parameters (after the closed form's eleven), of the law
#: its trials apply to the response rows: :data:`LAW_MESO` or :data:`LAW_COMPLIANCE`.
P_LAW = 11  # closed_form.N_CELL_PARAMS
#: A ``meso`` response (:func:`hmodel.cell.meso_kernel.meso_increment`), whose trials also
#: give their exact stress slope.
LAW_MESO = 1.0
#: Learned compliances of eq. 1.7 (:func:`hmodel.cell.compliance_kernel.compliance_increment`).
LAW_COMPLIANCE = 2.0

#: State kinds (:attr:`CellSolver.state_kind`). An H-cell: eq. 1.2's eight fields
#: (:data:`hmodel.cell.state.FIELDS`), whose meso-stress the REV takes from eq. 1.12.
STATE_H_CELL = "h-cell"
#: A bi-hexagon of the 3D model: two H-cells' fields (:data:`hmodel.cell.bihex.BIHEX_FIELDS`).
STATE_BIHEXAGON = "bi-hexagon"
#: A layout of the solver's own (:meth:`CellSolver.field_names`) with its own meso-stress
#: (:meth:`CellSolver.meso`): a richer DEM cell's, a ``meso`` surrogate's summary, ...
STATE_OWN = "own"
STATE_KINDS = (STATE_H_CELL, STATE_BIHEXAGON, STATE_OWN)
#: The cell mechanisms a parameter set may switch on (docs/mechanisms.md): Params fields whose
#: default is the published H-model; a solver declares which other values its cells implement
#: (:attr:`CellSolver.mechanisms`).
MECHANISM_PARAMS = ("contact", "renewal", "cross_contacts")


def mechanisms_of(params: Params) -> frozenset[str]:
    """The mechanisms ``params`` switches on: ``NAME=VALUE`` of each :data:`MECHANISM_PARAMS`
    field away from its default (``contact=hertz-mindlin``, ``renewal=rebirth``,
    ``cross_contacts=frictionless``)."""
    default = Params()
    return frozenset(f"{name}={getattr(params, name)}" for name in MECHANISM_PARAMS
                     if getattr(params, name) != getattr(default, name))


def check_mechanisms(solver: "CellSolver", sets: Sequence[Params]) -> None:
    """Refuse, in one line, parameter sets that switch on a mechanism the solver's cells do not
    implement (:attr:`CellSolver.mechanisms`): a learned cell (surrogate, DEM cell, compliance
    or meso kernel) learned the published model's linear contacts without renewal."""
    for params in sets:
        missing = sorted(mechanisms_of(params) - solver.mechanisms)
        if missing and missing[0].startswith("cross_contacts=") and solver.n_lengths == 2:
            raise InputError(f"{missing[0]} has no meaning for a 2D H-cell: its contacts join the "
                             "two hexagons of the 3D model's bi-hexagon (--dim 3)")
        if missing:
            raise InputError(f"{missing[0]} is not implemented by the {solver.name} cells (their "
                             "law is the published one: linear contacts, no renewal); the "
                             "closed-form cells implement it (--solver closed-form)")


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

    @property
    def exact_tangent(self) -> bool:
        """Whether the law's cells have their exact Jacobians (eq. 1.7's,
        :func:`hmodel.cell.closed_form.cell_jacobian`), from which the 2D REV's tangent is
        computed in one pass (the FEM material's); a learned law's is differentiated."""
        return not self.learned


class CellSolver(ABC):
    """Everything the engine asks of a cell solver, over arrays of any leading shape S.

    A solver implements :meth:`initial` and :meth:`step` and declares its capabilities; every
    other member has a default, that of a 2D H-cell solver without a compiled increment.

    Attributes
    ----------
    name : str
        The solver's spec, as results record it (no default: every solver declares it).
    n_lengths : int
        Length increments one cell takes in :meth:`step`: 2 for the H-cells of the 2D model
        (dl1, dl2, the default), 3 for the bi-hexagons of the 3D model (dl1, dl2, dl3).
    state_kind : str
        What a cell state is (:data:`STATE_KINDS`): :data:`STATE_H_CELL` (the default),
        :data:`STATE_BIHEXAGON` or :data:`STATE_OWN`.
    stress_rtol : float
        Newton's relative stress tolerance floor for REVs of these cells (0, the default, for a
        solver whose response is exact to round-off; larger where cells are converged
        iteratively or jump).
    bytes_per_cell : int
        Working memory of one cell in a running REV [bytes], state, buffers and the solver's
        own arrays together: the work-size guard (:mod:`hmodel.limits`) multiplies it by the
        cells of a request before anything is allocated (default 4096, a learned cell's).
    max_cell_strain : float
        The largest cell strain increment dl / l0 that :meth:`step` takes (inf, the default:
        any); the REV's Newton holds its trials within it
        (:func:`hmodel.loading.newton.solver_limits`).
    batches_sets : bool
        Whether :meth:`step_sets` steps the cells of several parameter sets in one call (a
        family network, whose material is an input); default False: the REV steps each set.
    spread_alpha0 : bool
        Whether the cells of one REV may start at their own opening angles
        (``alpha0_spread > 0``): each cell's state carries its α0 and nothing of the solver
        reads ``params.alpha0``; default False.
    learned : bool
        Whether the increments are a trained network's (a surrogate); default False.
    dem_cells : bool
        Whether the cells are DEM cells (grains relaxed in YADE), solved there or, for a learned
        solver, learned from them; default False.
    counts : dict or None
        The solver's counters (a learned solver's cell updates, cells outside its training
        domain, fallbacks), or None (the default).
    domain : dict or None
        The materials the solver was trained for, ``{name: (lo, hi)}`` in the units of the
        :class:`~hmodel.params.Params` fields (a family network's); None (the default): any.
    trained_params : dict or None
        The material parameters its cells were trained with (a learned formulation's
        ``params``, as :meth:`hmodel.params.Params.to_dict` writes them), or None (the default).
    geometry : CellGeometry or None
        The grains of a DEM cell (:class:`hmodel.cell.geometry.CellGeometry`: layout and
        Love-Weber sum), or None (the default).
    mechanisms : frozenset of str
        The cell mechanisms its cells implement beyond the published H-model, as
        ``NAME=VALUE`` of :class:`~hmodel.params.Params` (:data:`MECHANISM_PARAMS`:
        ``contact=hertz-mindlin``, ``renewal=rebirth``); a REV refuses parameters that switch
        on another (:func:`check_mechanisms`). Default: none (a learned cell's).
    """

    name: str
    n_lengths: int = 2
    state_kind: str = STATE_H_CELL
    stress_rtol: float = 0.0
    bytes_per_cell: int = 4096
    max_cell_strain: float = math.inf
    batches_sets: bool = False
    spread_alpha0: bool = False
    learned: bool = False
    dem_cells: bool = False
    counts: dict | None = None
    domain: dict | None = None
    trained_params: dict | None = None
    geometry: "CellGeometry | None" = None
    mechanisms: frozenset[str] = frozenset()

    @abstractmethod
    def initial(self, params: Params, shape: tuple[int, ...] = ()) -> CellState:
        """Unloaded cells of shape S = ``shape``, in this solver's state layout."""

    @abstractmethod
    def step(self, params: Params, state: CellState,
             *lengths: np.ndarray) -> tuple[CellState, CellFlags]:
        """One increment of every cell by its :attr:`n_lengths` length increments [m]
        (dl1, dl2 of an H-cell; dl1, dl2, dl3 of a bi-hexagon), each broadcast to S."""

    def initial_cells(self, params: Params, alpha0: np.ndarray) -> CellState:
        """Unloaded cells with their own opening angles ``alpha0`` [rad] (shape S); by default
        those of :meth:`initial`, all at ``params.alpha0`` (other angles are refused)."""
        alpha0 = np.asarray(alpha0, float)
        if not np.allclose(alpha0, params.alpha0, rtol=0.0, atol=1e-12):
            raise InputError(f"the cells of {self.name} start at the opening angle params.alpha0 only")
        return self.initial(params, alpha0.shape)

    def field_names(self) -> tuple[str, ...]:
        """Names of the fields of ``CellState.values`` (the H-cell's by default)."""
        return FIELDS

    def meso(self, params: Params, state: CellState) -> tuple[np.ndarray, np.ndarray] | None:
        """V σ in the cell frame and meso-volumes (S,) of cells whose stress is not eq. 1.12 of
        their eight H-cell fields (S, 3) (bi-hexagons: (S, 6)); None for H-cells (the default)."""
        return None

    def kernel(self, params: Params) -> CellKernel | None:
        """The compiled form of :meth:`step` for the compiled loading path, or None (the
        default: the generic driver then calls :meth:`step`)."""
        return None

    def fractions(self, params: Params, state: CellState) -> dict[str, np.ndarray]:
        """Diagnostics of this solver beyond the cells' flags: name -> boolean array (S) of the
        cells it holds for, recorded as fractions of each point's cells (a gated surrogate's
        ``gated``: the cells its next increment sends to the exact solver); {} by default."""
        return {}

    def step_sets(self, sets: Sequence[Params], index: np.ndarray, state: CellState,
                  *lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`step` of the points of several parameter sets in one call (point b of the set
        ``sets[index[b]]``): the values and flags after the increment. Only where
        :attr:`batches_sets` is declared."""
        raise NotImplementedError(f"{self.name} does not step several parameter sets at once")

    def check_available(self) -> None:
        """Refuse, before any work, a solver that cannot run here (a DEM cell solver without
        YADE), in one line; nothing by default."""
