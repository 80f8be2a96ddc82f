"""Least-squares calibration: multi-start trust-region reflective fits with batched Jacobians."""

from __future__ import annotations

import dataclasses
import math
import re
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import qmc

from ..cell import CellSolver
from ..errors import InputError, SolverError
from ..loading.lab_tests import default_radial
from ..params import Params
from ..rev import Sphere
from ..rev.model3d import check_3d_params, params_3d
from ..variants import ModelVariant, get_variant
from ..workers import run_tasks
from .bayes import Noise, Posterior, estimate_noise, sample
from .data import Test
from .kinds import dimension
from .model import ISO_STEP, Model, Prediction, residuals
from .space import Space, training_domain

#: Scaled residual given to a parameter set whose run failed (least_squares needs finite ones):
#: far above any fit, so the optimizer steps back.
FAILED_RESIDUAL = 1e3
#: Forward-difference step of the Jacobian in the unit box (above the Newton tolerance's noise,
#: below the scale of the curves' features).
JAC_STEP = 1e-3
#: A singular value of the unit-box Jacobian below this fraction of the largest marks a
#: direction the data do not constrain; the parameters that make up that direction are flagged.
IDENTIFIABLE = 1e-3

#: The 3D model's rule (Lebedev order, azimuths) of the multi-start search, whose best point is
#: then refined at the model's own rule (:func:`fit`): a batched evaluation runs about 8 times
#: faster than at the default rule (order 23, 6 azimuths), and on drained, undrained and
#: extension triaxial tests its q departs from a fine rule's by up to 4.2 % of peak q instead
#: of 0.5 % (benchmarks/calibration/calibrate3d.py measures both).
SEARCH_RULE = (17, 2)

METHODS = ("least-squares", "bayes")
#: Posterior samples whose curves make the 90 % posterior predictive band (one batched call).
BAND_SAMPLES = 64


@dataclass
class Calibration:
    """The result of :func:`fit` (values in the CLI's units: angles in degrees)."""

    method: str
    space: Space
    tests: tuple[Test, ...]
    z: np.ndarray
    cost: float
    #: standard errors (CLI units); NaN, undefined, for a parameter the tests do not identify
    stderr: dict[str, float]
    correlation: np.ndarray
    condition: float
    unidentified: list[str]
    starts: list[dict]
    evaluations: int
    failures: list[dict]
    wall_s: float
    prediction: Prediction = field(repr=False)
    posterior: Posterior | None = field(default=None, repr=False)
    #: per test, (5 %, 95 %) quantiles of the posterior's curves (q and εv), each (2, n_t)
    band: list[tuple[np.ndarray, np.ndarray]] | None = field(default=None, repr=False)
    #: the 3D model's directions (triaxial kinds); None for the 2D model
    sphere: Sphere | None = None
    #: the coarser directions of the 3D multi-start search and the refinement of its best point
    #: at ``sphere`` (:func:`fit`); None when the search ran on ``sphere`` itself
    search: dict | None = None
    #: the variant of the H-model fitted, and the void ratio at which its α0 is given (None
    #: where the variant does not use e0)
    variant: ModelVariant = field(default_factory=lambda: get_variant(None))
    e_ref: float | None = None
    #: the model's increments and cell solver (None: the closed form), to run it again as fitted
    step: float = 1e-3
    iso_step: float = ISO_STEP
    solver: str | None = None
    #: how the drained triaxial tests held their sides (:func:`~hmodel.loading.run_triaxial`;
    #: None for 2D tests)
    radial: str | None = None

    @property
    def fitted(self) -> dict[str, float]:
        return self.space.as_dict(self.space.values(self.z))

    @property
    def params(self) -> Params:
        return self.space.params(self.z[None])[0]

    @property
    def at_bound(self) -> dict[str, str]:
        """The fitted parameters that ended on a bound of their search range: ``"lower"`` or
        ``"upper"`` by name (:meth:`Space.at_bound`)."""
        return self.space.at_bound(self.z)

    def failure_reasons(self, top: int = 2) -> list[tuple[int, str]]:
        """The ``top`` most common reasons the failed parameter sets failed, as (count, the
        first such message); messages that differ only in their numbers (the parameter values
        they name) count as one reason."""
        groups = Counter(_reason_key(f["error"]) for f in self.failures)
        first = {}
        for f in self.failures:
            first.setdefault(_reason_key(f["error"]), f["error"])
        return [(n, first[key]) for key, n in groups.most_common(top)]

    def to_dict(self) -> dict:
        """The ``calibration.json`` record."""
        fitted = self.fitted
        return {
            "method": self.method,
            "params": self.params.to_dict(),
            "fit": list(self.space.names),
            "fitted": fitted,
            "bounds": {n: list(b) for n, b in zip(self.space.names, self.space.bounds)},
            # null where undefined (a parameter the tests do not identify)
            "stderr": {n: (v if math.isfinite(v) else None) for n, v in self.stderr.items()},
            "correlation": {a: {b: float(self.correlation[i, j]) for j, b in enumerate(self.space.names)}
                            for i, a in enumerate(self.space.names)},
            "condition_number": self.condition,
            "unidentified": self.unidentified,
            "at_bound": {n: {"side": side, "bound": self.space.bound(n, side)} for n, side in self.at_bound.items()},
            "objective": self.cost,
            "starts": self.starts,
            "evaluations": self.evaluations,
            "failures": self.failures,
            "failure_reasons": [{"count": n, "reason": why} for n, why in self.failure_reasons(top=5)],
            "wall_s": self.wall_s,
            "tests": [{"name": t.name, "kind": t.kind, "p0": t.p0, "rows": len(t.eps11), "e0": t.e0}
                      for t in self.tests],
            # what hmodel.calibrate.CalibratedModel needs to run the fitted model again (angles in radians)
            "model": {"variant": self.variant.name, "e_ref": self.e_ref, "dim": self.tests[0].kind.dim,
                      "step": self.step, "iso_step": self.iso_step, "solver": self.solver or "closed-form",
                      "params_rad": self.params.to_dict(degrees=False),
                      **({"radial": self.radial} if self.radial is not None else {})},
            **({"sphere": _sphere_record(self.sphere)} if self.sphere is not None else {}),
            **({"search": self.search} if self.search is not None else {}),
            **({"posterior": self.posterior.summary, "sampling": self.posterior.to_dict()}
               if self.posterior is not None else {}),
        }


