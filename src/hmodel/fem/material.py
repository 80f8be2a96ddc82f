"""Material laws at the Gauss points: the batched H-model REV, and linear elasticity (tests).

A law answers one question, the stress after a strain increment from its committed state and
the consistent tangent there, for all Gauss points at once (:meth:`trial`); :meth:`commit`
makes a trial the new committed state once the global Newton has converged. Its ``state`` (and
its trials') is the REV state of its Gauss points, or None for a law without cells. Strains, stresses
and tangents use hmodel's convention (:mod:`hmodel.fem.assembly`).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..cell import CellFlags, CellState
from ..errors import InputError
from ..loading import consolidate
from ..loading.compiled import batch_inputs, closed_form_tangent, trial
from ..rev import Rev, RevState

#: Finite-difference strain perturbation of the tangent. The stress of one increment is
#: piecewise smooth in the increment (a cell's regime changes at a kink); a perturbation far
#: below the load step's strain (1e-4 .. 1e-3) keeps the tangent on the trial's own branch,
#: and at stresses ~1e5 Pa and stiffnesses ~1e8 Pa it still moves the stress by ~1 Pa, nine
#: orders above round-off. A solver whose cells are converged only to a relative ``stress_rtol``
#: (DEM cells, surrogates' sub-steps) gets ten times that instead, so that its noise stays
#: far below the perturbation's response.
FD_STEP = 1e-8


@njit(cache=True, parallel=True, error_model="numpy")
def _fused_trials(values, flags, eps, deps, geo, p, sets, mode, volume0, resp, out, oflags, sig, ok):
    """Every Gauss point's REV trial of ``deps`` (B, 3) in one pass over its cells, the points
    in parallel: the compiled trial (:func:`hmodel.loading.compiled.trial`, the operations of
    ``Rev.step`` in its order) into ``out``/``oflags``/``sig``; ``ok[b]`` False where a cell
    increment failed."""
    for b in prange(values.shape[0]):
        k = sets[b]
        ok[b] = trial(values[b], eps[b], deps[b], geo[k], p[k], mode, volume0[k], out[b], oflags[b],
                      sig[b], resp[b])


@njit(cache=True, parallel=True, error_model="numpy")
def _fused_tangents(values, eps, deps, geo, p, sets, mode, volume0, sig, D, ok):
    """The exact tangent ``D`` (B, 3, 3) of :func:`_fused_trials` at ``deps`` whose stresses
    are ``sig`` (:func:`hmodel.loading.compiled.closed_form_tangent`: the closed-form cells'
    own Jacobians in the regime each takes, one pass over the cells), the points in parallel."""
    for b in prange(values.shape[0]):
        k = sets[b]
        ok[b] = closed_form_tangent(values[b], eps[b], deps[b], geo[k], p[k], mode, volume0[k],
                                    sig[b], D[b])


class Trial:
    """Response of every Gauss point to strain increments ``deps`` (B, 3): stress (B, 3),
    tangent (B, 3, 3) and the REV state (None for laws without one).

    The tangent may be given as ``tangent()``, computed on first use of :attr:`D`: Newton
    needs it only at the trials it corrects from, not at the line search's rejected ones
    nor at the converged one."""

    def __init__(self, deps: np.ndarray, sig: np.ndarray, D: np.ndarray | None = None,
                 state: RevState | None = None, tangent=None):
        self.deps, self.sig, self.state = deps, sig, state
        self._D, self._tangent = D, tangent

    @property
    def D(self) -> np.ndarray:
        if self._D is None:
            self._D = self._tangent()
            self._tangent = None
        return self._D


class HModelMaterial:
    """Every Gauss point a material point of one batched :class:`~hmodel.rev.Rev`.

    Parameters
    ----------
    rev : Rev
        Its parameter sets (one, or one per zone: an imperfection is a zone of other parameters).
    sets : ndarray (B,) int
        Each Gauss point's parameter set.
    p0 : float
        Isotropic consolidation pressure [Pa] (:func:`hmodel.loading.consolidate`, each set once:
        all points of a set start in the same state).
    """

    def __init__(self, rev: Rev, sets: np.ndarray, p0: float, step=None):
        self.rev = rev
        #: ``step(rev, state, deps) -> state``: where the batched REV call runs (this process,
        #: or a Dask cluster: :class:`DaskStep`)
        self.step = step or (lambda rev, state, deps: rev.step(state, deps))
        sets = np.asarray(sets, np.int64)
        if sets.min() < 0 or sets.max() >= rev.n_sets:
            raise InputError(f"Gauss-point parameter sets must lie in [0, {rev.n_sets})")
        start = consolidate(rev, [p0], state=rev.initial(rev.n_sets))
        self.state = start.select(sets if rev.n_sets > 1 else np.zeros(len(sets), np.int64))
        self.fd_step = max(FD_STEP, 10 * float(rev.solver.stress_rtol))
        #: the compiled kernel's inputs where the cells' law has exact tangents (the closed
        #: form's) and the REV runs here (2D REV; a Dask step, a learned law or a cell solver
        #: without a compiled increment takes four calls)
        self._inputs = (batch_inputs(rev) if step is None and rev.kernel is not None
                        and rev.kernel.exact_tangent and rev.n_components == 3 else None)

    @property
    def n_points(self) -> int:
        return self.state.n_points

    @property
    def sig(self) -> np.ndarray:
        return self.state.sig

    def trial(self, deps: np.ndarray) -> Trial:
        """Stress after ``deps`` (B, 3) from the committed state, and its tangent when first
        asked for (:class:`Trial`).

        With the closed form's compiled increment, fused kernels: each point's increment
        (:func:`_fused_trials`: the stresses and states of ``Rev.step``, the same operations in
        the same order), later its exact tangent (:func:`_fused_tangents`), each one pass over
        its cells, the points in parallel. A point whose cell increment fails sends the batch
        through :meth:`trial_calls`, whose REV call raises the solver's error."""
        if self._inputs is None:
            return self.trial_calls(deps)
        st = self.state
        values = np.ascontiguousarray(st.cells.values, dtype=float)
        flags = np.ascontiguousarray(st.flags.flags)
        eps = np.ascontiguousarray(st.eps, dtype=float)
        deps = np.ascontiguousarray(deps, dtype=float)
        # the closed form's cells need no per-cell responses (a learned cell's would)
        sets = st.set_index.astype(np.int64)
        common = (values, flags, eps, deps, *self._inputs, sets, self.rev.mode, self.rev.volumes0,
                  np.empty((*values.shape[:2], 0)))
        out, oflags = np.empty_like(values), np.empty_like(flags)
        sig = np.empty((len(deps), 3))
        ok = np.empty(len(deps), np.bool_)
        _fused_trials(*common, out, oflags, sig, ok)
        if not ok.all() or not np.isfinite(sig).all():
            return self.trial_calls(deps)

        def tangent():
            D = np.empty((len(deps), 3, 3))
            _fused_tangents(values, eps, deps, *self._inputs, sets, self.rev.mode, self.rev.volumes0,
                            sig, D, ok)
            return D if ok.all() and np.isfinite(D).all() else self._fd_tangent(st, deps, sig)
        return Trial(deps, sig, None, RevState(CellState(out), CellFlags(oflags), st.eps + deps, sig, st.sets),
                     tangent)

    def trial_calls(self, deps: np.ndarray) -> Trial:
        """:meth:`trial` as batched REV calls of B points (the increment, and for the tangent
        its three perturbations), for any cell solver and wherever ``step`` runs.

        Calls of the same committed state rather than one call of it tiled four times: a
        surrogate keeps its network's outputs for the last states it saw, so the perturbations
        (and every later Newton iterate of the load step) reuse the first call's inference,
        where a tiled state would send every cell through the network four times."""
        st = self.state
        out = self.step(self.rev, st, deps)
        return Trial(deps, out.sig, None, out, lambda: self._fd_tangent(st, deps, out.sig))

    def _fd_tangent(self, state: RevState, deps: np.ndarray, sig: np.ndarray) -> np.ndarray:
        """Forward differences (B, 3, 3) of the stress ``sig`` of ``deps`` from ``state``."""
        h = self.fd_step
        D = np.empty((len(deps), 3, 3))
        for j in range(3):
            d = deps.copy()
            d[:, j] += h
            D[:, :, j] = (self.step(self.rev, state, d).sig - sig) / h
        return D

    def commit(self, trial: Trial) -> None:
        self.state = trial.state

    def checkpoint(self) -> RevState:
        return self.state

    def restore(self, state: RevState) -> None:
        self.state = state

    def fractions(self) -> dict[str, np.ndarray]:
        """Fractions of sliding and open cells per Gauss point (B,)."""
        return self.state.fractions()


