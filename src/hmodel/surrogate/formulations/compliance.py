"""The ``compliance`` formulation: the network learns the cell's compliance, the contact law stays exact.

For a given contact regime, eq. 1.7 is linear in the length increments:
A(s)·[δd1, δd2, δα] = [δl1, δl2, λ], where A and λ depend on the state s before the increment
only (λ = 0 while sticking, eq. 1.10 while sliding in the direction ξ = ±1). So in each regime
r ∈ {stick, slide+, slide−}

    [δd1/2r, δd2/2r, δα] = B_r(s)·[δl1, δl2]/2r + b_r(s)·λ_r(s)/2r.

The network maps the state (α, d1/2r, N1/(kn·2r), T1/(kn·2r): the variables eq. 1.7's matrix
depends on) to the 24 numbers B_stick (3×2), B_slide+ (3×2), b_slide+ (3), B_slide− (3×2),
b_slide− (3). Everything around them is applied exactly, as in the closed form
(:func:`hmodel.cell.closed_form.finish_increment`): the regime by the Coulomb check of the
sticking trial (eq. 1.3), λ by eq. 1.10 (:func:`~hmodel.cell.closed_form.sliding_lambda`),
forces by eqs. 1.8-1.9, openings, lengths and extra contacts. Force levels enter only through
the features, so the learned numbers are O(1) at any confining pressure; the sliding offset is
the exact λ times a learned coefficient.

Training rows must be single increments (Dataset 2 with ``--substeps 1``): each row is fitted in
the regime it was in (sliding flag, ξ = sign of T1 after), the error divided by the row's drive
|δl|/2r + |λ|/2r so that small and large increments count alike. A cell that opened does not
record its regime (the flags are reset); such a row is fitted in the regime that matches it best.

In the cell solver (:meth:`ComplianceFormulation.step_cells`) the network sees the state only:
it is evaluated once per state and reused for every trial increment of a Newton iteration
(:class:`hmodel.surrogate.solver.SurrogateSolver` caches it), and every increment is an exact,
compiled application of the learned compliances, of any size within its regime (no sub-steps).
The REV's compiled loading path takes the compliances once per increment
(:meth:`ComplianceFormulation.responses`, with :meth:`ComplianceFormulation.kernel_params`) and
applies them in every Newton trial, inside its kernel
(:func:`hmodel.cell.compliance_kernel.compliance_increment`, the same per-cell code as
:meth:`ComplianceFormulation.advance`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ...cell.base import LAW_COMPLIANCE
from ...cell.closed_form import kernel_params, sliding_lambda
from ...cell.compliance_kernel import (
    MINUS,
    N_OUT,
    PLUS,
    STICK,
    advance_cells,
    compliance_increment,
    pack_responses,
)
from ...cell.state import FIELDS, initial_lengths
from ...params import Params
from .base import Formulation, Increment, MaterialScales, Networks, material_features

__all__ = ["MINUS", "N_OUT", "PLUS", "STICK", "ComplianceFormulation"]


@dataclass(frozen=True)
class ComplianceFormulation(MaterialScales, Formulation):
    """Inputs, targets and the exact decoding of the compliance formulation for one material."""

    params: Params  #: the material (only its material parameters matter)
    #: A family's material inputs (``("kt_kn", "tan_phi_g")``): the network sees them after
    #: the state, the rows' own material (drawn per path) in training and the run's in a REV,
    #: whose kn and r scale forces and lengths; () for one material.
    material_inputs: tuple[str, ...] = ()
    name: str = "compliance"
    logit_column = None
    n_outputs = N_OUT
    #: Members' compliances average (an ensemble: within a contact regime the increment is
    #: linear in them), and their spread can be the gate's trust score.
    ensembles = True
    #: float32 inference, the precision the network was trained in: the network sees the state
    #: only, so no Newton tangent differentiates its round-off; the comparison grid (every path
    #: at increments of 2e-4 to 2e-3, both loading drivers) is unchanged to 0.001 % of peak q.
    single_precision = True
    state_only = True

    def to_dict(self) -> dict:
        d = {"name": self.name, "params": self.params.to_dict()}
        if self.material_inputs:
            d["material_inputs"] = list(self.material_inputs)
        return d

    def features(self, values: np.ndarray, params: Params | None = None) -> np.ndarray:
        """Network inputs (n, 4 + material inputs) from packed cell states (n, 8)
        (:data:`hmodel.cell.FIELDS`) of the material ``params`` (None: the trained one)."""
        p = self.params if params is None else params
        d, F = 2 * p.radius, p.kn * 2 * p.radius
        X = np.column_stack([values[:, 2], values[:, 0] / d, values[:, 3] / F, values[:, 5] / F])
        if not self.material_inputs:
            return X
        return np.hstack([X, material_features(self.material_inputs, p, n=len(X))])

    def inputs(self, c: dict[str, np.ndarray]) -> np.ndarray:
        X = self.features(_packed(c))
        if not self.material_inputs:
            return X
        return np.hstack([X[:, :4], material_features(self.material_inputs, columns=c)])

    def _row_params(self, c: dict[str, np.ndarray]) -> np.ndarray:
        """Packed kernel parameters of every row (n, 7): the rows' own kt/kn and φg where they
        draw a material per path (kn, r and the closures are the dataset's)."""
        P = np.tile(kernel_params(self.params), (len(c["alpha"]), 1))
        if "kt_kn" in c:
            P[:, 1] = self.params.kn * np.asarray(c["kt_kn"], float)
            P[:, 2] = np.tan(np.asarray(c["phi_g"], float))
        return P

    def length_increments(self, c: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """δl1, δl2 of database rows: δl = −l0·δε on the cell's initial lengths (schema)."""
        l10, l20 = initial_lengths(self.radius, c["alpha0"])
        return -l10 * c["deps1"], -l20 * c["deps2"]

    def aux(self, c: dict[str, np.ndarray]) -> np.ndarray:
        """Per-row drive of the loss: (δl1, δl2, λ+, λ−)/(2r·s) and the regime (0 stick, ±1 slide,
        2 unknown: the cell opened, which resets the recorded regime)."""
        return self._drive(c)[0]

    def targets(self, c: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """Y = (δd1/2r, δd2/2r, δα)/s and the row weights (0 for empty drives)."""
        _, s = self._drive(c)
        d = 2 * self.radius
        inc = np.column_stack([(c["d1_next"] - c["d1"]) / d, (c["d2_next"] - c["d2"]) / d,
                               c["alpha_next"] - c["alpha"]])
        ok = s > 0
        Y = np.where(ok[:, None], inc / np.where(ok, s, 1.0)[:, None], 0.0)
        return Y, np.repeat(ok[:, None].astype(float), 3, axis=1)

    def _drive(self, c):
        d = 2 * self.radius
        opened = np.asarray(c["open1"], bool) | np.asarray(c["open2"], bool)
        regime = np.where(opened, 2.0, np.where(np.asarray(c["sliding"], bool),
                                                np.where(c["T1_next"] >= 0, 1.0, -1.0), 0.0))
        dl1, dl2 = self.length_increments(c)
        v, P = _packed(c), self._row_params(c)
        lp, lm = _lambda(v, np.ones(len(v)), P) / d, _lambda(v, -np.ones(len(v)), P) / d
        u1, u2 = dl1 / d, dl2 / d
        lam = np.where(regime == 1.0, np.abs(lp), np.where(regime == -1.0, np.abs(lm), 0.0))
        lam = np.where(regime == 2.0, np.maximum(np.abs(lp), np.abs(lm)), lam)
        s = np.hypot(u1, u2) + lam
        inv = 1.0 / np.where(s > 0, s, 1.0)
        return np.column_stack([u1 * inv, u2 * inv, lp * inv, lm * inv, regime]), s

    def head(self, out, aux, target=None):
        """Increment (δd1/2r, δd2/2r, δα)/s of each row in its recorded regime (NumPy or torch).

        Rows of unknown regime take the regime that fits ``target`` best: eq. 1.7 ran in one of
        them before the contact opened.
        """
        u1, u2, lp, lm, r = aux[:, 0:1], aux[:, 1:2], aux[:, 2:3], aux[:, 3:4], aux[:, 4:5]

        def linear(k):
            return out[:, k:k + 6:2] * u1 + out[:, k + 1:k + 6:2] * u2

        stick = linear(STICK)
        plus = linear(PLUS) + out[:, PLUS + 6:PLUS + 9] * lp
        minus = linear(MINUS) + out[:, MINUS + 6:MINUS + 9] * lm
        is_plus, is_minus = (r > 0.5) * (r < 1.5) * 1.0, (r < -0.5) * 1.0
        if target is not None:
            unknown = (r > 1.5) * 1.0
            e_s, e_p, e_m = (((x - target) ** 2).sum(1)[:, None] for x in (stick, plus, minus))
            is_plus = is_plus + unknown * (e_p < e_s) * (e_p <= e_m)
            is_minus = is_minus + unknown * (e_m < e_s) * (e_m < e_p)
        return stick * (1.0 - is_plus - is_minus) + plus * is_plus + minus * is_minus

    def advance(self, values: np.ndarray, dl: np.ndarray, out: np.ndarray, params: Params | None = None,
                rows: np.ndarray | None = None):
        """New packed states (n, 8) and flags (n, 5) of cells ``values`` under length increments
        ``dl`` (n, 2), with the network's compliances ``out`` (n, 24) for those states, of the
        material ``params`` (None: the trained one) or each row's (``rows``, packed (n, 7))."""
        new = np.empty_like(values)
        flags = np.empty((len(values), 5), dtype=np.bool_)
        args = (np.ascontiguousarray(values), np.ascontiguousarray(dl), np.ascontiguousarray(out))
        if rows is not None:
            _advance_rows(*args, np.ascontiguousarray(rows), new, flags)
        else:
            advance_cells(*args, kernel_params(self.params if params is None else params), new, flags)
        return new, flags

    def kernel_params(self, params: Params) -> np.ndarray:
        """The compiled increment's parameters: the learned compliances of the states (one
        network evaluation per increment, :meth:`responses`), which every Newton trial applies in
        :func:`hmodel.cell.compliance_kernel.compliance_increment`; cells outside the training
        domain take eq. 1.7 there."""
        return np.append(kernel_params(params), LAW_COMPLIANCE)

    def responses(self, v: np.ndarray, outs: list[np.ndarray], mask: np.ndarray) -> np.ndarray:
        """Packed response rows (n, 25) of cell states ``v`` (n, 8): the compliances (an
        ensemble's mean) and the cells outside the training domain ``mask``, which take the
        closed form instead."""
        return pack_responses(_mean(outs), mask)

    def step_cells(self, net: Networks, params: Params, v, e1, e2, dl) -> Increment:
        """One exact increment of cells ``v`` with the learned compliances of their states (a
        family's: of their states and the run's material)."""
        outs, mask = net.outputs(v, params=params) if self.material_inputs else net.outputs(v)
        new, flags = self.advance(v, dl, _mean(outs), params)
        return Increment(new, flags, mask, self.describe(v), outs)

    def member_afters(self, v, strain, dl, outs):
        """Every member's states after length increments ``dl``, its compliances applied."""
        return [self.advance(v, dl, o)[0] for o in outs]

    def decode(self, c: dict[str, np.ndarray], out: np.ndarray) -> dict[str, np.ndarray]:
        """Predicted state after the increment of database rows (Surrogate.predict)."""
        dl1, dl2 = self.length_increments(c)
        new, _ = self.advance(_packed(c), np.column_stack([dl1, dl2]), out, rows=self._row_params(c))
        return {"alpha_next": new[:, 2], "N1_next": new[:, 3], "N2_next": new[:, 4], "T1_next": new[:, 5]}


def _mean(outs: list[np.ndarray]) -> np.ndarray:
    """The compliances of an ensemble's members averaged (one member's as they are)."""
    return outs[0] if len(outs) == 1 else np.mean(outs, axis=0)


def _packed(c: dict[str, np.ndarray]) -> np.ndarray:
    return np.column_stack([np.asarray(c[k], float) for k in FIELDS])


@njit(cache=True)
def _lambda_kernel(values, regime, P, out):
    for i in range(values.shape[0]):
        out[i] = sliding_lambda(values[i, 2], values[i, 3], values[i, 5],
                                1.0 if regime[i] >= 0 else -1.0, P[i])


def _lambda(values, regime, P):
    """λ of eq. 1.10 of every row in the sliding direction ``regime`` (±1), with the rows'
    packed parameters P (n, 7)."""
    out = np.empty(len(values))
    _lambda_kernel(np.ascontiguousarray(values), np.asarray(regime, float), np.ascontiguousarray(P), out)
    return out


@njit(cache=True)
def _advance_rows(values, dl, resp, P, out, flags):
    """:func:`advance_cells` with each row's own packed parameters P (n, 7)."""
    for i in range(values.shape[0]):
        compliance_increment(values, i, dl[i, 0], dl[i, 1], resp, P[i], out, flags)
