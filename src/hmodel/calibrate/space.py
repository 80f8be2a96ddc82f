"""The parameters a calibration searches, their bounds and the unit box the optimizers see."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..params import ANGLE_PARAMS, Params

#: Default search range of each fittable parameter, in the CLI's units (angles in degrees),
#: wide enough for real materials; kn is searched on a log scale.
DEFAULT_BOUNDS = {
    "kn": (1e6, 1e11), "kt_kn": (0.05, 2.0), "phi_g": (5.0, 60.0), "alpha0": (31.0, 89.0),
    "alpha_omega": (0.0, 0.9), "beta_omega": (0.0, 180.0), "alpha0_spread": (0.0, 0.95),
    "shear_modulus": (1e7, 1e12), "poisson": (0.0, 0.45),
}
FITTABLE = tuple(DEFAULT_BOUNDS)
#: Searched on a log scale (a stiffness spans orders of magnitude).
LOG = ("kn", "shear_modulus")
#: A fitted value within this fraction of its search range (in the unit box: of the decades of
#: kn) of a bound has ended on it: the data pull it there, and the best fit may lie beyond.
AT_BOUND = 0.02
#: Where each parameter is valid (``Params.validate``), in the CLI's units: (low, high, open?).
_VALID = {"kn": (0.0, math.inf, True), "kt_kn": (0.0, math.inf, True), "phi_g": (0.0, 90.0, True),
          "alpha0": (30.0, 90.0, True), "alpha_omega": (0.0, 1.0, False),
          "beta_omega": (-math.inf, math.inf, False),
          # [0, 1) in Params: a search reaching 1 would ask for a cell at 30° or 90°
          "alpha0_spread": (0.0, 0.99, False),
          "shear_modulus": (0.0, math.inf, True), "poisson": (0.0, 0.5, False)}


@dataclass(frozen=True)
class Space:
    """Fitted parameters ``names`` within ``bounds`` (CLI units), the others fixed in ``base``.

    The optimizers work in the unit box z ∈ [0, 1]^n: z_j maps linearly onto the bounds of
    parameter j, or onto their logarithms for kn.
    """

    names: tuple[str, ...]
    bounds: tuple[tuple[float, float], ...]
    base: Params

    @classmethod
    def make(cls, names, bounds: dict | None = None, base: Params | None = None,
             domain: dict | None = None) -> Space:
        """The space of ``names`` within ``bounds`` (CLI units; default :data:`DEFAULT_BOUNDS`),
        the others fixed in ``base``. ``domain``: a cell solver's training domain
        (:func:`training_domain`, Params units: angles in radians; None: any material), which
        the default bounds of a fitted parameter become (where it is narrower than them), which
        given bounds must stay within, and in which ``base``'s fixed parameters must lie."""
        names = tuple(names)
        if not names:
            raise InputError("give at least one parameter to fit (--fit)")
        if len(set(names)) != len(names):
            raise InputError(f"a parameter is named twice in --fit: {', '.join(names)}")
        for n in names:
            if n not in FITTABLE:
                raise InputError(f"cannot fit {n!r} (fittable: {', '.join(FITTABLE)})")
        bounds = dict(bounds or {})
        for n in bounds:
            if n not in names:
                raise InputError(f"--bounds names {n!r}, which is not fitted (--fit)")
        base = base or Params()
        trained = _domain_cli(domain)
        for n, (dlo, dhi) in trained.items():
            v = getattr(base, n)
            v = math.degrees(v) if n in ANGLE_PARAMS else v
            if n not in names and not dlo <= v <= dhi:
                raise InputError(f"{n} = {v:g} (fixed) lies outside the model's training domain "
                                 f"({_span(n, dlo, dhi)}): fit it (--fit) or give a value inside")
        out = []
        for n in names:
            lo, hi = (float(b) for b in bounds.get(n, _default(n, trained)))
            vlo, vhi, open_ = _VALID[n]
            if not (math.isfinite(lo) and math.isfinite(hi)) or not lo < hi:
                raise InputError(f"bounds of {n} must be finite with low < high, got {lo:g}:{hi:g}")
            if (lo <= vlo or hi >= vhi) if open_ else (lo < vlo or hi > vhi):
                raise InputError(f"bounds of {n} ({lo:g}:{hi:g}) leave its valid range "
                                 f"{'(' if open_ else '['}{vlo:g}, {vhi:g}{')' if open_ else ']'}")
            if n in LOG and lo <= 0:
                raise InputError(f"bounds of {n} must be positive (log scale), got {lo:g}:{hi:g}")
            if n in trained and not trained[n][0] <= lo < hi <= trained[n][1]:
                raise InputError(f"--bounds {n}={lo:g}:{hi:g} reaches outside the model's training "
                                 f"domain ({_span(n, *trained[n])})")
            out.append((lo, hi))
        return cls(names, tuple(out), base)

    @property
    def n(self) -> int:
        return len(self.names)

    def values(self, z: np.ndarray) -> np.ndarray:
        """Parameter values (..., n) in CLI units of unit-box points z (..., n)."""
        z = np.asarray(z, float)
        out = np.empty_like(z)
        for j, (name, (lo, hi)) in enumerate(zip(self.names, self.bounds)):
            if name in LOG:
                out[..., j] = lo * (hi / lo) ** z[..., j]
            else:
                out[..., j] = lo + (hi - lo) * z[..., j]
        return out

    def unit(self, values: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`values`."""
        v = np.asarray(values, float)
        out = np.empty_like(v)
        for j, (name, (lo, hi)) in enumerate(zip(self.names, self.bounds)):
            out[..., j] = (np.log(v[..., j] / lo) / np.log(hi / lo) if name in LOG
                           else (v[..., j] - lo) / (hi - lo))
        return out

    def dvalues_dz(self, z: np.ndarray) -> np.ndarray:
        """d value / d z of each parameter at z (n,): the chain rule for standard errors."""
        v = self.values(z)
        return np.array([v[j] * math.log(hi / lo) if name in LOG else hi - lo
                         for j, (name, (lo, hi)) in enumerate(zip(self.names, self.bounds))])

    def params(self, z: np.ndarray) -> list[Params]:
        """One Params per row of z (k, n): the base with the fitted values (angles converted)."""
        sets = []
        for row in np.atleast_2d(self.values(z)):
            changes = {n: math.radians(v) if n in ANGLE_PARAMS else float(v)
                       for n, v in zip(self.names, row)}
            sets.append(self.base.with_(**changes))
        return sets

    def as_dict(self, values: np.ndarray) -> dict[str, float]:
        """The fitted values by name, CLI units."""
        return {n: float(v) for n, v in zip(self.names, values)}

    def bound(self, name: str, side: str) -> float:
        """The ``"lower"`` or ``"upper"`` bound of fitted parameter ``name`` (CLI units)."""
        lo, hi = self.bounds[self.names.index(name)]
        return lo if side == "lower" else hi

    def at_bound(self, z: np.ndarray) -> dict[str, str]:
        """The parameters of unit-box point z (n,) that lie on a bound (within :data:`AT_BOUND`
        of the range), by name: ``"lower"`` or ``"upper"``."""
        out = {}
        for name, zj in zip(self.names, np.asarray(z, float)):
            if zj <= AT_BOUND:
                out[name] = "lower"
            elif zj >= 1.0 - AT_BOUND:
                out[name] = "upper"
        return out


def training_domain(solver) -> dict | None:
    """The training domain (Params units) of a cell solver: its own (a family surrogate's
    ``domain``) or, for the 3D model's bi-hexagon, that of the 2D cell solver stepping its
    hexagons, which sees the material's parameters as they are; None: any material."""
    return None if solver is None else solver.domain


def _default(name: str, trained: dict[str, tuple[float, float]]) -> tuple[float, float]:
    """The default search range of ``name``: :data:`DEFAULT_BOUNDS`, within the training
    domain where one is given (a network is not asked outside the materials it learned)."""
    lo, hi = DEFAULT_BOUNDS[name]
    if name not in trained:
        return lo, hi
    dlo, dhi = trained[name]
    return max(lo, dlo), min(hi, dhi)


def _domain_cli(domain: dict | None) -> dict[str, tuple[float, float]]:
    """A solver's training domain (Params units) in the CLI's units, fittable parameters only."""
    out = {}
    for n, (lo, hi) in (domain or {}).items():
        if n in FITTABLE:
            out[n] = ((math.degrees(lo), math.degrees(hi)) if n in ANGLE_PARAMS
                      else (float(lo), float(hi)))
    return out


def _span(name: str, lo: float, hi: float) -> str:
    """``10–45°``, ``0.2–1``: a range as the error messages show it."""
    return f"{lo:.4g}–{hi:.4g}{'°' if name in ANGLE_PARAMS else ''}"
