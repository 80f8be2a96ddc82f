"""Material laws at the Gauss points: the batched H-model REV, and linear elasticity (tests).

A law answers one question, the stress after a strain increment from its committed state and
the consistent tangent there, for all Gauss points at once (:meth:`trial`); :meth:`commit`
makes a trial the new committed state once the global Newton has converged. Strains, stresses
and tangents use hmodel's convention (:mod:`hmodel.fem.assembly`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..cell import CellFlags, CellState
from ..errors import InputError
from ..loading import consolidate
from ..rev import Rev, RevState

#: Finite-difference strain perturbation of the tangent. The stress of one increment is
#: piecewise smooth in the increment (a cell's regime changes at a kink); a perturbation far
#: below the load step's strain (1e-4 .. 1e-3) keeps the tangent on the trial's own branch,
#: and at stresses ~1e5 Pa and stiffnesses ~1e8 Pa it still moves the stress by ~1 Pa, nine
#: orders above round-off. A solver whose cells are converged only to a relative ``stress_rtol``
#: (DEM cells, surrogates' sub-steps) gets ten times that instead, so that its noise stays
#: far below the perturbation's response.
FD_STEP = 1e-8


@dataclass
class Trial:
    """Response of every Gauss point to strain increments ``deps`` (B, 3): stress (B, 3),
    tangent (B, 3, 3) and the REV state (None for laws without one)."""

    deps: np.ndarray
    sig: np.ndarray
    D: np.ndarray
    state: RevState | None = None


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
        self.fd_step = max(FD_STEP, 10 * float(getattr(rev.solver, "stress_rtol", 0.0)))

    @property
    def n_points(self) -> int:
        return self.state.n_points

    @property
    def sig(self) -> np.ndarray:
        return self.state.sig

    def trial(self, deps: np.ndarray) -> Trial:
        """Stress and finite-difference tangent after ``deps`` (B, 3) from the committed state:
        four batched REV calls of B points (the increment and its three perturbations).

        Four calls of the same committed state rather than one call of it tiled four times: a
        surrogate keeps its network's outputs for the last states it saw, so the perturbations
        (and every later Newton iterate of the load step) reuse the first call's inference,
        where a tiled state would send every cell through the network four times."""
        h = self.fd_step
        out = self.step(self.rev, self.state, deps)
        sig = out.sig
        D = np.empty((len(deps), 3, 3))
        for j in range(3):
            d = deps.copy()
            d[:, j] += h
            D[:, :, j] = (self.step(self.rev, self.state, d).sig - sig) / h
        return Trial(deps, sig, D, out)

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

