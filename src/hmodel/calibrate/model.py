"""The H-model's predictions of a set of tests, for many parameter sets in one batched call."""

from __future__ import annotations

import inspect
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..cell import CellSolver
from ..errors import InputError, SolverError
from ..loading.lab_tests import check_radial
from ..params import Params
from ..rev import Sphere
from ..variants import ModelVariant, get_variant
from .data import Test
from .kinds import BUILTIN, OBSERVABLES, Kind, dimension

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
    model's triaxial kinds, the directions of ``sphere`` (None: ``Sphere()``) and the sides of a
    drained test held as ``radial`` says (:func:`~hmodel.loading.run_triaxial`; None: by the
    parameters, :func:`~hmodel.loading.lab_tests.default_radial`).

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
    radial: str | None = None

    def __post_init__(self) -> None:
        if self.radial is not None:
            check_radial(self.radial)
        if self.variant.uses_e0:
            missing = [t.name for t in self.tests if t.e0 is None]
            if missing:
                raise InputError(f"model {self.variant.name} sets each test's initial state from its void ratio: "
                                 f"test {missing[0]} has no e0 (give KIND:P0:FILE:e0=VALUE)")
            if self.e_ref is None:
                object.__setattr__(self, "e_ref", reference_void_ratio(self.tests))
        for t in self.tests:
            unknown = [o for o in t.kind.observables() if o not in OBSERVABLES]
            if unknown:
                raise InputError(f"test {t.name}: kind {t.kind} observes {', '.join(unknown)}, which the model "
                                 f"does not predict (it predicts {', '.join(OBSERVABLES)})")
        if self.dim == 2 and self.radial not in (None, "free"):
            raise InputError("--radial says how a drained triaxial test holds its sides: the tests are 2D "
                             "biaxial ones (one lateral strain)")
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
        for kind, idx in _by_kind(self.tests):
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
                           step=self.step, iso_step=self.iso_step,
                           # a kind of its own holds its sides as its run says
                           **({"radial": self.radial} if self.radial is not None
                              and "radial" in inspect.signature(kind.run).parameters else {}))
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


def _by_kind(tests: Sequence[Test]) -> list[tuple[Kind, list[int]]]:
    """The tests' kinds, each with the indices of its tests: the built-in kinds in the order of
    :data:`~hmodel.calibrate.kinds.BUILTIN` (a set failing in several keeps the last one's
    reason), then the others in the order they first appear. A kind is its class and name, so
    that another instance of a class runs with it and a subclass of a built-in does not."""
    groups: dict[tuple[type, str], list[int]] = {}
    for i, t in enumerate(tests):
        groups.setdefault((type(t.kind), t.kind.value), []).append(i)
    rank = {(type(k), k.value): r for r, k in enumerate(BUILTIN)}
    order = sorted(groups, key=lambda g: rank.get(g, len(rank)))  # stable: first appearance after
    return [(tests[groups[g][0]].kind, groups[g]) for g in order]


def curves_at(res, b: int, test: Test, dropped: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """q and εv since consolidation of material point ``b`` of an engine result ``res`` (a
    run of ``test``'s kind), at ``test``'s axial strains (:meth:`Kind.curves
    <hmodel.calibrate.kinds.Kind.curves>`). A point ``dropped`` where its Newton failed keeps
    its rows up to there: NaN beyond the last strain it reached."""
    return test.kind.curves(res, b, test, dropped)


def reference_void_ratio(tests: Sequence[Test]) -> float:
    """The void ratio at which a calibration's α0 is given: the mean e0 of its tests."""
    return float(np.mean([t.e0 for t in tests]))


def residuals(tests: Sequence[Test], pred: Prediction, weighted: bool = True) -> np.ndarray:
    """Scaled residuals (K, m) of every parameter set: per test, for each of its
    :func:`fitted` observables in turn, (model − measured) / the test's scale of it (q: over
    peak |q|; εv: over the range of εv); with ``weighted``, each test's residuals divided by the
    square root of its rows, so that every test weighs alike whatever its sampling. NaN rows
    where the set failed."""
    parts = []
    for j, t in enumerate(tests):
        w = 1.0 / math.sqrt(len(t.eps11)) if weighted else 1.0
        for o in fitted(t):
            parts.append(w * (getattr(pred, o)[j] - getattr(t, o)) / getattr(t, f"{o}_scale"))
    return np.concatenate(parts, axis=1)


def fitted(test: Test) -> tuple[str, ...]:
    """The observables of ``test`` that enter the fit, in the residuals' order: those its kind
    says the model must reproduce (:meth:`Kind.observables
    <hmodel.calibrate.kinds.Kind.observables>`) that the test measured. Each is the name of a
    curve of a :class:`Prediction` and of a :class:`~hmodel.calibrate.data.Test`, whose
    ``NAME_scale`` scales its residuals."""
    return tuple(o for o in test.kind.observables() if getattr(test, o) is not None)


def has_eps_v(test: Test) -> bool:
    """Whether a test's εv enters the fit (tests that measured it whose kind observes it; an
    undrained test's εv is zero by its definition)."""
    return "eps_v" in fitted(test)


def eps_v_scales(tests: Sequence[Test]) -> np.ndarray:
    """The scale of each εv residual of :func:`residuals` (its test's range of εv), in order."""
    return np.concatenate([np.full(len(t.eps11), t.eps_v_scale) for t in tests if has_eps_v(t)]
                          or [np.zeros(0)])


def residual_kinds(tests: Sequence[Test]) -> np.ndarray:
    """Which residual of :func:`residuals` is a q (True) or an εv (False) one, (m,)."""
    return np.concatenate([np.full(len(t.eps11), o == "q") for t in tests for o in fitted(t)])
