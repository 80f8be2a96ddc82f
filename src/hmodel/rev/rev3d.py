"""The 3D REV: bi-hexagonal cells on the sphere (docs/model3d.md).

A :class:`Rev3D` holds what does not change along a path (parameters, the sphere's directions
and cell frames, the cell solver); a :class:`~hmodel.rev.RevState` is the state of ``B``
material points with C bi-hexagons each (cells (B, C) of 16 fields, flags (B, C, 11)).

Strains and stresses are ``(B, 6)`` arrays in the order ``(11, 22, 33, 23, 13, 12)``, tensor
(not engineering) shear components, soil-mechanics signs (compression positive); stresses in Pa.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from ..cell import CellFlags, CellState
from ..cell.bihex import BIHEX_FLAGS, BiHexSolver, check_params
from ..errors import InputError
from ..params import Params, check_batch
from .batch import RevBatch
from .directions import weighted_opening_angles
from .kernels import LOC_BOX, LOC_CELL
from .kernels3d import geometry, renew_mix3d
from .model3d import cell_solver_3d
from .sphere import Sphere
from .state import RevState

#: Voigt positions (11, 22, 33, 23, 13, 12) of the index pairs (i, j).
VOIGT = ((0, 0), (1, 1), (2, 2), (1, 2), (0, 2), (0, 1))
#: Bytes per bi-hexagon of what a 3D REV holds whatever its points: the frames, projector rows,
#: weighted dyads, the compiled trial's geometry block and the temporaries that build them
#: (measured: about 640 bytes a cell, beside 650 a cell and point).
GEOMETRY_BYTES_PER_CELL = 1024


def voigt_to_tensor(v: np.ndarray) -> np.ndarray:
    """Symmetric tensors (..., 3, 3) of Voigt rows (..., 6) (tensor shear components)."""
    v = np.asarray(v, float)
    t = np.empty((*v.shape[:-1], 3, 3))
    for k, (i, j) in enumerate(VOIGT):
        t[..., i, j] = v[..., k]
        t[..., j, i] = v[..., k]
    return t


def tensor_to_voigt(t: np.ndarray) -> np.ndarray:
    """Voigt rows (..., 6) of symmetric tensors (..., 3, 3) (the symmetric part's components)."""
    t = np.asarray(t, float)
    return np.stack([0.5 * (t[..., i, j] + t[..., j, i]) for i, j in VOIGT], axis=-1)


def projector(frames: np.ndarray) -> np.ndarray:
    """P (C, 3, 6): the normal strains along a cell's axes, ε_kk = e_k·ε·e_k = P[k] @ ε_voigt,
    for frames (C, 3, 3) of rows e_k (eq. 1.1 lifted to 3D, tensor shear counted twice)."""
    e = np.asarray(frames, float)
    return np.stack([e[..., i] * e[..., j] * (1.0 if i == j else 2.0) for i, j in VOIGT], axis=-1)


def lateral_projector(proj: np.ndarray, lateral: str) -> np.ndarray:
    """The projector ``proj`` (C, 3, 6) of :func:`projector` with the lateral rows a cell's
    lengths follow (``Params.lateral``, docs/mechanisms.md, "Lateral strain about the cell's
    axis"): as they are (``affine``) or both the mean of the two (``axisymmetric``: the part of
    the strain that is axisymmetric about the cell's axis n, the trace of its restriction to
    the plane across n, halved)."""
    if lateral == "affine":
        return proj
    out = proj.copy()
    out[:, 1] = out[:, 2] = 0.5 * (proj[:, 1] + proj[:, 2])
    return out


def cell_sphere(sphere: Sphere, lateral: str, solver) -> Sphere:
    """The sphere whose cells a REV holds: ``sphere``, or with ``lateral="axisymmetric"`` and a
    bi-hexagon stepped as two hexagons (:class:`~hmodel.cell.bihex.BiHexSolver`) the same
    directions with one azimuth each. The localization then gives every azimuth of a direction
    the same lengths ((I - n n)/2 across n), the cell sees only its lengths, and its two hexagons
    answer alike (σ_t1t1 = σ_t2t2), so the azimuths' dyads sum to the one cell's
    σ_nn n n + σ_tt (I - n n) whatever their number: one azimuth is the same REV to round-off
    (docs/mechanisms.md, "Lateral strain about the cell's axis"). A solver of three lengths
    (the DEM bi-hexagon) keeps every azimuth: its two hexagons need not answer alike."""
    if lateral != "axisymmetric" or not isinstance(solver, BiHexSolver) or sphere.n_azimuth == 1:
        return sphere
    return replace(sphere, n_azimuth=1)


def dyads(frames: np.ndarray) -> np.ndarray:
    """Q (C, 3, 6): Voigt components of e_k ⊗ e_k, to rotate a cell-frame diagonal stress to
    the global frame (σ = Σ_k σ_kk e_k ⊗ e_k)."""
    e = np.asarray(frames, float)
    return np.stack([e[..., i] * e[..., j] for i, j in VOIGT], axis=-1)


class Rev3D(RevBatch):
    """Directional averaging of bi-hexagons over the sphere, for a batch of material points.

    The parameters are used as given: ``Params()`` is the report's λ (with which the tests of
    the 3D REV under mixed control stopped near 1 % strain until the event loop counted
    hexagons, docs/loading.md "Cell events"); :func:`hmodel.rev.model3d.params_3d` gives the 3D
    model's defaults (``sliding_rhs="equilibrium"``).

    Parameters
    ----------
    params : Params or sequence of Params
        One parameter set for every point, or one per point (as :class:`hmodel.rev.Rev`). Used:
        kn, kt_kn, phi_g, alpha0, radius, volume (hexagon, rectangle or box), g2, sliding_rhs;
        the 2D fabric and discretization (alpha_omega, beta_omega, n_theta) are not: the 3D ones
        are the ``sphere``'s.
    sphere : Sphere, optional
        Lebedev order, azimuths per direction and transversely isotropic fabric (default
        ``Sphere()``).
    solver : BiHexSolver or 2D CellSolver, optional
        The 3D cell solver (default the closed-form bi-hexagon; any solver of ``n_lengths`` 3,
        e.g. the DEM bi-hexagon ``dem:bihexagon``, runs on the generic loading driver when it
        has no compiled kernel), or a 2D H-cell solver, which
        then steps each hexagon of every bi-hexagon (``BiHexSolver(hexagon=solver)``; e.g. a
        surrogate of the closed-form H-cell: the learned 3D cell, docs/model3d.md): the 3D
        model's rule, :func:`hmodel.rev.model3d.cell_solver_3d`.

    Examples
    --------
    >>> rev = Rev3D(Params(), Sphere(order=7))
    >>> s = rev.step(rev.initial(1), np.array([[1e-4, 1e-4, 1e-4, 0, 0, 0]]))
    >>> bool(np.allclose(s.sig[0, :3], s.sig[0, 0], rtol=1e-12)), bool(s.sig[0, 0] > 0)
    (True, True)
    """

    #: strain and stress components of a state: (11, 22, 33, 23, 13, 12)
    n_components = 6

    def __init__(self, params: Params | Sequence[Params], sphere: Sphere | None = None,
                 solver: BiHexSolver | None = None):
        self.solver = cell_solver_3d(solver)
        #: the parameter sets (K,), and the first, whose shared fields all sets have
        self.sets = check_batch(params)
        for s in self.sets:
            check_params(s)
        self.check_mechanisms()
        self.params = self.sets[0]
        #: the discretization asked for (recorded with results)
        self.sphere = Sphere() if sphere is None else sphere
        #: the one whose cells the REV holds (:func:`cell_sphere`: one azimuth per direction
        #: where the azimuths would repeat one cell)
        self.cell_sphere = cell_sphere(self.sphere, self.params.lateral, self.solver)
        # the sphere's cells (directions × azimuths) are counted before their frames are built
        self.check_size(len(self.sets), extra_bytes=float(self.n_cells) * GEOMETRY_BYTES_PER_CELL)
        #: cell frames (C, 3, 3), rows (n, t1, t2), and weights (C,) summing to 1
        self.frames, self.weights = self.cell_sphere.frames()
        self._proj = np.ascontiguousarray(lateral_projector(projector(self.frames), self.params.lateral))
        self._wdyads = np.ascontiguousarray(self.weights[:, None, None] * dyads(self.frames))
        cell0 = [self.solver.initial(s, ()) for s in self.sets]
        # V0 = sum_i w_i V_meso,i (eq. 1.14 lifted) per set; all cells of a set start alike, but
        # with a spread of α0 (its weighted mid-quantiles, weighted_opening_angles).
        #: initial macro volume of each set's points (K,) [m^3]
        self.volumes0 = np.array([float(self.solver.meso(s, c)[1]) for s, c in zip(self.sets, cell0)]
                                 ) * self.weights.sum()
        for k, s in enumerate(self.sets):
            if s.alpha0_spread > 0:
                if not self.solver.spread_alpha0:
                    raise InputError(f"alpha0_spread > 0 is implemented for the closed-form bi-hexagon, "
                                     f"not for {self.solver.name} cells")
                self.volumes0[k] = float(self.weights @ self.solver.meso(s, self._initial_cells(s, ()))[1])
        kernels = [self.solver.kernel(s) for s in self.sets]
        #: the solver's compiled increment of each set (None: the loading drivers call
        #: :meth:`step`), run by the compiled 3D trial (:func:`hmodel.rev.kernels3d.bihex_trial`)
        self.kernels = None if any(k is None for k in kernels) else tuple(kernels)
        #: localization mode of the compiled trial: the ``box`` volume drives l + 2r
        self.mode = LOC_BOX if self.params.volume == "box" else LOC_CELL

    @property
    def n_cells(self) -> int:
        """Bi-hexagons per material point (directions × azimuths of :attr:`cell_sphere`)."""
        return self.cell_sphere.n_cells

    def _initial_cells(self, params: Params, shape: tuple[int, ...]) -> CellState:
        """Unloaded bi-hexagons of one set, shape (..., C), each with its own α0 where the set
        has a spread of them (:func:`~hmodel.rev.directions.weighted_opening_angles`)."""
        if params.alpha0_spread == 0:
            return self.solver.initial(params, shape)
        angles = weighted_opening_angles(params, self.weights)
        return self.solver.initial_cells(params, np.broadcast_to(angles, (*shape[:-1], len(angles)))
                                         if shape else angles)

    def _describe(self, n_points: int) -> str:
        cells = f"{self.n_cells:,}" if self.n_cells < 10**12 else f"{float(self.n_cells):.3g}"
        return (f"a 3D REV of {n_points:,} material point{'s' if n_points != 1 else ''} × "
                f"{cells} bi-hexagons (Lebedev order {self.sphere.order})")

    def _no_flags(self, shape: tuple[int, ...]) -> CellFlags:
        return CellFlags(np.zeros((*shape, len(BIHEX_FLAGS)), bool))

    def geometry(self) -> np.ndarray:
        """Per-cell inputs (C, 36) of the compiled trial: the projector rows of the localization
        and the weighted dyads of the averaging (:func:`hmodel.rev.kernels3d.geometry`)."""
        return geometry(self._proj, self._wdyads)

    def localize(self, cells: CellState, deps: np.ndarray) -> np.ndarray:
        """Length increments (B, C, 3) of every cell for strain increments (B, 6):
        δl_k = -L_k ε_ij e_k,i e_k,j (eq. 1.1 lifted), L = (l1, l2, l3) (+ 2r each for the
        ``box`` volume, eq. 1.19)."""
        strain = np.einsum("ckj,bj->bck", self._proj, np.asarray(deps, float))
        v = cells.values
        lengths = np.stack([v[..., 6], v[..., 7], v[..., 15]], axis=-1)
        if self.params.volume == "box":
            lengths = lengths + 2.0 * self.params.radius
        return -lengths * strain

    def macro_volume(self, eps: np.ndarray, sets: np.ndarray | None = None) -> np.ndarray:
        """V = V0 det(I - ε) (B,): the macro volume follows the macro strain."""
        v0 = self.volume0 if sets is None else self.volumes0[np.asarray(sets, np.int64)]
        return v0 * np.linalg.det(np.eye(3) - voigt_to_tensor(eps))

    def stress(self, cells: CellState, eps: np.ndarray, sets: np.ndarray | None = None) -> np.ndarray:
        """Macro stress (B, 6) [Pa] of cells (B, C) at macro strain ε (B, 6): eq. 1.15 lifted,
        σ = (1/V) Σ_c w_c Σ_k (V σ)_c,kk e_k ⊗ e_k."""
        idx = np.zeros(cells.shape[0], np.int64) if sets is None else np.asarray(sets, np.int64)
        vs, _ = self._by_set(idx, lambda s, rows: self.solver.meso(s, CellState(cells.values[rows])))
        vsig = np.einsum("bck,ckj->bj", vs[..., :3], self._wdyads)
        if np.any(vs[..., 3:]):  # a solver with cell-frame shear (none yet): rotate it too
            e = self.frames
            for k, (i, j) in zip((3, 4, 5), ((1, 2), (0, 2), (0, 1))):
                sym = e[:, i, :, None] * e[:, j, None, :] + e[:, j, :, None] * e[:, i, None, :]
                vsig += np.einsum("bc,c,cj->bj", vs[..., k], self.weights, tensor_to_voigt(sym))
        return vsig / self.macro_volume(eps, None if sets is None else idx)[:, None]

    def flag_fractions(self, state: RevState) -> dict[str, np.ndarray]:
        """Fraction of each point's hexagons (two per bi-hexagon) sliding, open, with the extra
        contacts (:meth:`RevState.fractions`), and of bi-hexagons whose hexagons' grains cross,
        name -> (B,)."""
        return {**state.fractions(), "frac_cross": state.flags.flags[..., 10].mean(axis=1)}

    def step(self, state: RevState, deps: np.ndarray) -> RevState:
        """Apply macro strain increments ``deps`` (B, 6) in one cell increment."""
        deps = np.asarray(deps, dtype=float)
        if deps.shape != state.eps.shape:
            raise InputError(f"a 3D strain increment has shape {state.eps.shape}, got {deps.shape}")
        return super().step(state, deps)

    _mix_kernel = staticmethod(renew_mix3d)  # RevBatch._renew

    def _kernel_geometry(self) -> np.ndarray:
        """The cells' projector rows and weighted dyads (1, C, 36), one block for every set
        (:meth:`geometry`). The 3D trial is the closed form's: a learned 3D cell's kernel is
        refused (one-line :class:`~hmodel.errors.InputError`), not ignored."""
        if any(k.learned for k in self.kernels):
            raise InputError("the compiled 3D trial applies the closed-form bi-hexagon; a learned 3D "
                             "cell runs on the generic driver (run_segment(..., compiled=False))")
        return self.geometry()[None]
