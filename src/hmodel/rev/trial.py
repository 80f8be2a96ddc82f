"""The compiled trial of one material point, of either REV: the one face the compiled loading
path (:mod:`hmodel.loading.compiled`) calls.

Each REV gives its kernel inputs in one encoding (:meth:`hmodel.rev.batch.RevBatch.kernel_inputs`):
one row of numbers per cell, the same rows for every point of a parameter set, and each set's
packed cell parameters. The row says which trial runs: the H-cell's direction factors
(:data:`hmodel.rev.kernels.GEO_WIDTH`, the 2D REV's :func:`hmodel.rev.kernels.trial`) or the
bi-hexagon's projector rows and weighted dyads (:data:`hmodel.rev.kernels3d.GEO_WIDTH`, the 3D
REV's :func:`hmodel.rev.kernels3d.bihex_trial`).
"""

from __future__ import annotations

from numba import njit

from ..cell.bihex import bihex_prepared_width
from .kernels import new_prepared, prepared_width, trial, trial_prepared
from .kernels3d import GEO_WIDTH as BIHEX_WIDTH
from .kernels3d import bihex_trial, bihex_trial_prepared


@njit(cache=True, error_model="numpy")
def point_trial(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp):
    """The REV step of one point: cells ``values`` (C, n_fields) at strain ``eps`` by ``deps``
    -> cells ``out``, flags ``flags``, stress ``sig``; ``geo`` (C, width) and ``p`` the point's
    rows of its REV's kernel inputs, ``resp`` its learned responses (C, R; R = 0: none). Returns
    False when a cell increment failed."""
    if geo.shape[1] == BIHEX_WIDTH:
        return bihex_trial(values, eps, deps, geo, p, mode, volume0, out, flags, sig)
    return trial(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp)


@njit(cache=True, error_model="numpy")
def point_trial_prepared(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp, pre):
    """:func:`point_trial` given ``pre``, the inputs of its trials that the committed cells
    ``values`` fix (:func:`point_prepared`): for a caller that makes several trials from one
    state (Newton's), which prepares them once."""
    if geo.shape[1] == BIHEX_WIDTH:
        return bihex_trial_prepared(values, eps, deps, geo, p, mode, volume0, out, flags, sig, pre)
    return trial_prepared(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp, pre)


@njit(cache=True, error_model="numpy")
def point_prepared(values, geo, p, resp):
    """The inputs of a point's trials that its committed cells ``values`` fix, a new array (C,
    width) for :func:`point_trial_prepared` (the closed form's cells with linear contacts, an
    H-cell's or both hexagons' of a bi-hexagon; width 0 for the others);
    :func:`hmodel.rev.kernels.prepare` fills it again when the cells change."""
    if geo.shape[1] == BIHEX_WIDTH:
        return new_prepared(values, p, bihex_prepared_width(p))
    return new_prepared(values, p, prepared_width(p, resp))
