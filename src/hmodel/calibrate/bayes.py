"""Bayesian calibration: emcee's ensemble sampler, every walker in one batched engine call."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .model import Model, eps_v_scales, residual_kinds, residuals
from .space import Space

#: A chain shorter than this many integrated autocorrelation times gives unreliable statistics.
MIN_TAU_MULTIPLE = 50


@dataclass(frozen=True)
class Noise:
    """Standard deviations of the measurement noise: of q as a fraction of each test's peak |q|,
    of εv in strain."""

    q: float
    eps_v: float

    @classmethod
    def parse(cls, text: str) -> dict[str, float]:
        """``q=0.02,eps_v=0.001`` (the ``--noise`` option); either may be omitted."""
        out = {}
        for item in (t.strip() for t in text.split(",") if t.strip()):
            name, sep, value = item.partition("=")
            if not sep or name.strip() not in ("q", "eps_v"):
                raise InputError(f"--noise expects q=FRACTION,eps_v=STRAIN, got {text!r}")
            try:
                v = float(value)
            except ValueError:
                raise InputError(f"--noise {item!r}: not a number") from None
            if not (math.isfinite(v) and v > 0):
                raise InputError(f"--noise {item!r}: a noise level must be positive")
            out[name.strip()] = v
        return out


def estimate_noise(model: Model, space: Space, z: np.ndarray) -> Noise:
    """The noise levels the best fit leaves: RMS of its q residuals (relative to peak q) and of
    its εv residuals (strain), from the unweighted residuals at z."""
    pred = model.predict(space.params(z[None]))
    r = residuals(model.tests, pred, weighted=False)[0]
    kinds = residual_kinds(model.tests)
    q = float(np.sqrt(np.mean(r[kinds] ** 2)))
    ev_scale = eps_v_scales(model.tests)
    ev = float(np.sqrt(np.mean((r[~kinds] * ev_scale) ** 2))) if (~kinds).any() else 1.0
    return Noise(max(q, 1e-6), max(ev, 1e-9))


@dataclass
class Posterior:
    """Samples (after burn-in) and their summary, in the CLI's units."""

    samples: np.ndarray      # (S, n)
    chain: np.ndarray        # (steps, walkers, n), all of it, CLI units
    summary: dict[str, dict[str, float]]
    tau: np.ndarray          # integrated autocorrelation time per parameter [steps]
    acceptance: float
    burn: int
    noise: Noise
    warning: str

    def to_dict(self) -> dict:
        return {"summary": self.summary, "autocorrelation_time": self.tau.tolist(),
                "acceptance_fraction": self.acceptance, "burn_in": self.burn,
                "noise": {"q": self.noise.q, "eps_v": self.noise.eps_v}, "warning": self.warning}


def sample(model: Model, space: Space, start: np.ndarray, noise: Noise, walkers: int, steps: int,
           seed: int, count: Callable[[np.ndarray, list[str]], None],
           progress: Callable[[float], None] | None = None) -> Posterior:
    """emcee's affine-invariant ensemble sampler in the unit box (uniform priors on the bounds,
    log-uniform for kn), Gaussian likelihood with the given noise; walkers start in a small ball
    around ``start`` (the least-squares optimum). ``count(z, failed)`` is told every batch."""
    import emcee

    n = space.n
    if walkers < 2 * n:
        raise InputError(f"emcee needs at least 2 walkers per fitted parameter ({2 * n}), got {walkers}")
    if steps < 10:
        raise InputError(f"give at least 10 steps, got {steps}")
    kinds = residual_kinds(model.tests)
    sigma = np.where(kinds, noise.q, 0.0)
    sigma[~kinds] = noise.eps_v / eps_v_scales(model.tests)  # εv noise in the residuals' scale

    def log_prob(Z: np.ndarray) -> np.ndarray:
        Z = np.atleast_2d(Z)
        lp = np.full(len(Z), -np.inf)
        inside = np.all((Z >= 0.0) & (Z <= 1.0), axis=1)
        if inside.any():
            pred = model.predict(space.params(Z[inside]))
            r = residuals(model.tests, pred, weighted=False)
            ll = -0.5 * np.sum((r / sigma) ** 2, axis=1)
            ll[~pred.ok] = -np.inf
            lp[inside] = ll
            count(Z[inside], pred.failed)
        return lp

    rng = np.random.default_rng(seed)
    p0 = np.clip(start + 1e-3 * rng.normal(size=(walkers, n)), 1e-6, 1 - 1e-6)
    sampler = emcee.EnsembleSampler(walkers, n, log_prob, vectorize=True)
    sampler.random_state = np.random.RandomState(seed).get_state()
    for k, _ in enumerate(sampler.sample(p0, iterations=steps)):
        if progress is not None and (k + 1) % max(1, steps // 100) == 0:
            progress((k + 1) / steps)
    tau = np.asarray(sampler.get_autocorr_time(tol=0, quiet=True), float)
    burn = int(min(steps // 2, max(steps // 4, 2 * np.nanmax(tau)))) if np.all(np.isfinite(tau)) else steps // 2
    chain = space.values(sampler.get_chain())
    flat = space.values(sampler.get_chain(discard=burn, flat=True))
    summary = {name: {"mean": float(np.mean(flat[:, j])), "sd": float(np.std(flat[:, j])),
                      "q05": float(np.quantile(flat[:, j], 0.05)),
                      "q95": float(np.quantile(flat[:, j], 0.95))}
               for j, name in enumerate(space.names)}
    warning = ""
    if not np.all(np.isfinite(tau)) or steps < MIN_TAU_MULTIPLE * np.max(tau):
        warning = (f"the chain ({steps} steps) is shorter than {MIN_TAU_MULTIPLE} autocorrelation "
                   f"times (max {np.nanmax(tau):.3g} steps): the posterior statistics are unreliable")
    return Posterior(flat, chain, summary, tau, float(np.mean(sampler.acceptance_fraction)), burn,
                     noise, warning)
