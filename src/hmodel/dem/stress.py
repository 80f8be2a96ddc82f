"""Love-Weber meso-stress of a DEM cell (report eq. 1.11), compression positive.

V sigma = sum over contacts of f (x) b, with f the force on grain j by grain i and
b = x_j - x_i the branch vector (compression positive: a compressive contact pushes j away
from i, f.b > 0). For the standard cell this is eq. 1.12 term by term. The same tensor is
sum over grains of F_p (x) x_p, F_p the resultant contact force on grain p (each contact enters
twice with opposite signs), i.e. the boundary form through the reactions of the driven grains
(``tests/test_dem.py`` checks both forms agree).

With grain rotations blocked the grains need not be in moment equilibrium, so the sum may
have a skew part (the blocking torques); :func:`meso_stress` returns the symmetric part (the
test measures what was dropped: nothing, for the mirror-symmetric cells).
"""

from __future__ import annotations

import numpy as np

from .scene import CellRun


def love_weber(contacts: np.ndarray) -> np.ndarray:
    """V sigma (2, 2) [N m] = sum f (x) b over the rows of a contact table (scene.CONTACT_COLUMNS)."""
    c = np.asarray(contacts, float).reshape(-1, 8)
    return np.einsum("ca,cb->ab", c[:, 4:6], c[:, 6:8])


def vsigma(run: CellRun) -> np.ndarray:
    """V sigma of every recorded step, full (not symmetrized), shape (S+1, 2, 2) [N m]."""
    return np.array([love_weber(c) for c in run.contacts])


def meso_stress(run: CellRun) -> np.ndarray:
    """Symmetric meso-stress sigma = sym(V sigma) / V of every step, (S+1, 2, 2) [Pa m]."""
    vs = vsigma(run)
    vol = run.mesostructure.volume(run.positions)
    return 0.5 * (vs + np.swapaxes(vs, -1, -2)) / vol[:, None, None]
