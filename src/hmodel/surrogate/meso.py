"""The ``meso`` formulation: surrogates of richer cells (DEM mesostructures) through a summary state.

A richer DEM cell (the hexagon with a centre grain, ...) has no closed form and a state of
8 + 2g + g(g-1)/2 fields (grain centres, contact shear forces; :mod:`hmodel.dem.solver`). Its
surrogate carries a summary of that state instead, 11 fields (:data:`STATE_FIELDS`): the 8
H-cell fields measured on the six hexagon grains (:data:`hmodel.cell.FIELDS`), which describe
the cell's shape and its outer contacts, and the cell's meso-stress times its meso-volume,
``Vs = V sigma`` (nn, tt, nt), from the Love-Weber sum over all its contacts (eq. 1.11). What the
grains inside do enters through Vs, which is also all the REV needs of a cell (eqs. 1.13-1.14).

The network maps the summary before (forces over F = kn 2r, lengths over 2r) to an
incrementally multi-linear response: for a cell strain increment de, with e = de/m0, m0 = 1e-3,

    X = (alpha, l1/2r, l2/2r, N1/F, N2/F, T1/F, Vs_nn/F2r, Vs_tt/F2r[, Vs_nt/F2r])
    dz = A(X) e + sum_k <n_k(X) . e> B_k(X),   k = 1..K (``mechanisms``, default 4),
    dz = (d alpha, dN1/F, dN2/F, dT1/F, dVs_nn/F2r, dVs_tt/F2r[, dVs_nt/F2r]),

<x> = max(x, 0): the network outputs the tangent A and, for each mechanism, a loading direction
n_k and a flow B_k. This is the form of a rate-independent cell's increment to first order:
linear within a contact regime (every contact sticking, sliding or open), and continuous with a
kink where the increment's direction crosses into another regime (a contact starts to slide:
the line n_k . e = 0 of the Coulomb trial, eq. 1.3), with one mechanism per independent kink.
The increments of the data (<= 0.2 %) change the state so little that the second-order term is
below the data's noise. The form gives exactly no change for no strain (no bias to accumulate
over the thousands of increments of a path); the network sees the state only, so the REV's
Newton iterations and their finite-difference probes reuse one evaluation per state.
Loss: on dz/m0, so that small increments, whose dz is mostly DEM noise relative to m, weigh
little. (Tried first, worse: the direction of de as an input with a single tangent, 5-15 % of
peak q on closed-form REV paths; the magnitude as an input too: small steps half as stiff.)

Vs_nt is learned for richer cells only (the bracketed terms): an H-cell's eq. 1.12 has no nt
term, whereas in DEM a free inner grain can leave the axis and break the cell's symmetry (up to
0.5 % of |Vs| in the hexagon-center data).

The way back enforces what holds for every such cell: N1, N2 >= 0, |T1| <= tan(phi_g) N1
(eq. 1.3), Vs positive semi-definite (every contact force is compressive), lengths from the
strain, d1 and d2 from alpha and the lengths (eq. 1.2), and the meso-volume of the six driven
grains' hexagon, V = 2 d1 sin(alpha) (d2 + d1 cos(alpha)) (eq. 1.20, the DEM cells' meso-volume).

Training rows come from any cell solver: a richer DEM cell's extra state columns give its
Love-Weber stress; for H-cells (``closed-form``, ``dem:standard``) it is eq. 1.12 of the fields
(with the extra contacts of over-compressed cells), as in the REV.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..cell.mesostress import meso_vsigma
from ..cell.state import FIELDS, CellState
from ..errors import InputError
from ..params import Params
from .formulations import OUTPUTS

MESO_FIELDS = ("Vs_nn", "Vs_tt", "Vs_nt")
STATE_FIELDS = FIELDS + MESO_FIELDS
SYMMETRIC = ("alpha", "N1", "N2", "T1", "Vs_nn", "Vs_tt")  #: learned fields of H-cells
_COL = {k: j for j, k in enumerate(STATE_FIELDS)}


@dataclass(frozen=True)
class MesoFormulation:
    """Summary state, inputs, targets and decoding for cells of the solver ``cell``."""

    params: Params  #: the material the data was made with
    cell: str = "closed-form"  #: the data's cell solver (``dem:hexagon-center``, ...)
    mechanisms: int = 4  #: kinks of the incremental response (see the module docstring)
    name: str = "meso"
    logit_column = None
    n_state = len(STATE_FIELDS)

    @property
    def shear(self) -> bool:
        """Whether Vs_nt is learned: richer cells (more than the H-cell's 8 fields)."""
        return self._dem.n_fields > len(FIELDS)

    @property
    def learned(self) -> tuple[str, ...]:
        return SYMMETRIC + (("Vs_nt",) if self.shear else ())

    @property
    def outputs(self) -> tuple[str, ...]:
        return OUTPUTS + tuple(f"{k}_next" for k in self.learned[4:])

    @property
    def input_names(self) -> tuple[str, ...]:
        return ("alpha", "l1/2r", "l2/2r", "N1/F", "N2/F", "T1/F") + tuple(
            f"{k}/F2r" for k in self.learned[4:])

    @property
    def n_outputs(self) -> int:
        """A (row-major, len(learned) x 2), then (n_k, B_k) per mechanism."""
        L = len(self.learned)
        return 2 * L + self.mechanisms * (L + 2)
    m0 = 1e-3  #: strain scale of the inputs and targets

    def __post_init__(self) -> None:
        if not (self.cell == "closed-form" or self.cell.startswith("dem:")):
            raise InputError(f"the meso formulation needs H-cell or DEM data, got cells of {self.cell!r}")

    def to_dict(self) -> dict:
        return {"name": self.name, "params": self.params.to_dict(), "cell": self.cell,
                "mechanisms": self.mechanisms}

    @property
    def radius(self) -> float:
        return self.params.radius

    @property
    def tan_phi(self) -> float:
        return self.params.tan_phi

    @property
    def force_scale(self) -> float:
        return self.params.kn * 2 * self.params.radius

    @cached_property
    def _dem(self):
        """The DEM description of the cells (geometry and Love-Weber sum; never starts YADE)."""
        from ..dem.solver import DEMSolver
        return DEMSolver(self.cell if self.cell.startswith("dem:") else "dem:standard")

    # -- summary state ------------------------------------------------------------------
    def vsigma(self, full: np.ndarray) -> np.ndarray:
        """(V sigma_nn, V sigma_tt, V sigma_nt) (n, 3) of full cell states (n, n_fields): the
        Love-Weber sum of a richer cell's contacts; eq. 1.12 of an H-cell's fields, as the REV
        computes it (a sum over contacts rebuilt from positions would differ where the closed
        form's incremental d1, alpha drift from eq. 1.2 at second order: 1e-7 of a length is
        ~1e-3 of a force)."""
        full = np.asarray(full, float)
        if full.shape[1] == len(FIELDS):
            vs = meso_vsigma(self.params, CellState(np.ascontiguousarray(full)))
            return np.column_stack([vs, np.zeros(len(full))])
        return self._dem.love_weber(self.params, full)[0]

    def summary(self, full: np.ndarray) -> np.ndarray:
        """Summary rows (n, 11) of full cell states (n, n_fields) of the data's solver."""
        return np.hstack([full[:, :8], self.vsigma(full)])

    def initial(self, shape: tuple[int, ...] = ()) -> CellState:
        """Summary of unloaded cells of opening angle params.alpha0."""
        full = (CellState.initial(self.params, (1,)) if self.cell == "closed-form"
                else self._dem.initial(self.params, (1,))).values
        return CellState(np.broadcast_to(self.summary(full)[0], (*shape, self.n_state)).copy())

    def meso(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(V sigma) (..., 3) and meso-volume (...) of summary states (..., 11), for the REV."""
        d1, d2, a = values[..., 0], values[..., 1], values[..., 2]
        return values[..., 8:11], 2 * d1 * np.sin(a) * (d2 + d1 * np.cos(a))  # eq. 1.20

    def augment(self, c: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Database columns plus the meso-stress before and after (``Vs_nn``, ``Vs_nn_next``, ...)."""
        if "Vs_nn" in c:
            return c
        n_extra = self._dem.n_fields - 8
        if n_extra and "state_extra" not in c:
            raise InputError(f"rows of {self.cell} cells need their state_extra columns (a DEM dataset "
                             f"or a sample made from one)")
        out = dict(c)
        for suffix, extra in (("", "state_extra"), ("_next", "state_extra_next")):
            full = np.column_stack([c[k + suffix] for k in FIELDS]
                                   + ([np.asarray(c[extra], float).reshape(len(c["deps1"]), -1)] if n_extra else []))
            vs = self.vsigma(full)
            for j, k in enumerate(MESO_FIELDS):
                out[k + suffix] = vs[:, j]
        return out

    # -- network inputs and targets -----------------------------------------------------
    def features(self, v: np.ndarray) -> np.ndarray:
        """X (n, 8 or 9) from summary states v (n, 11)."""
        d, F = 2 * self.radius, self.force_scale
        return np.column_stack([v[:, 2], v[:, 6] / d, v[:, 7] / d, v[:, 3] / F, v[:, 4] / F,
                                v[:, 5] / F, v[:, 8:4 + len(self.learned)] / (F * d)])

    def _scales(self) -> np.ndarray:
        F, d = self.force_scale, 2 * self.radius
        return np.array([1.0, F, F, F] + [F * d] * (len(self.learned) - 4))

    def inputs(self, c: dict[str, np.ndarray]) -> np.ndarray:
        c = self.augment(c)
        return self.features(np.column_stack([c[k] for k in STATE_FIELDS]))

    def targets(self, c: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """dz/m0 (n, len(learned)) and weights: 0 on the rows where a closed cell opens. There
        the forces are cut to zero within the increment, which is not a homogeneous function of
        de (the kink does not pass through de = 0); the linear continuation learned on the other
        rows opens them in :meth:`constrain`, as the closed form's trial does. (Fitting these
        rows, 17 % of the closed-form data, left 4-6 % errors on V sigma in the other rows.)
        Rows of cells open before (zero forces) are fitted: they may close again."""
        c = self.augment(c)
        Y = np.column_stack([c[f"{k}_next"] - c[k] for k in self.learned]) / self._scales() / self.m0
        was_open = (c["N1"] <= 0) | (c["N2"] <= 0)
        opens = (np.asarray(c["open1"], bool) | np.asarray(c["open2"], bool)) & ~was_open
        W = np.ones_like(Y)
        W[opens] = 0.0
        return Y, W

    def aux(self, c: dict[str, np.ndarray]) -> np.ndarray:
        """e = de/m0 (n, 2), which the head applies the response to."""
        return np.column_stack([c["deps1"], c["deps2"]]) / self.m0

    def head(self, out, e, target=None):
        """dz/m0 = A e + sum_k <n_k . e> B_k from network outputs (n, n_outputs); NumPy or torch."""
        L = len(self.learned)
        dz = (out[:, :2 * L].reshape(-1, L, 2) @ e[:, :, None])[:, :, 0]
        for k in range(self.mechanisms):
            base = 2 * L + k * (L + 2)
            load = (out[:, base:base + 2] * e).sum(1)
            dz = dz + (0.5 * (load + abs(load)))[:, None] * out[:, base + 2:base + 2 + L]
        return dz

    def increment(self, out: np.ndarray, e1: np.ndarray, e2: np.ndarray) -> np.ndarray:
        """dz/m0 from network outputs and cell strains."""
        return self.head(out, np.column_stack([e1, e2]) / self.m0)

    def decode(self, c: dict[str, np.ndarray], out: np.ndarray) -> dict[str, np.ndarray]:
        """Predicted summary after the increment (``*_next`` columns) from network outputs A."""
        c = self.augment(c)
        v = np.column_stack([c[k] for k in STATE_FIELDS])
        Y = self.increment(out, c["deps1"], c["deps2"])
        new = self.constrain(v[:, [_COL[k] for k in self.learned]] + Y * self._scales() * self.m0)
        return {f"{k}_next": new[:, j] for j, k in enumerate(self.learned)}

    def constrain(self, u: np.ndarray) -> np.ndarray:
        """Learned fields (n, 6) made admissible: forces >= 0, Coulomb (eq. 1.3), Vs_nn, Vs_tt >= 0."""
        u = u.copy()
        u[:, 1:3] = np.maximum(u[:, 1:3], 0.0)
        u[:, 3] = np.clip(u[:, 3], -self.tan_phi * u[:, 1], self.tan_phi * u[:, 1])
        u[:, 4:6] = np.maximum(u[:, 4:6], 0.0)
        if u.shape[1] > 6:  # Vs_nt within the PSD bound
            bound = np.sqrt(u[:, 4] * u[:, 5])
            u[:, 6] = np.clip(u[:, 6], -bound, bound)
        return u

    # -- cell solver ----------------------------------------------------------------------
    def advance(self, v: np.ndarray, Y: np.ndarray, dl: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Summary states after length increments dl (n, 2), from targets Y = dz/m0 (n, 6); and flags."""
        u = self.constrain(v[:, [_COL[k] for k in self.learned]] + Y * self._scales() * self.m0)
        a = u[:, 0]
        l1, l2 = v[:, 6] + dl[:, 0], v[:, 7] + dl[:, 1]
        d1 = l2 / (2.0 * np.sin(a))  # eq. 1.2
        d2 = l1 - 2.0 * d1 * np.cos(a)
        nt = u[:, 6] if self.shear else np.zeros(len(u))
        new = np.column_stack([d1, d2, a, u[:, 1], u[:, 2], u[:, 3], l1, l2, u[:, 4], u[:, 5], nt])
        two_r = 2.0 * self.radius
        n1, n2, t1 = u[:, 1], u[:, 2], u[:, 3]
        flags = np.column_stack([(n1 > 0) & (np.abs(t1) >= self.tan_phi * n1 * (1 - 1e-9)),
                                 n1 == 0, n2 == 0, l1 <= two_r, l2 <= two_r])
        return new, flags
