"""Responses of one material point to many independent increments from the same state, in the
compiled kernel: the public face of the compiled point for stability analyses
(:mod:`hmodel.stability`).

:func:`strain_responses` applies each strain increment to the point's cells (one trial each,
eq. 1.7 or the solver's learned response); :func:`stress_responses` solves, for each stress
target, the strain increment that reaches it (the loading paths' mixed-control Newton with every
row stress-controlled; NaN where it does not converge). Both leave the state as it was.
Both run on the kernels of :mod:`hmodel.loading.compiled`, written for n components, with the
REV's own trial and kernel inputs (:func:`hmodel.rev.trial.point_trial`: the 2D REV's H-cells,
the 3D REV's bi-hexagons). They need a solver with a compiled kernel (:func:`supports`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..rev import Rev, RevState
from ..rev.trial import point_prepared, point_trial_prepared
from .compiled import NOT_CONVERGED, cell_responses_of, fd_tangent, kernel_inputs, solve_point, supports
from .newton import NewtonSettings

__all__ = ["strain_responses", "stress_responses", "supports"]


@njit(cache=True, error_model="numpy")
def _strain_kernel(values, n_flags, eps, probes, geo, p, mode, volume0, sig, resp):
    out = np.empty_like(values)
    flags = np.empty((values.shape[0], n_flags), dtype=np.bool_)
    pre = point_prepared(values, geo, p, resp)  # every probe starts from ``values``
    for k in range(probes.shape[0]):
        point_trial_prepared(values, eps, probes[k], geo, p, mode, volume0, out, flags, sig[k], resp,
                             pre)


@njit(cache=True, error_model="numpy")
def _stress_kernel(values, flags, eps, sig, K, targets, geo, p, mode, volume0, c, deps_out, resp):
    n, m = values.shape
    n_comp = eps.shape[0]
    buf = np.empty((4, n, m))
    bufflags = np.empty((4, n, flags.shape[1]), dtype=np.bool_)
    S = np.ones(n_comp, dtype=np.bool_)
    M = np.eye(n_comp)
    pre = point_prepared(values, geo, p, resp)  # solve_point fills it again
    for k in range(targets.shape[0]):
        v = values.copy()
        f = flags.copy()
        e = eps.copy()
        s = sig.copy()
        Kk = K.copy()
        has = np.ones(1, dtype=np.bool_)
        status = solve_point(v, f, e, s, Kk, has, S, M, targets[k], geo, p, mode, volume0, c, 0,
                             buf, bufflags, resp, pre, np.empty(0), np.zeros(1, dtype=np.int64))
        for j in range(n_comp):
            deps_out[k, j] = np.nan if status == NOT_CONVERGED else e[j] - eps[j]


def strain_responses(rev: Rev, one: RevState, deps: np.ndarray) -> np.ndarray:
    """Stresses (n, c) after each strain increment ``deps`` (n, c) from the single material
    point ``one`` (c: the REV's components, 3 in 2D, 6 in 3D)."""
    k = int(one.set_index[0])
    geo, p = kernel_inputs(rev, k)
    sig = np.empty((len(deps), one.n_components))
    values = np.ascontiguousarray(one.cells.values[0])
    _strain_kernel(values, one.flags.flags.shape[-1], one.eps[0], np.ascontiguousarray(deps, float),
                   geo, p, rev.mode, rev.volumes0[k], sig, cell_responses_of(rev.kernels[k], values))
    return sig


def stress_responses(rev: Rev, one: RevState, targets: np.ndarray,
                     settings: NewtonSettings = NewtonSettings()) -> np.ndarray:
    """Strain increments (n, c) that reach each stress ``targets`` (n, c) from the single
    material point ``one`` (NaN rows where Newton does not converge), starting every solve
    from the point's finite-difference tangent."""
    k = int(one.set_index[0])
    geo, p = kernel_inputs(rev, k)
    c = one.n_components
    values = np.ascontiguousarray(one.cells.values[0])
    flags = np.ascontiguousarray(one.flags.flags[0])
    K = np.empty((c, c))
    resp = cell_responses_of(rev.kernels[k], values)
    fd_tangent(values, one.eps[0], np.zeros(c), geo, p, rev.mode, rev.volumes0[k], settings.fd_step,
               np.empty_like(values), np.empty_like(flags), K, resp, point_prepared(values, geo, p, resp))
    deps = np.empty((len(targets), c))
    _stress_kernel(values, flags, one.eps[0].copy(), one.sig[0].copy(), K,
                   np.ascontiguousarray(targets, float), geo, p, rev.mode, rev.volumes0[k],
                   settings.packed(), deps, resp)
    return deps