class _Objective:
    """Residuals of unit-box points, evaluated in batches; counts evaluations and failures and
    remembers the last point (least_squares asks for the Jacobian where it just evaluated)."""

    def __init__(self, model: Model, space: Space):
        self.model, self.space = model, space
        self.evaluations, self.failures = 0, []
        self._last: tuple[np.ndarray, np.ndarray] | None = None

    def use(self, model: Model) -> None:
        """Evaluate with ``model`` from now on (the refinement after a coarser search)."""
        self.model, self._last = model, None

    def batch(self, z: np.ndarray) -> tuple[np.ndarray, Prediction]:
        z = np.clip(np.atleast_2d(z), 0.0, 1.0)
        pred = self.model.predict(self.space.params(z))
        r = residuals(self.model.tests, pred)
        self.count(z, pred.failed)
        r[~pred.ok] = FAILED_RESIDUAL
        return r, pred

    def count(self, z: np.ndarray, failed: list[str]) -> None:
        """Counts the parameter sets evaluated and lists the failed ones."""
        self.evaluations += len(z)
        for row, why in zip(z, failed):
            if why:
                self.failures.append({"params": self.space.as_dict(self.space.values(row)), "error": why})

    def fun(self, z: np.ndarray) -> np.ndarray:
        r, _ = self.batch(z)
        self._last = (np.array(z, float), r[0])
        return r[0]

    def jac(self, z: np.ndarray) -> np.ndarray:
        """Forward differences, every column in one batched call (backward at the upper bound)."""
        z = np.array(z, float)
        h = np.where(z + JAC_STEP <= 1.0, JAC_STEP, -JAC_STEP)
        probes = z + np.diag(h)
        if self._last is not None and np.array_equal(self._last[0], z):
            r0, r = self._last[1], self.batch(probes)[0]
        else:
            both = self.batch(np.vstack([z, probes]))[0]
            r0, r = both[0], both[1:]
        return ((r - r0) / h[:, None]).T


#: The parameters only one contact law reads (Params.contact).
_LAW_PARAMS = {"linear": ("kn", "kt_kn"), "hertz-mindlin": ("shear_modulus", "poisson")}


def _check_contact_params(names: Sequence[str], contact: str) -> None:
    """Refuse fitting a parameter the model's contact law does not read (its objective would be
    flat in it)."""
    for law, own in _LAW_PARAMS.items():
        unused = [n for n in names if n in own and law != contact]
        if unused:
            raise InputError(f"{unused[0]} is not read by {contact} contacts: fit "
                             f"{' and '.join(_LAW_PARAMS[contact])} instead (--fit)")


