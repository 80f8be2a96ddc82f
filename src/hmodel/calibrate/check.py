"""A calibrated cell model against another cell solver at the same parameters.

A least-squares or Bayesian fit with a learned cell (a surrogate) finds the parameters at which
the *network's* curves match the tests. Where the network misses the cell it learned, the
optimizer is free to settle there, and the fitted material is then the network's, not the
cell's. :func:`check_at` runs the tests again at the calibrated parameters with the cell it
learned (its teacher: the closed form, or a DEM cell) and reports, per test, how far the
calibrated model's curves lie from the teacher's: max and RMS |Δq| over the teacher's peak |q|,
and max |Δεv|.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..cell import CellSolver
from ..params import Params
from ..rev import Sphere
from ..variants import ModelVariant, get_variant
from .data import Test
from .model import ISO_STEP, Model, Prediction


def deviation(q: np.ndarray, eps_v: np.ndarray, q_ref: np.ndarray, eps_v_ref: np.ndarray) -> dict:
    """How far one curve (q, εv) lies from a reference at the same axial strains: max and RMS
    |Δq| over the reference's peak |q|, and max |Δεv| (a strain)."""
    q, eps_v, q_ref, eps_v_ref = (np.asarray(a, dtype=float) for a in (q, eps_v, q_ref, eps_v_ref))
    peak = float(np.abs(q_ref).max())
    dq = np.abs(q - q_ref)
    return {"max_dq": float(dq.max() / peak), "rms_dq": float(np.sqrt(np.mean(dq ** 2)) / peak),
            "max_deps_v": float(np.abs(eps_v - eps_v_ref).max())}


@dataclass(frozen=True)
class Check:
    """The check solver's curves at the calibrated parameters and, per test, their distance
    from the calibrated model's (:func:`deviation`); ``failed`` is the reason the check solver
    could not run them, or ""."""

    solver: str
    tests: tuple[Test, ...]
    q: list[np.ndarray] = field(repr=False)
    eps_v: list[np.ndarray] = field(repr=False)
    deviations: list[dict]
    seconds: float
    failed: str = ""

    @property
    def worst(self) -> tuple[str, float]:
        """The test of the largest max |Δq| / peak q, and that value."""
        k = int(np.argmax([d["max_dq"] for d in self.deviations]))
        return self.tests[k].name, self.deviations[k]["max_dq"]

    def to_dict(self) -> dict:
        """The ``check`` record of ``calibration.json``."""
        if self.failed:
            return {"solver": self.solver, "failed": self.failed, "seconds": self.seconds}
        return {"solver": self.solver, "seconds": self.seconds,
                "tests": {t.name: d for t, d in zip(self.tests, self.deviations)}}


def check_at(tests: Sequence[Test], params: Params, calibrated: Prediction, solver: CellSolver,
             step: float = 1e-3, iso_step: float = ISO_STEP, sphere: Sphere | None = None,
             variant: ModelVariant | None = None, e_ref: float | None = None,
             radial: str | None = None) -> Check:
    """Run ``tests`` at ``params`` with ``solver`` (the same increments, directions and model
    variant as the calibration's model) and compare the curves with ``calibrated``, the
    calibrated model's prediction at ``params`` (one parameter set)."""
    tests = tuple(tests)
    t0 = time.perf_counter()
    ref = Model(tests, solver, step, iso_step, sphere, variant or get_variant(None), e_ref,
                radial).predict([params])
    seconds = time.perf_counter() - t0
    if not ref.ok[0]:
        return Check(solver.name, tests, [], [], [], seconds, failed=ref.failed[0])
    q = [r[0] for r in ref.q]
    ev = [r[0] for r in ref.eps_v]
    devs = [deviation(cq[0], cev[0], rq, rev) for cq, cev, rq, rev in zip(calibrated.q, calibrated.eps_v, q, ev)]
    return Check(solver.name, tests, q, ev, devs, seconds)
