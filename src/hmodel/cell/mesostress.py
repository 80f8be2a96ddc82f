"""Love-Weber meso-stress of an H-cell (report eqs. 1.11-1.12, extra contacts of Fig. 1.6).

Returned as V_meso * sigma in the cell frame (n, t); sigma_nt = 0 by the cell's symmetry.
Compression positive. Units: N*m per unit thickness (i.e. Pa * m^2).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..params import Params
from .closed_form import P_HERTZ, kernel_params
from .hertz import extra_force
from .state import CellState


@njit(cache=True, inline="always")
def contact_vsigma(d1, d2, ca, sa, n1, n2, t1):
    """(V sigma_nn, V sigma_tt) of the hexagon's six contacts (eq. 1.12; ca, sa = cos, sin of
    alpha). Plain arithmetic: its ``py_func`` serves NumPy arrays and torch tensors too (the
    meso surrogate's way back)."""
    return (4.0 * n1 * d1 * ca * ca + 4.0 * t1 * d1 * ca * sa + 2.0 * n2 * d2,
            4.0 * n1 * d1 * sa * sa - 4.0 * t1 * d1 * ca * sa)


@njit(cache=True, inline="always")
def vsigma_local(v, i, kn, hertz, two_r):
    """(V sigma_nn, V sigma_tt) of cell i from its packed state ``v[i]`` (eq. 1.12), indexed in
    place (no row view: see closed_form.cell_update).

    Over-compressed cells get the extra contacts of docs/model.md, step 3: F(2r - l1) l1 on
    V sigma_nn when l1 <= 2r (grains 1-4) and 2 F(2r - l2) l2 on V sigma_tt when l2 <= 2r
    (grains 2-6 and 3-5), with F(δ) = kn δ, or c δ^(3/2) for Hertz-Mindlin contacts
    (``hertz`` = c, 0 for linear ones; :func:`hmodel.cell.hertz.extra_force`).
    """
    l1, l2 = v[i, 6], v[i, 7]
    vnn, vtt = contact_vsigma(v[i, 0], v[i, 1], math.cos(v[i, 2]), math.sin(v[i, 2]), v[i, 3],
                              v[i, 4], v[i, 5])
    if l1 <= two_r:
        vnn += extra_force(kn, hertz, two_r - l1) * l1
    if l2 <= two_r:
        vtt += 2.0 * extra_force(kn, hertz, two_r - l2) * l2
    return vnn, vtt


@njit(cache=True)
def _vsigma_all(values, kn, hertz, two_r, out):
    for i in range(values.shape[0]):
        out[i, 0], out[i, 1] = vsigma_local(values, i, kn, hertz, two_r)


def meso_vsigma(params: Params, state: CellState) -> np.ndarray:
    """V_meso * (sigma_nn, sigma_tt) of every cell, shape (..., 2) (eq. 1.12)."""
    values = np.ascontiguousarray(state.values.reshape(-1, state.values.shape[-1]))
    out = np.empty((values.shape[0], 2))
    _vsigma_all(values, params.kn, kernel_params(params)[P_HERTZ], 2.0 * params.radius, out)
    return out.reshape(*state.shape, 2)


def meso_volume(params: Params, state: CellState) -> np.ndarray:
    """Meso-volume of each cell for the chosen option (eqs. 1.18-1.21), shape (...)."""
    d1, d2, a, l1, l2 = state.d1, state.d2, state.alpha, state.l1, state.l2
    if params.volume in ("hexagon", "hexagon-consistent"):
        return 2 * d1 * np.sin(a) * (d2 + d1 * np.cos(a))  # eq. 1.20 (= l1* l2*, eq. 1.21)
    if params.volume == "rectangle":
        return l1 * l2  # eq. 1.18
    return (l1 + 2 * params.radius) * (l2 + 2 * params.radius)  # box, eq. 1.19
