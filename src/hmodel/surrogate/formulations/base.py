"""What every surrogate formulation declares: the base class :class:`Formulation`.

A formulation maps the columns of the H-cell databases (``hmodel.data.schema``) to network
inputs X and targets Y, maps predictions back to the state after the increment, and is the
cell solver's side of a surrogate: the cells' state layout and meso-stress, the largest
increment its network knows, the precision of its inference, and how one increment of a batch
of cells follows from the network's outputs. :class:`Formulation` declares all of it, with the
defaults of a formulation of H-cells (8 fields, stress by eq. 1.12, one network in float64, no
compiled increment, the closed form for cells outside the training domain); the solver
(:class:`~hmodel.surrogate.solver.SurrogateSolver`) and the training code read these
declarations and never probe a formulation for an attribute.

The solver runs the networks (:class:`Networks`) and keeps its own counts and fallback: a
formulation's :meth:`Formulation.step_cells` returns the new states with the cells outside the
training domain (an :class:`Increment`), and the solver counts them and hands them to its
fallback solver where :attr:`Formulation.falls_back`.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import NamedTuple, Protocol

import numpy as np

from ...cell.base import STATE_H_CELL
from ...cell.state import FIELDS, CellState, initial_cells
from ...params import Params

#: The predicted state columns of an H-cell (report §2.3).
OUTPUTS = ("alpha_next", "N1_next", "N2_next", "T1_next")

#: Material inputs a network over a range of materials (a *family*) may take, each
#: dimensionless: kn and r are scaled out (forces in kn·2r, lengths in 2r), so the response in
#: those units depends on these alone. Each maps to (the value of a Params, the column of
#: database rows that draw a material per path, :data:`hmodel.data.schema.MATERIAL_COLUMNS`).
MATERIAL_INPUTS = {
    "kt_kn": (lambda p: p.kt_kn, lambda c: np.asarray(c["kt_kn"], float)),
    # tan φg, not φg: the Coulomb bound T = tan φg N, hence the sliding compliances, are linear in it
    "tan_phi_g": (lambda p: p.tan_phi, lambda c: np.tan(np.asarray(c["phi_g"], float))),
    "alpha0": (lambda p: p.alpha0, lambda c: np.asarray(c["alpha0"], float)),
}


def material_features(names: tuple[str, ...], params: Params | None = None,
                      columns: dict[str, np.ndarray] | None = None, n: int = 0) -> np.ndarray:
    """The material inputs ``names`` (:data:`MATERIAL_INPUTS`) as (n, len(names)) columns: of
    one material ``params`` for n cells, or of database rows ``columns``."""
    if columns is not None:
        return np.column_stack([MATERIAL_INPUTS[k][1](columns) for k in names])
    return np.tile([MATERIAL_INPUTS[k][0](params) for k in names], (n, 1))


def is_h_cell(cell: str) -> bool:
    """Whether the cell solver ``cell`` (a spec) makes H-cells, as it declares
    (:attr:`hmodel.cell.CellSolver.state_kind`): the closed form's, the standard DEM cell's."""
    from ...solvers import get_solver

    return get_solver(cell).state_kind == STATE_H_CELL


class Networks(Protocol):
    """The networks a formulation's increment evaluates, run by the solver
    (:class:`~hmodel.surrogate.solver.SurrogateSolver`)."""

    def forward(self, X: np.ndarray) -> np.ndarray:
        """The network's outputs for inputs X (n, n_inputs), in float64, not cached (one
        network: strain-input formulations have no ensembles)."""
        ...

    def outside(self, X: np.ndarray) -> np.ndarray:
        """Rows of X outside the training domain (the solver's margin)."""
        ...

    def outputs(self, v: np.ndarray, X: np.ndarray | None = None, params: Params | None = None,
                key: tuple | None = None) -> tuple[list[np.ndarray], np.ndarray]:
        """Every member's outputs for states v whose inputs X depend on the state only (None:
        the formulation's features of v, and of a family's material ``params``, computed when
        v is new), and the mask of the cells outside the training domain (or gated); cached
        while the states (and the material, or what ``key`` names) do not change."""
        ...


class Increment(NamedTuple):
    """One network step of a batch of cells (:meth:`Formulation.step_cells`)."""

    #: New states (n, n_state).
    new: np.ndarray
    #: Flags (n, 5) (:class:`hmodel.cell.CellFlags`).
    flags: np.ndarray
    #: Cells outside the training domain (n,), which the solver counts and, where the
    #: formulation :attr:`~Formulation.falls_back`, hands to its fallback solver.
    outside: np.ndarray
    #: ``describe(i)`` names cell i's inputs, for the out-of-domain error.
    describe: Callable[[int], str]
    #: Every member's network outputs for the cells' states (formulations whose network sees
    #: the state only: an ensemble's gate on the increment compares them), else None.
    outs: list[np.ndarray] | None = None
    #: Rows the network evaluated outside the solver's cached :meth:`Networks.outputs`.
    network_cells: int = 0


class Formulation(ABC):
    """Inputs, targets and the way back of training, and the formulation's side of the cell
    solver; every attribute declared here has the default of an H-cell formulation.

    Attributes
    ----------
    name : str
        ``report``, ``increment``, ``report-leak``, ``compliance`` or ``meso``
        (:mod:`hmodel.surrogate.formulations.registry`).
    """

    name: str
    #: Fields of a cell state (the H-cell's 8, or the ``meso`` summary's 11).
    n_state: int = len(FIELDS)
    #: Their names (the H-cell's, :data:`hmodel.cell.FIELDS`, or the ``meso`` summary's).
    state_fields: tuple[str, ...] = FIELDS
    #: Index of the output trained by classification (None: all regression).
    logit_column: int | None = None
    #: Outputs of a network whose outputs are not the targets (a structured :meth:`head`;
    #: None: as many as targets).
    n_outputs: int | None = None
    #: Whether the network runs in float32 (:meth:`hmodel.surrogate.model.Surrogate.forward`).
    #: Strain-input networks' Newton tangents are finite differences of their outputs, which
    #: float32 round-off turns into noise: float64 by default.
    single_precision: bool = False
    #: Columns the solver leaves after one network's outputs, for the formulation to fill.
    spare_columns: int = 0
    #: Whether several networks may combine their increments (an ensemble:
    #: :meth:`member_afters`, :meth:`ensemble_decode`).
    ensembles: bool = False
    #: Whether the network sees the cell's state only (:meth:`features`), so that the solver
    #: evaluates it once per state and reuses it for every trial increment.
    state_only: bool = False
    #: Whether a cell outside the training domain (or gated) can be handed to an exact H-cell
    #: solver (the closed form): its state is an H-cell's.
    falls_back: bool = True
    #: Whether the cells are richer than H-cells (their meso-stress is learned, not eq. 1.12).
    richer: bool = False
    #: The cell solver of the training data (H-cell formulations: any H-cell solver).
    cell: str = "closed-form"
    #: Whether the inputs need the state after the increment (no cell solver can run it).
    needs_answer: bool = False
    #: The predicted state columns (``*_next``) of :meth:`decode`.
    outputs: tuple[str, ...] = OUTPUTS
    #: A family network's material inputs (:data:`MATERIAL_INPUTS`), after the state's; ()
    #: for a network of one material.
    material_inputs: tuple[str, ...] = ()
    #: Whether :meth:`step_cells_sets` steps cells of several materials in one network call.
    steps_sets: bool = False
    #: Whether a narrower network can learn this one's increments (:mod:`hmodel.surrogate.distill`):
    #: those of a structured head (:meth:`head`) with a secant weighting and rollouts.
    distils: bool = False

    @abstractmethod
    def to_dict(self) -> dict:
        """What rebuilds the formulation (a model file's ``formulation``)."""

    # -- training -------------------------------------------------------------------------
    def augment(self, c: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Database columns with the columns the formulation derives from them (none)."""
        return c

    @abstractmethod
    def inputs(self, c: dict[str, np.ndarray]) -> np.ndarray:
        """Network inputs X from database columns."""

    @abstractmethod
    def targets(self, c: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """Targets Y and their weights in the loss from database columns."""

    def aux(self, c: dict[str, np.ndarray]) -> np.ndarray | None:
        """Per-row inputs of :meth:`head` (None: the network's outputs are the targets)."""
        return None

    def head(self, out, aux, target=None):
        """The targets' prediction from network outputs (NumPy or torch): the outputs."""
        return out

    @abstractmethod
    def decode(self, c: dict[str, np.ndarray], out: np.ndarray) -> dict[str, np.ndarray]:
        """The state after the increment (``*_next`` columns) from network outputs."""

    def ensemble_decode(self, c: dict[str, np.ndarray], outs: list[np.ndarray]) -> dict[str, np.ndarray]:
        """:meth:`decode` of an ensemble whose members' outputs are ``outs``, as the solver
        combines them: their mean."""
        return self.decode(c, np.mean(outs, axis=0))

    def fits(self, cell: str) -> bool:
        """Whether rows of cells of the solver ``cell`` are this formulation's: H-cells."""
        return is_h_cell(cell)

    def row_weights(self, Y: np.ndarray, W: np.ndarray, aux: np.ndarray | None, config) -> np.ndarray:
        """The weights ``W`` of :meth:`targets` under a training's ``config`` (as they are)."""
        return W

    def rollout_loss(self, columns: dict[str, np.ndarray], config, rng, x_scaler, net):
        """The loss along the data's paths that a training's ``config`` adds (None: none)."""

    # -- the cell solver's side -----------------------------------------------------------
    def features(self, values: np.ndarray, params: Params | None = None) -> np.ndarray:
        """Network inputs of cell states (n, n_state), where the network sees the state only
        (:attr:`state_only`), for the material ``params`` (a family's; None: the trained one)."""
        raise TypeError(f"the {self.name} network's inputs are not those of a state alone")

    def max_increment(self, input_range: np.ndarray | None) -> float:
        """The largest cell strain increment one network step may take (inf: any); a larger
        one is cut into sub-steps by the solver."""
        return math.inf

    def initial(self, params: Params, shape: tuple[int, ...] = ()) -> CellState:
        """Unloaded cells in this formulation's state layout."""
        return CellState.initial(params, shape)

    def initial_cells(self, params: Params, alpha0: np.ndarray) -> CellState:
        """Unloaded cells with their own opening angles."""
        return initial_cells(params, np.asarray(alpha0, float))

    def meso(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """V sigma and meso-volume of states, for the REV; None where the stress is eq. 1.12."""
        return None

    def kernel_params(self, params: Params) -> np.ndarray | None:
        """The packed parameters of the compiled increment, whose responses are
        :meth:`responses` (:class:`hmodel.cell.CellKernel`); None: no compiled increment."""
        return None

    def responses(self, v: np.ndarray, outs: list[np.ndarray], mask: np.ndarray) -> np.ndarray:
        """The compiled increment's response rows of states ``v`` from every member's outputs
        ``outs`` for them and the cells outside the training domain ``mask``."""
        raise TypeError(f"the {self.name} formulation has no compiled increment")

    def describe(self, v: np.ndarray) -> Callable[[int], str]:
        """Names the state of cell i of ``v``, for the out-of-domain error."""
        return lambda i: ", ".join(f"{k}={v[i, j]:.4g}" for j, k in enumerate(FIELDS))

    @abstractmethod
    def step_cells(self, net: Networks, params: Params, v: np.ndarray, e1: np.ndarray, e2: np.ndarray,
                   dl: np.ndarray) -> Increment:
        """Cells ``v`` after one network step: cell strains e1, e2 (n,), length increments
        dl (n, 2)."""

    def member_afters(self, v: np.ndarray, strain: np.ndarray, dl: np.ndarray,
                      outs: list[np.ndarray]) -> list[np.ndarray]:
        """Every ensemble member's states after cell strains ``strain`` (n, 2) and length
        increments ``dl`` (n, 2) from states ``v``, from its outputs ``outs[k]``."""
        raise TypeError(f"{self.name!r} networks make no ensembles")

    def step_cells_sets(self, net: Networks, sets, row_set: np.ndarray, v, e1, e2, dl) -> Increment:
        """:meth:`step_cells` of cells of several materials (cell i of ``sets[row_set[i]]``) in
        one network call, where :attr:`steps_sets` is declared."""
        raise TypeError(f"{self.name!r} networks step one material at a time")


class MaterialScales:
    """Scales of a formulation whose material is ``self.params``: grain radius, friction
    coefficient and the force unit F = kn 2r."""

    params: Params

    @property
    def radius(self) -> float:
        return self.params.radius

    @property
    def tan_phi(self) -> float:
        return self.params.tan_phi

    @property
    def force_scale(self) -> float:
        return self.params.kn * 2 * self.params.radius
