"""Global Newton-Raphson on the nodal displacements, and load stepping with step cutting.

A load step moves the load factor from lambda to lambda + d_lambda: the prescribed
displacements (platens, footing, walls) move by d_lambda times their full increment ``g``;
dead loads ``f_ext`` (the confining tractions) stay constant. Newton solves
f_int(u) = f_ext on the free degrees of freedom with the consistent tangent of the material
law; each iteration is one batched material call for all Gauss points. A step converges when
the residual norm on the free dofs is below ``rtol`` times the reference force (the norm of the
internal forces of the committed state, which is the confining pressure times the mesh size,
or of the step's first trial where that is larger, e.g. from an unstressed state).

Cell events. With ``sliding_rhs="report"`` a cell that starts sliding with T1 < 0 loses its
contact at once (docs/model.md), a jump of the stress. When equilibrium lies inside such a jump
no displacement meets it and Newton cycles across it. As the material-point driver does
(docs/loading.md, "Cell events"), a step whose Newton has not converged after ``event_after``
iterations, or stalls before that (:func:`_stalled`), commits its trial in which the most cells
broke (the event happens: the prescribed displacements are met, the free nodes are out of
balance) and restores equilibrium from there with no further load, at most ``max_events``
times per step.

A step that does not converge (too many iterations, a diverging residual, or a material point
that refuses its increment) is cut in half, up to ``max_cuts`` times; after a converged cut
the step grows back towards the nominal one. A step that still fails ends the run: the
caller keeps every converged step and the reason.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.sparse.linalg import splu
from skfem import Basis, condense, solve

from ..errors import HModelError
from .assembly import Operators
from .material import Trial


@dataclass(frozen=True)
class GlobalNewtonSettings:
    """Settings of the global Newton on the nodal displacements (the material points' own
    mixed-control Newton has :class:`hmodel.loading.NewtonSettings`). ``rtol``: residual tolerance relative to the reference force; ``max_iter`` per step;
    ``max_cuts``: halvings of a failing step before the run stops; ``event_after``,
    ``max_events``: the cell-event fallback; ``event_on_stall``: also take the fallback as soon
    as Newton stalls across cell events (:func:`_stalled`); ``line_search``: halvings of a
    correction that raises the residual."""

    rtol: float = 1e-8
    max_iter: int = 20
    max_cuts: int = 6
    event_after: int = 8
    max_events: int = 6
    line_search: int = 3
    event_on_stall: bool = True


@dataclass
class Problem:
    """A discretized boundary-value problem: ``basis``; the material law at its Gauss points;
    the prescribed dofs ``fixed`` and their increments per unit load factor ``g`` (N,);
    the dead loads ``f_ext`` (N,); ``b_bar``: the B-bar strain operator."""

    basis: Basis
    material: object
    fixed: np.ndarray
    g: np.ndarray
    f_ext: np.ndarray
    b_bar: bool = False  # the element's mean volumetric strain (hmodel.fem.assembly.bbar)
    free: np.ndarray = field(init=False)

    def __post_init__(self):
        mask = np.ones(self.n_dofs, bool)
        mask[self.fixed] = False
        self.free = np.flatnonzero(mask)
        #: the basis's strain operator and the assembly built on it, once per problem
        self.ops = Operators(self.basis, self.b_bar)

    # A regularized problem (hmodel.fem.regularization) adds unknowns after the displacements
    # and overrides the methods below; the global Newton only goes through them.
    @property
    def n_dofs(self) -> int:
        """Unknowns of the global Newton (here the nodal displacements)."""
        return self.basis.N

    def evaluate(self, du: np.ndarray):
        """Trial of the increment ``du`` from the committed state: (trial, internal forces,
        residual), each of the problem's unknowns."""
        trial = self.material.trial(self.ops.strain(du))
        f_int = self.ops.internal_force(trial.sig)
        return trial, f_int, f_int - self.f_ext

    def tangent(self, trial):
        """Jacobian of the residual at ``trial`` (sparse n_dofs x n_dofs)."""
        return self.ops.stiffness(trial.D)

    def reference_force(self) -> float:
        """Norm of the committed state's internal forces (the residual's scale)."""
        return float(np.linalg.norm(self.ops.internal_force(self.material.sig)))

    def commit(self, trial) -> None:
        self.material.commit(trial)

    def checkpoint(self):
        return self.material.checkpoint()

    def restore(self, saved) -> None:
        self.material.restore(saved)


