"""The closed-form cell's exact Jacobian (:func:`hmodel.cell.closed_form.cell_jacobian`) against
central differences of the cell update itself, in every regime the update distinguishes:
sticking and sliding both ways, an open cell, the extra contacts of over-compressed cells, and
both volume options (docs/fem.md, "The material tangent")."""

import numpy as np
import pytest

from hmodel import Params
from hmodel.cell.closed_form import kernel_params
from hmodel.cell.mesostress import contact_vsigma


def _vsigma(r, kn, two_r):
    """(V σnn, V σtt) of a cell_update result r (eq. 1.12 with the extra contacts)."""
    vnn, vtt = contact_vsigma.py_func(r[1], r[2], np.cos(r[3]), np.sin(r[3]), r[4], r[5], r[6])
    if r[7] <= two_r:
        vnn += kn * (two_r - r[7]) * r[7]
    if r[8] <= two_r:
        vtt += 2.0 * kn * (two_r - r[8]) * r[8]
    return np.array([vnn, vtt])


def _cells(params):
    """Cell states (d1, d2, α, N1, N2, T1, l1, l2) and increments (dl1, dl2) chosen to put the
    update in each regime: name -> (state, dl)."""
    r, kn = params.radius, params.kn
    two_r = 2 * r
    d1, d2, a = two_r * (1 - 2e-4), two_r * (1 - 1e-4), np.radians(60)
    n1, n2 = kn * (two_r - d1), kn * (two_r - d2)
    l1, l2 = 2 * d1 * np.cos(a) + d2, 2 * d1 * np.sin(a)
    tan = params.tan_phi
    return {
        "sticking": ((d1, d2, a, n1, n2, 0.1 * tan * n1, l1, l2), (-1e-7 * r, 2e-7 * r)),
        "sliding +": ((d1, d2, a, n1, n2, 0.999 * tan * n1, l1, l2), None),
        "sliding -": ((d1, d2, a, n1, n2, -0.999 * tan * n1, l1, l2), None),
        "open": ((two_r * (1 + 1e-3), d2, a, 0.0, n2, 0.0, l1, l2), (1e-5 * r, -1e-5 * r)),
        "over-compressed": ((d1, d2, a, n1, n2, 0.1 * tan * n1, 0.98 * two_r, 0.99 * two_r),
                            (-1e-7 * r, -2e-7 * r)),
    }


@pytest.mark.parametrize("volume", ["hexagon", "hexagon-consistent"])
@pytest.mark.parametrize("regime", ["sticking", "sliding +", "sliding -", "open", "over-compressed"])
def test_cell_jacobian_equals_central_differences_of_the_update(volume, regime, jacobian_check):
    params = Params(volume=volume, sliding_rhs="equilibrium")  # "report" opens a cell sliding with T1 < 0
    state, dl = _cells(params)[regime]
    two_r = 2 * params.radius
    jacobian_check(state, dl, regime, kernel_params(params), two_r, lambda r: _vsigma(r, params.kn, two_r),
                   params.radius * 1e-5, 1e-5)