def fit(tests: Sequence[Test], fit: Sequence[str] = ("kn", "kt_kn", "phi_g", "alpha0"),
        bounds: dict | None = None, base: Params | None = None, method: str = "least-squares",
        solver: CellSolver | None = None, starts: int = 8, seed: int = 0, step: float = 1e-3,
        iso_step: float = ISO_STEP, max_nfev: int = 60, walkers: int = 32, steps: int = 2000,
        noise: dict | None = None, sphere: Sphere | None = None,
        search_rule: tuple[int, int] | None = SEARCH_RULE, workers: int = 1,
        progress: Callable[[float], None] | None = None, model: str | ModelVariant | None = None,
        scheduler: str | None = None, radial: str | None = None) -> Calibration:
    """Fit the parameters ``fit`` to ``tests``; the others are those of ``base``.

    ``least-squares``: :func:`scipy.optimize.least_squares` (trust-region reflective, within the
    bounds) on the scaled residuals of :func:`hmodel.calibrate.model.residuals`, from ``starts``
    points of a Latin hypercube design over the bounds (``seed``), keeping the best; kn on a log
    scale. Standard errors and correlations come from the Jacobian at the optimum
    (cov = s² (JᵀJ)⁻¹, s² the residual variance); a direction of the unit box whose singular
    value is below ``IDENTIFIABLE`` times the largest flags the parameters that make it up.

    ``bayes``: the least-squares fit, then emcee's ensemble sampler (``walkers`` × ``steps``,
    all walkers in one batched engine call per step) from a small ball around its optimum,
    uniform priors on the bounds (log-uniform for kn) and a Gaussian likelihood whose noise is
    ``noise`` (``{"q": fraction of peak q, "eps_v": strain}``) or, where not given, the RMS the
    best fit leaves; reports the posterior's mean, sd, 5 % and 95 % quantiles, the
    autocorrelation time and acceptance fraction, a warning when the chain is shorter than 50
    autocorrelation times, and the 90 % posterior predictive band of every test.

    A cell solver with a training domain (a family surrogate's ``domain``, or the 3D model's
    learned bi-hexagon's, whose hexagons a family surrogate steps) bounds the search: the default
    bounds of a fitted parameter are its domain (within the general ones), given ``bounds``
    reaching outside it and fixed parameters outside it are refused (:meth:`Space.make`).

    A parameter the tests do not identify (:data:`IDENTIFIABLE`; one on which the objective
    does not depend at all included) is listed in ``unidentified`` and its standard error is
    NaN: undefined, not zero. ``at_bound`` names the parameters that ended on a bound.

    ``model``: the variant of the H-model (:func:`hmodel.variants.get_variant`; None: the
    published one). One that uses e0 runs each test from its own void ratio, α0 being fitted at
    the reference void ratio ``e_ref``, the mean e0 of the tests (recorded in the result).
    ``scheduler``: a Dask scheduler's address, where the least-squares starts run instead of
    ``workers`` local processes (the same result).

    The tests' kinds choose the model: the 2D one for biaxial kinds, the 3D one for triaxial
    kinds, whose directions are ``sphere`` (None: ``Sphere()``), the 2D model's own parameters
    (n_theta, alpha_omega, beta_omega) then neither fitted nor given in ``base``; its ``base``
    defaults to the 3D model's parameters, ``sliding_rhs="equilibrium"`` or a learned cell's own
    (:func:`~hmodel.rev.model3d.params_3d`, as the 3D commands': with the report's λ the
    mixed-control Newton stops a 3D triaxial test near 1 % axial strain). Kinds of both
    dimensions are refused. The 3D multi-start search runs at the coarser rule ``search_rule``
    (Lebedev order, azimuths; the model's fabric) where it has fewer cells than ``sphere``, and
    its best point is then refined at ``sphere`` by one more least-squares run (the next best if
    that one fails there); everything after (uncertainty, posterior, curves) is ``sphere``'s.
    ``search_rule=None``: the search runs at ``sphere``. Ignored by the 2D model.

    ``radial``: how the 3D model's drained triaxial tests hold their sides
    (:func:`~hmodel.loading.run_triaxial`: ``free``, each lateral stress held; ``equal``, one
    radial strain; None: by the variant's parameters,
    :func:`~hmodel.loading.lab_tests.default_radial`), recorded with the model.

    ``workers``: the least-squares starts run in that many processes (each start is
    independent, so the result is the same as in one; the calibration's own batched calls
    then run on one thread each).
    """
    if method not in METHODS:
        raise InputError(f"unknown calibration method {method!r} (available: {', '.join(METHODS)})")
    tests = tuple(tests)
    if not tests:
        raise InputError("give at least one test to calibrate on (--data)")
    if not (isinstance(starts, int) and starts >= 1):
        raise InputError(f"the number of starts must be a positive integer, got {starts!r}")
    for name, value in (("step", step), ("iso_step", iso_step)):
        if not (math.isfinite(value) and value > 0):
            raise InputError(f"the model's {name} must be a positive finite strain, got {value}")
    searcher = None
    three_d = dimension([t.kind for t in tests]) == 3
    if three_d:
        check_3d_params(fit, "--fit")
        base = params_3d(solver) if base is None else base
        sphere = Sphere() if sphere is None else sphere
        searcher = _search_sphere(sphere, search_rule)
    variant = model if isinstance(model, ModelVariant) else get_variant(model)
    _check_contact_params(fit, variant.apply(base or Params()).contact)
    if radial is None and three_d:
        radial = default_radial(variant.apply(base))
    model = Model(tests, solver, step, iso_step, sphere, variant, radial=radial)
    needed = variant.default_bounds(base or Params(), model.dim, [t.e0 for t in tests], model.e_ref)
    bounds = {**{n: b for n, b in needed.items() if n in fit}, **(bounds or {})}
    # a family model's training domain bounds the search (None: any material)
    space = Space.make(fit, bounds, base, training_domain(solver))
    obj = _Objective(model if searcher is None else replace(model, sphere=searcher), space)
    t0 = time.perf_counter()
    design = qmc.LatinHypercube(space.n, seed=seed).random(starts)
    runs = []
    share = 1.0 if method == "least-squares" else 0.2  # of the progress bar
    share_search = share if searcher is None else 0.8 * share
    if not (isinstance(workers, int) and workers >= 1):
        raise InputError(f"the number of workers must be a positive integer, got {workers!r}")
    done = {}
    for i, (run, evaluations, failures) in run_tasks(
            _start, [(obj.model, space, z0, max_nfev) for z0 in design], range(starts), workers=workers,
            scheduler=scheduler):
        done[i] = run
        obj.evaluations += evaluations
        obj.failures += failures
        if progress is not None:
            progress(share_search * len(done) / starts)
    runs = [done[i] for i in range(starts)]
    best = min(runs, key=lambda r: r.cost)
    search = None
    if searcher is not None:
        best, search = _refine(obj, model, runs, searcher, max_nfev)
        if progress is not None:
            progress(share)
    m = len(best.fun)
    J = obj.jac(best.x)
    pred = obj.batch(best.x)[1]
    _check_ran(obj, pred)
    stderr, corr, cond, weak = _uncertainty(space, best.x, best.fun, J, m)
    posterior = band = None
    if method == "bayes":
        given = dict(noise or {})
        est = estimate_noise(model, space, best.x)
        posterior = sample(model, space, best.x, Noise(given.get("q", est.q), given.get("eps_v", est.eps_v)),
                           walkers, steps, seed, obj.count,
                           None if progress is None else (lambda f: progress(0.2 + 0.8 * f)))
        band = _band(model, space, posterior, seed, obj)
    return Calibration(
        method=method, space=space, tests=tests, z=best.x, cost=float(best.cost), stderr=stderr,
        correlation=corr, condition=cond, unidentified=weak,
        starts=[{"start": space.as_dict(space.values(z0)), "end": space.as_dict(space.values(r.x)),
                 "objective": float(r.cost), "evaluations": int(r.nfev), "status": int(r.status)}
                for z0, r in zip(design, runs)],
        evaluations=obj.evaluations, failures=obj.failures, wall_s=time.perf_counter() - t0,
        prediction=pred, posterior=posterior, band=band, sphere=sphere, search=search, variant=variant,
        e_ref=model.e_ref, step=step, iso_step=iso_step, solver=None if solver is None else solver.name,
        radial=radial)


