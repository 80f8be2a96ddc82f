"""The H-model's predictions of a set of tests, for many parameter sets in one batched call."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..cell import CellSolver
from ..errors import InputError, SolverError
from ..params import Params
from ..rev import Sphere
from ..variants import ModelVariant, get_variant
from .data import Test
from .kinds import Kind, dimension

#: Consolidation increments of a calibration's runs: the last one is solved so that p = p0
#: exactly, and 10 times the loading paths' default changes q by 3e-7 of its peak and εv by
#: 3e-9 on drained tests to 3 % (closed form, 100 and 400 kPa), for a tenth of the steps.
ISO_STEP = 1e-4


@dataclass(frozen=True)
class Prediction:
    """Model curves of every test for K parameter sets, at the tests' own axial strains.

    ``q[t]`` and ``eps_v[t]`` are (K, n_t) for test t (NaN rows where the set failed);
    ``failed`` (K,) holds the reason of each failed set, or "".
    """

    q: list[np.ndarray]
    eps_v: list[np.ndarray]
    failed: list[str]

    @property
    def ok(self) -> np.ndarray:
        return np.array([not f for f in self.failed])


@dataclass(frozen=True)
class Model:
    """Runs the tests' loadings with the H-model: each test's kind and p0, sheared to its
    largest axial strain in increments of ``step`` after consolidation in isotropic increments
    of ``iso_step``, with cell solver ``solver`` (None: the closed form) and, for the 3D
    model's triaxial kinds, the directions of ``sphere`` (None: ``Sphere()``).

    One call of :meth:`predict` makes one engine run per kind of test (drained, undrained, ...)
    for all K parameter sets and all tests of that kind: K × (number of tests) material points,
    each with its own parameter set. A set whose run fails is reported, never fatal: a point
    whose Newton fails is dropped by the engine while the others go on (``drop_failed``); a
    cell solver that refuses the whole batch (e.g. a surrogate outside its training domain)
    has the batch bisected down to the failing sets. The tests must all be of one dimension,
    which is the model's (2D kinds with a 3D cell solver or a sphere are refused).
    """

    tests: tuple[Test, ...]
    solver: CellSolver | None = None
    step: float = 1e-3
    iso_step: float = ISO_STEP
    sphere: Sphere | None = None
    variant: ModelVariant = get_variant(None)
    e_ref: float | None = None

    def __post_init__(self) -> None:
        if self.variant.uses_e0:
            missing = [t.name for t in self.tests if t.e0 is None]
            if missing:
                raise InputError(f"model {self.variant.name} sets each test's initial state from its void ratio: "
                                 f"test {missing[0]} has no e0 (give KIND:P0:FILE:e0=VALUE)")
            if self.e_ref is None:
                object.__setattr__(self, "e_ref", reference_void_ratio(self.tests))
        if self.dim == 2 and self.sphere is not None:
            raise InputError("a sphere of directions (--order, --azimuths, --fabric) is the 3D "
                             "model's: the tests are 2D biaxial ones")
        if self.dim == 2 and self.solver is not None and self.solver.n_lengths == 3:
            raise InputError(f"cell solver {self.solver.name} is a 3D cell: the tests are 2D "
                             "biaxial ones (give triaxial-... kinds to calibrate the 3D model)")

    @property
    def dim(self) -> int:
        """The model's dimension: the tests' (2 or 3)."""
        return dimension([t.kind for t in self.tests])

    def predict(self, sets: Sequence[Params]) -> Prediction:
        K = len(sets)
        q = [np.full((K, len(t.eps11)), np.nan) for t in self.tests]
        ev = [np.full((K, len(t.eps11)), np.nan) for t in self.tests]
        failed = [""] * K
        for kind in Kind:
            idx = [i for i, t in enumerate(self.tests) if t.kind is kind]
            if idx:
                self._run(kind, idx, list(range(K)), sets, q, ev, failed)
        return Prediction(q, ev, failed)

    def _run(self, kind: Kind, idx, which, sets, q, ev, failed) -> None:
        """The tests ``idx`` of one kind for the parameter sets ``which``; on a failure, each
        half of the sets again, down to single sets."""
        tests = [self.tests[i] for i in idx]
        batch, kept = [], []
        for k in which:  # a set with no initial state for a test (beyond the loosest cell) fails alone
            try:
                batch += [self.variant.initial_params(sets[k], self.dim, t.e0, self.e_ref) for t in tests]
                kept.append(k)
            except InputError as e:
                failed[k] = str(e)[:300]
        which = kept
        if not which:
            return
        p0 = [t.p0 for _ in which for t in tests]
        strain = max(float(t.strain[-1]) for t in tests)
        try:
            res = kind.run(batch, p0, strain, solver=self.solver, sphere=self.sphere,
                           step=self.step, iso_step=self.iso_step)
        except SolverError as e:  # the whole batch refused (a cell solver's error): bisect
            why = " ".join(str(e).split())[:300]
            if len(which) == 1:
                failed[which[0]] = why
                return
            half = len(which) // 2
            self._run(kind, idx, which[:half], sets, q, ev, failed)
            self._run(kind, idx, which[half:], sets, q, ev, failed)
            return
        dropped = res.meta["failed"]
        for b, why in dropped.items():
            failed[which[b // len(tests)]] = why[:300]
        for b in range(len(batch)):
            k, j = which[b // len(tests)], b % len(tests)
            if failed[k]:
                continue
            q[idx[j]][k], ev[idx[j]][k] = curves_at(res, b, tests[j])


def curves_at(res, b: int, test: Test, dropped: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """q and εv since consolidation of material point ``b`` of an engine result ``res`` (a
    test's run), at ``test``'s axial strains. A point ``dropped`` where its Newton failed keeps
    its rows up to there: NaN beyond the last strain it reached."""
    point, stage = res["point"], res["stage"]
    mine = point == b
    cons = np.flatnonzero(mine & (stage == "consolidation"))
    if not len(cons):
        return np.full(len(test.eps11), np.nan), np.full(len(test.eps11), np.nan)
    cons = cons[-1]
    shear = mine & (stage == "shear")
    # the axial strain's magnitude since consolidation (increasing in extension too)
    e = test.kind.sign * np.concatenate([[0.0], res["eps11"][shear] - res["eps11"][cons]])
    q = np.interp(test.strain, e, np.concatenate([[res["q"][cons]], res["q"][shear]]))
    ev = np.interp(test.strain, e, np.concatenate([[0.0], res["eps_v"][shear] - res["eps_v"][cons]]))
    if dropped:
        beyond = test.strain > e[-1]
        q[beyond] = ev[beyond] = np.nan
    return q, ev


def reference_void_ratio(tests: Sequence[Test]) -> float:
    """The void ratio at which a calibration's α0 is given: the mean e0 of its tests."""
    return float(np.mean([t.e0 for t in tests]))


def residuals(tests: Sequence[Test], pred: Prediction, weighted: bool = True) -> np.ndarray:
    """Scaled residuals (K, m) of every parameter set: per test, (q_model − q) / peak |q| and, for
    drained tests with εv, (εv_model − εv) / range of εv; with ``weighted``, each test's
    residuals divided by the square root of its rows, so that every test weighs alike whatever
    its sampling. NaN rows where the set failed."""
    parts = []
    for t, q, ev in zip(tests, pred.q, pred.eps_v):
        w = 1.0 / math.sqrt(len(t.eps11)) if weighted else 1.0
        parts.append(w * (q - t.q) / t.q_scale)
        if has_eps_v(t):
            parts.append(w * (ev - t.eps_v) / t.eps_v_scale)
    return np.concatenate(parts, axis=1)


def has_eps_v(test: Test) -> bool:
    """Whether a test's εv enters the fit (drained tests that measured it; an undrained test's
    εv is zero by its definition)."""
    return test.eps_v is not None and not test.kind.undrained


def eps_v_scales(tests: Sequence[Test]) -> np.ndarray:
    """The scale of each εv residual of :func:`residuals` (its test's range of εv), in order."""
    return np.concatenate([np.full(len(t.eps11), t.eps_v_scale) for t in tests if has_eps_v(t)]
                          or [np.zeros(0)])


def residual_kinds(tests: Sequence[Test]) -> np.ndarray:
    """Which residual of :func:`residuals` is a q (True) or an εv (False) one, (m,)."""
    parts = []
    for t in tests:
        parts.append(np.ones(len(t.eps11), bool))
        if has_eps_v(t):
            parts.append(np.zeros(len(t.eps11), bool))
    return np.concatenate(parts)