@dataclass
class StepResult:
    """A converged step: displacement increment (N,), the material trial, internal forces
    (N,), the residual norms of each iteration (relative), and the load-factor increment."""

    du: np.ndarray
    trial: Trial
    f_int: np.ndarray
    residuals: list
    d_lambda: float
    event: bool = False  # an event state out of balance: commit it, then restore equilibrium

    @property
    def iterations(self) -> int:
        return len(self.residuals) - 1


class NotConverged(Exception):
    """A load step that Newton could not converge (the reason in the message)."""


def _broken(obj) -> int:
    """Number of open cells of all Gauss points of a material or trial (its ``state``: 0 for a
    law without cells, whose state is None)."""
    state = obj.state
    return 0 if state is None else int(state.flags.broken.sum())


def _evaluate(pb: Problem, du: np.ndarray):
    """Material trial and internal forces of the displacement increment ``du``."""
    return _refusable(pb.evaluate, du)


def _tangent(pb: Problem, trial):
    """The problem's tangent at ``trial``: the material's is computed when first asked for
    (:class:`hmodel.fem.material.Trial`), where a probe's cell increment may be refused."""
    return _refusable(pb.tangent, trial)


def _superlu(K, rhs: np.ndarray) -> np.ndarray:
    """SuperLU with the minimum degree ordering of K^T + K and diagonal pivots where they are
    at least a tenth of their column's largest entry: the tangents' pattern is structurally
    symmetric (a nodal stencil), and this ordering keeps its predicted fill only while the
    pivots stay on the diagonal. On the regularized tangents (16x32 and 32x64) it leaves about
    half the fill of SciPy's default (COLAMD with partial pivoting) and factors 2-4 times
    faster; the same ordering with partial pivoting doubles the fill past the peak."""
    try:
        lu = splu(K.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.1,
                  options={"SymmetricMode": True})
    except RuntimeError as e:  # "Factor is exactly singular": a mechanism, the step is cut
        raise NotConverged(f"singular tangent ({e})") from None
    return lu.solve(rhs)


def _solve(K, rhs: np.ndarray, x: np.ndarray | None, fixed: np.ndarray) -> np.ndarray:
    """Solution of K x = rhs on the free dofs, ``x`` (or zero) on the ``fixed`` ones."""
    return solve(*condense(K, rhs, x=x, D=fixed), solver=_superlu)


def _refusable(call, arg):
    """``call(arg)``, a material point's refusal (an HModelError) as :class:`NotConverged`."""
    try:
        return call(arg)
    except HModelError as e:
        why = " ".join(str(e).split())
        raise NotConverged("a material point refused its increment ("
                           + (why if len(why) < 200 else why[:200] + "...") + ")") from None


def newton_step(pb: Problem, d_lambda: float, guess: np.ndarray | None,
                settings: GlobalNewtonSettings, scale: float, events_left: int = 0) -> StepResult:
    """Solve one load step from the committed state; raises :class:`NotConverged`. With
    ``events_left``, a stalled Newton may return an event state (:class:`StepResult.event`).

    A correction that raises the residual is halved up to ``settings.line_search`` times
    (the best trial is kept): where cells change regime between iterates (sliding starts or
    stops at a kink of the response) the full correction can cycle between two states."""
    du = np.zeros(pb.n_dofs) if guess is None else guess.copy()
    du[pb.fixed] = d_lambda * pb.g[pb.fixed]
    if guess is None and d_lambda != 0:
        # no previous step to extrapolate: the committed state's tangent predicts the free
        # nodes (moving only the prescribed ones puts large strains into the boundary
        # elements, where cells may open and leave interior nodes without stiffness)
        t0, _, r0 = _evaluate(pb, np.zeros(pb.n_dofs))
        du = _solve(_tangent(pb, t0), -r0, du, pb.fixed)
    trial, f_int, r = _evaluate(pb, du)
    # an unstressed start: the forces of the prescribed motion set the scale
    scale = max(scale, float(np.linalg.norm(f_int)))
    norm = lambda r: float(np.linalg.norm(r[pb.free])) / scale  # noqa: E731
    res = norm(r)
    residuals, trials = [res], []
    broken0 = _broken(pb.material)
    for it in range(settings.max_iter + 1):
        if not np.isfinite(res):
            raise NotConverged("non-finite residual")
        if res <= settings.rtol:
            return StepResult(du, trial, f_int, residuals, d_lambda)
        if it == settings.max_iter:
            break
        if len(residuals) > 3 and res > 1e3 * residuals[0]:
            raise NotConverged(f"Newton diverged (relative residual {res:.2e})")
        trials.append((_broken(trial), du, trial, f_int, res))
        if events_left > 0 and (it == settings.event_after
                                or (settings.event_on_stall and _stalled(residuals, trials))):
            most = max(trials, key=lambda t: t[0])
            if most[0] > broken0:
                return StepResult(most[1], most[2], most[3], residuals[:trials.index(most) + 1],
                                  d_lambda, event=True)
        ddu = _solve(_tangent(pb, trial), -r, None, pb.fixed)
        best = None
        for k in range(settings.line_search + 1):
            cand = du + ddu / 2 ** k
            t2, f2, r2 = _evaluate(pb, cand)
            n2 = norm(r2)
            if best is None or n2 < best[4]:
                best = (cand, t2, f2, r2, n2)
            if n2 < res:
                break
        du, trial, f_int, r, res = best
        residuals.append(res)
    raise NotConverged(f"Newton did not converge in {settings.max_iter} iterations "
                       f"(relative residual {residuals[-1]:.2e}, last ones "
                       + ", ".join(f"{x:.1e}" for x in residuals[-3:]) + ")")