def _start(model: Model, space: Space, z0: np.ndarray, max_nfev: int):
    """One least-squares start from the unit-box point ``z0``: the result, the parameter sets
    it evaluated and its failures (a task of :func:`hmodel.workers.run_tasks`)."""
    obj = _Objective(model, space)
    run = least_squares(obj.fun, z0, jac=obj.jac, bounds=(0.0, 1.0), method="trf", x_scale=1.0,
                        max_nfev=max_nfev)
    return run, obj.evaluations, obj.failures


class CalibrationFailed(SolverError):
    """No parameter set of a calibration could be run, or the best one failed: no result."""


def _check_ran(obj: _Objective, best: Prediction) -> None:
    """Refuse a calibration whose every evaluation failed, or whose best point failed (its
    objective is the failure penalty, not a fit)."""
    if obj.failures and len(obj.failures) >= obj.evaluations:
        raise CalibrationFailed(f"every one of the {obj.evaluations} parameter sets evaluated failed "
                                f"(the first: {obj.failures[0]['error']})")
    if not best.ok[0]:
        raise CalibrationFailed(f"the best parameter set failed ({len(obj.failures)} of "
                                f"{obj.evaluations} failed; the best: {best.failed[0]})")


def _search_sphere(sphere: Sphere, rule: tuple[int, int] | None) -> Sphere | None:
    """The sphere of the 3D multi-start search: ``rule``'s order and azimuths with the model's
    fabric, where it has fewer cells than the model's ``sphere`` (None: search at ``sphere``)."""
    if rule is None:
        return None
    if len(rule) != 2:
        raise InputError(f"the search rule is (Lebedev order, azimuths), got {rule!r}")
    coarse = dataclasses.replace(sphere, order=int(rule[0]), n_azimuth=int(rule[1]))
    return coarse if coarse.n_cells < sphere.n_cells else None


