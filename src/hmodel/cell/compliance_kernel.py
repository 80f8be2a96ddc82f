"""A cell increment with learned compliances of eq. 1.7, as a compiled per-cell kernel.

It lives with the cells, below the loading drivers and the surrogates that both use it: the
``compliance`` surrogates (:mod:`hmodel.surrogate.formulations.compliance`) learn the 24 numbers of a state's
compliances, this applies them. Within a contact regime eq. 1.7 is linear in the length
increments, so for the network's compliances ``c`` (24,) of a cell's state

    [δd1, δd2, δα] = 2r B_r [δl1, δl2]/2r + 2r b_r λ_r/2r

with r the regime of the sticking trial's Coulomb check (eq. 1.3) and λ of eq. 1.10; forces,
lengths and openings follow exactly (:func:`hmodel.cell.closed_form.finish_increment`). A
compliance network sees the state only, so every Newton trial of an increment applies the same
row ``c`` to another strain: the compiled loading driver (:mod:`hmodel.loading.compiled`) runs
:func:`compliance_increment` inside its Newton loop, so a trial costs no Python call and no
network evaluation.

A response row (:data:`N_RESPONSE` columns) is the network's 24 outputs, then a flag: non-zero
where the cell takes the closed form's increment instead (outside the training domain).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .closed_form import P_KN, P_KT, P_R, P_TAN, cell_increment, finish_increment, sliding_lambda

#: Learned numbers per state: B_stick (3x2), then [B_slide+, b_slide+], [B_slide-, b_slide-]
#: (3x2 and 3 each), row-major.
N_OUT = 24
STICK, PLUS, MINUS = 0, 6, 15  # offsets of B_stick, [B_slide+, b_slide+], [B_slide-, b_slide-]
#: Columns of a packed response row: the compliances, then the closed-form flag.
N_RESPONSE = N_OUT + 1
EXACT = N_OUT  # column of the closed-form flag


def pack_responses(comp: np.ndarray, exact: np.ndarray | None = None) -> np.ndarray:
    """Response rows (n, :data:`N_RESPONSE`) of compliances ``comp`` (n, 24) and the cells
    ``exact`` (n,) that take the closed form's increment (None: none)."""
    out = np.empty((len(comp), N_RESPONSE))
    out[:, :N_OUT] = comp
    out[:, EXACT] = 0.0 if exact is None else exact
    return out


@njit(cache=True, error_model="numpy")
def compliance_increment(values, i, dl1, dl2, resp, p, out, flags):
    """Advance cell i of ``values`` (n, 8) by (dl1, dl2) with its learned compliances
    ``resp[i, :24]`` (or eq. 1.7 itself where ``resp[i, EXACT]`` is set); write ``out[i]`` and
    ``flags[i]`` (indexed in place, no row views: see closed_form.cell_update).
    Returns False when the new state is not finite (or eq. 1.7 singular)."""
    if resp.shape[1] > EXACT and resp[i, EXACT] != 0.0:
        return cell_increment(values, i, dl1, dl2, p, out, flags, 0, 0)
    two_r = 2.0 * p[P_R]
    u1 = dl1 / two_r
    u2 = dl2 / two_r
    dd1 = two_r * (resp[i, 0] * u1 + resp[i, 1] * u2)
    dd2 = two_r * (resp[i, 2] * u1 + resp[i, 3] * u2)
    da = resp[i, 4] * u1 + resp[i, 5] * u2
    t1 = values[i, 5] + p[P_KT] * values[i, 0] * da  # sticking trial, eqs. 1.8-1.9
    sliding = abs(t1) >= p[P_TAN] * (values[i, 3] - p[P_KN] * dd1)
    xi = 1.0 if t1 >= 0.0 else -1.0
    if sliding:
        k = PLUS if xi > 0 else MINUS
        lam = sliding_lambda(values[i, 2], values[i, 3], values[i, 5], xi, p) / two_r
        dd1 = two_r * (resp[i, k] * u1 + resp[i, k + 1] * u2 + resp[i, k + 6] * lam)
        dd2 = two_r * (resp[i, k + 2] * u1 + resp[i, k + 3] * u2 + resp[i, k + 7] * lam)
        da = resp[i, k + 4] * u1 + resp[i, k + 5] * u2 + resp[i, k + 8] * lam
    return finish_increment(values, i, dl1, dl2, dd1, dd2, da, sliding, xi, p, out, flags)


@njit(cache=True, error_model="numpy")
def advance_cells(values, dl, resp, p, out, flags):
    """:func:`compliance_increment` of every cell of ``values`` (n, 8) by ``dl`` (n, 2) with
    the rows ``resp`` (n, 24 or :data:`N_RESPONSE`); writes ``out`` and ``flags``. Returns the
    index of the first non-finite cell, or -1."""
    bad = -1
    for i in range(values.shape[0]):
        if not compliance_increment(values, i, dl[i, 0], dl[i, 1], resp, p, out, flags) and bad < 0:
            bad = i
    return bad