def _stalled(residuals: list, trials: list) -> bool:
    """Newton cycles across cell events: the last two corrections each reduced the residual
    less than fourfold (a converging Newton with the exact tangent gains orders of magnitude
    per iteration) while the iterates' numbers of open cells differ (cells that open and close
    again between iterates)."""
    if len(residuals) < 3:
        return False
    slow = residuals[-1] > residuals[-2] / 4 and residuals[-2] > residuals[-3] / 4
    return slow and len({t[0] for t in trials[-3:]}) > 1


@dataclass
class Stepping:
    """Outcome of :func:`run_steps`: the number of converged steps and, when the run stopped
    early, why (None: the full load was applied)."""

    n_steps: int
    stopped: str | None


def run_steps(pb: Problem, n_steps: int, on_step: Callable[[StepResult, float], None],
              settings: GlobalNewtonSettings = GlobalNewtonSettings(),
              where: Callable[[float], str] = lambda lam: f"load factor {lam:.4g}") -> Stepping:
    """Apply the load in ``n_steps`` nominal steps, cutting failing ones; ``on_step(step,
    lambda)`` after each converged step (its state committed). ``where(lambda)`` describes a
    load level for the stop message."""
    nominal = 1.0 / n_steps
    smallest = nominal / 2 ** settings.max_cuts
    lam, d_lam, done = 0.0, nominal, 0
    prev = None
    while lam < 1.0 - 1e-12:
        d_lam = min(d_lam, 1.0 - lam)
        while True:
            guess = None if prev is None else prev.du * (d_lam / prev.d_lambda)
            try:
                step = _step_with_events(pb, d_lam, guess, settings)
                break
            except NotConverged as e:
                if d_lam <= smallest * (1 + 1e-9):
                    return Stepping(done, f"step {done + 1} did not converge at {where(lam)} "
                                          f"with the step cut {settings.max_cuts} times (to "
                                          f"{d_lam / nominal:.3g} of the nominal one): {e}")
                d_lam = max(d_lam / 2, smallest)
        lam += step.d_lambda
        done += 1
        prev = step
        on_step(step, lam)
        if step.iterations <= settings.max_iter // 2:  # grow back after a cut
            d_lam = min(nominal, 2 * d_lam)
    return Stepping(done, None)


def _scale(pb: Problem) -> float:
    """Reference force: the norm of the committed state's internal forces."""
    return max(pb.reference_force(), 1e-300)


def _step_with_events(pb: Problem, d_lam: float, guess, settings: GlobalNewtonSettings) -> StepResult:
    """One load step, committed on success, with the event fallback; on failure the material
    is back in its state at the start of the step."""
    start = pb.checkpoint()
    scale = _scale(pb)
    step = newton_step(pb, d_lam, guess, settings, scale, settings.max_events)
    du, residuals = step.du, list(step.residuals)
    events = 0
    while step.event:
        events += 1
        pb.commit(step.trial)
        try:  # restore equilibrium at the reached load, from the event state
            step = newton_step(pb, 0.0, None, settings, scale, settings.max_events - events)
        except NotConverged:
            pb.restore(start)
            raise
        du = du + step.du
        residuals += step.residuals
    pb.commit(step.trial)
    return StepResult(du, step.trial, step.f_int, residuals, d_lam)