def _refine(obj: _Objective, model: Model, runs: list, searcher: Sphere, max_nfev: int):
    """The search's optima, best first, refined at ``model``'s rule by least squares until one
    runs there; returns that run and the record of the search and the refinement."""
    obj.use(model)
    tried = []
    for r in sorted(runs, key=lambda r: r.cost):
        if any(np.array_equal(r.x, t) for t in tried):
            continue
        tried.append(r.x)
        fine = least_squares(obj.fun, r.x, jac=obj.jac, bounds=(0.0, 1.0), method="trf",
                             x_scale=1.0, max_nfev=max_nfev)
        if not np.all(fine.fun == FAILED_RESIDUAL):  # it ran: not a failed set's penalty
            break
    space = obj.space
    return fine, {"order": searcher.order, "n_azimuth": searcher.n_azimuth,
                  "refined": {"start": space.as_dict(space.values(r.x)),
                              "end": space.as_dict(space.values(fine.x)),
                              "search_objective": float(r.cost), "objective": float(fine.cost),
                              "evaluations": int(fine.nfev), "status": int(fine.status),
                              "optima_tried": len(tried)}}


def _sphere_record(sphere: Sphere) -> dict:
    """The 3D model's directions as ``calibration.json`` records them."""
    return {"order": sphere.order, "n_azimuth": sphere.n_azimuth, "alpha_omega": sphere.alpha_omega,
            "axis": list(sphere.axis)}


def _band(model: Model, space: Space, posterior: Posterior, seed: int, obj: _Objective):
    """5 % and 95 % quantiles of the curves of posterior samples (one batched call)."""
    rng = np.random.default_rng(seed)
    pick = posterior.samples[rng.choice(len(posterior.samples), min(BAND_SAMPLES, len(posterior.samples)),
                                        replace=False)]
    z = space.unit(pick)
    pred = model.predict(space.params(z))
    obj.count(z, pred.failed)
    out = []
    for q, ev in zip(pred.q, pred.eps_v):
        q, ev = q[pred.ok], ev[pred.ok]
        out.append((np.quantile(q, [0.05, 0.95], axis=0), np.quantile(ev, [0.05, 0.95], axis=0)))
    return out


def _uncertainty(space: Space, z: np.ndarray, r: np.ndarray, J: np.ndarray, m: int):
    """Standard errors (CLI units), correlations, condition number of the unit-box Jacobian and
    the parameters the data cannot identify."""
    n = space.n
    s2 = float(r @ r) / max(m - n, 1)
    # the covariance in the unit box (columns of like scale), then by the chain rule in the
    # parameters' units (kn spans ten orders of magnitude more than the angles: inverting in
    # those units would drop its direction as round-off)
    dv = space.dvalues_dz(z)
    cov = s2 * np.linalg.pinv(J.T @ J) * np.outer(dv, dv)
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(se, se)
    corr = np.where(np.isfinite(corr), corr, 0.0)
    sv, V = np.linalg.svd(J, full_matrices=False)[1:]
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf
    weak = set()
    for k, s in enumerate(sv):
        # "<=": where the objective depends on no parameter at all, sv[0] is 0 too
        if s <= IDENTIFIABLE * sv[0]:
            weak |= {space.names[j] for j in np.flatnonzero(np.abs(V[k]) > 0.3)}
    # the pseudo-inverse gives a direction the data do not constrain zero variance: its
    # parameters' uncertainty is unbounded by the data, not zero
    return ({nm: (math.nan if nm in weak else float(v)) for nm, v in zip(space.names, se)}, corr, cond,
            [nm for nm in space.names if nm in weak])


def _reason_key(message: str) -> str:
    """A failure message without its numbers: the reason, whatever parameter values it names."""
    return re.sub(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?", "#", message)