def _arrays(state: RevState) -> tuple:
    # plain arrays travel to the workers (the state's cell containers do not pickle)
    return state.cells.values, state.flags.flags, state.eps, state.sig, state.sets


def _state(values, flags, eps, sig, sets) -> RevState:
    return RevState(CellState(values), CellFlags(flags), eps, sig, sets)


def _step_chunk(rev: Rev, arrays: tuple, deps: np.ndarray) -> tuple:
    return _arrays(rev.step(_state(*arrays), deps))


def concatenate(parts: list[tuple]) -> RevState:
    """Material points of several states' arrays (:func:`_arrays`), in order, as one state."""
    sets = None if parts[0][4] is None else np.concatenate([p[4] for p in parts])
    return _state(*(np.concatenate([p[i] for p in parts]) for i in range(4)), sets)


class DaskStep:
    """The batched REV call split into one contiguous chunk of Gauss points per worker of a
    Dask cluster (``scheduler``: its address, as for ``hmodel data generate --scheduler``).
    Every material point's update is independent of the others, so the states are those of a
    local call; what is worth sending away is an expensive cell solver (DEM cells)."""

    def __init__(self, scheduler: str, rev: Rev):
        try:
            from distributed import Client
        except ImportError:
            raise InputError("--scheduler needs Dask: pip install 'hmodel[dask]'") from None
        try:
            self.client = Client(scheduler, timeout="10s", set_as_default=False)
        except (OSError, TimeoutError) as e:
            raise InputError(f"cannot reach the Dask scheduler at {scheduler!r}: {e}") from None
        self.n = max(1, len(self.client.scheduler_info().get("workers", {})))
        self.rev = self.client.scatter(rev, broadcast=True)

    def __call__(self, rev: Rev, state: RevState, deps: np.ndarray) -> RevState:
        bounds = np.linspace(0, state.n_points, self.n + 1).astype(int)
        futures = [self.client.submit(_step_chunk, self.rev, _arrays(state.select(slice(a, b))), deps[a:b],
                                      pure=False)
                   for a, b in zip(bounds[:-1], bounds[1:]) if b > a]
        return concatenate(self.client.gather(futures))

    def close(self) -> None:
        self.client.close()

