"""Probes from one state: small increments in many directions applied to copies of the state in
one batched call (the state itself is never changed), and the response envelopes they draw."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..loading.newton import NewtonSettings
from ..loading.probes import strain_responses, stress_responses, supports
from ..rev import Rev, RevState
from .work import second_order_work, shear_factors

#: Newton's settings for the stress probes (those of the loading paths).
SETTINGS = NewtonSettings()


def _check(n: int, magnitude: float) -> None:
    if not isinstance(n, (int, np.integer)) or n < 1:
        raise InputError(f"the number of probes must be a positive integer, got {n!r}")
    if not (math.isfinite(magnitude) and magnitude > 0):
        raise InputError(f"the probe magnitude must be positive and finite, got {magnitude!r}")


def _fibonacci(n: int) -> np.ndarray:
    """n nearly uniform unit vectors (n, 3) on the sphere: the Fibonacci (golden-angle) spiral."""
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    r = np.sqrt(1 - z * z)
    phi = math.pi * (3 - math.sqrt(5)) * k
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def _halton_sphere(n: int, dim: int) -> np.ndarray:
    """n quasi-uniform unit vectors (n, dim): points 1..n of the Halton sequence (primes 2, 3,
    5, ...; point 0 is the cube's corner) mapped to a normal sample by the inverse normal CDF,
    then normalized (a normal vector's direction is uniform on the sphere). Deterministic, for
    any n, and low-discrepancy where a seeded random sample clusters."""
    from scipy.special import ndtri
    from scipy.stats import qmc

    h = qmc.Halton(d=dim, scramble=False)
    h.fast_forward(1)
    g = ndtri(h.random(n))
    return g / np.linalg.norm(g, axis=1, keepdims=True)


def probe_directions(n: int, shear: bool = False, components: int = 3) -> np.ndarray:
    """Unit directions (n, components) with tensor norm 1, in the Voigt order of a REV of
    ``components`` components (:data:`hmodel.loading.result.COMPONENTS`).

    2D (3 components, (11, 22, 12)): a circle in the (11, 22) plane, or with ``shear`` a
    Fibonacci sphere in (11, 22, √2·12). 3D (6 components): a Fibonacci sphere in the principal
    space (11, 22, 33), the shears zero; or with ``shear`` a Halton set on the unit sphere of
    (11, 22, 33, √2·23, √2·13, √2·12) (:func:`_halton_sphere`)."""
    if components == 3 and not shear:
        t = 2 * math.pi * np.arange(n) / n
        return np.column_stack([np.cos(t), np.sin(t), np.zeros(n)])
    if components == 3:
        return _fibonacci(n) / np.sqrt(shear_factors(3))
    if components != 6:
        shear_factors(components)  # raises
    if not shear:
        return np.column_stack([_fibonacci(n), np.zeros((n, 3))])
    # Euclidean coordinates with the √2 on the shears have the tensor norm: back to components
    return _halton_sphere(n, 6) / np.sqrt(shear_factors(6))


def section_directions(n: int, components: int = 3) -> np.ndarray:
    """n unit directions (n, components) on a circle of a plane of normal components: the
    (11, 22) plane in 2D (:func:`probe_directions` without shear), the Rendulic plane of
    axisymmetric increments in 3D, (cos t, sin t/√2, sin t/√2, 0, 0, 0), whose coordinates
    are (x11, √2 xr) with xr = x22 = x33 (:func:`~hmodel.stability.work.section`)."""
    if components != 6:
        return probe_directions(n, False, components)
    t = 2 * math.pi * np.arange(n) / n
    s = np.sin(t) / math.sqrt(2)
    return np.column_stack([np.cos(t), s, s, np.zeros((n, 3))])


def triaxial_directions(n: int, shear: bool = False) -> np.ndarray:
    """Probe directions (n, 6) of an axisymmetric (triaxial) path: ⌈n/2⌉ on the Rendulic circle
    (:func:`section_directions`), the rest spread (:func:`probe_directions` of 6 components).

    Derived here, and measured (docs/stability.md, "3D"): a state of a triaxial path is
    transversely isotropic about axis 1 (fabric and stress), its d²W is unchanged by swapping
    axes 2 and 3, and its instability cone opens in the plane dε22 = dε33 first: 36 directions
    there and 36 spread find the least d²W of 2000 spread ones, which 72 spread ones miss."""
    half = (n + 1) // 2
    return np.vstack([section_directions(half, 6), probe_directions(n - half, shear, 6)])


@dataclass(frozen=True)
class Envelope:
    """Probes from one state: increments applied and responses, both (n, 3 or 6), and d²W."""

    kind: str  # "strain" or "stress"
    deps: np.ndarray
    dsig: np.ndarray

    @property
    def work(self) -> np.ndarray:
        return second_order_work(self.deps, self.dsig)[0]

    @property
    def normalized(self) -> np.ndarray:
        return second_order_work(self.deps, self.dsig)[1]

    @property
    def min_normalized(self) -> float:
        w = self.normalized
        return float(np.nanmin(w)) if np.isfinite(w).any() else float("nan")


def strain_envelope(rev: Rev, state: RevState, n: int = 72, magnitude: float = 1e-5,
                    shear: bool = False, point: int = 0,
                    directions: np.ndarray | None = None) -> Envelope:
    """Stress responses to ``n`` strain probes of ``magnitude`` from material point ``point``
    of a 2D or 3D REV, in the directions of :func:`probe_directions`, or in the unit
    ``directions`` (n, components) given (e.g. :func:`section_directions`)."""
    _check(n, magnitude)
    c = rev.n_components
    if directions is None:
        directions = probe_directions(n, shear, c)
    elif np.shape(directions) != (n, c):
        raise InputError(f"probe directions must have shape ({n}, {c}), got {np.shape(directions)}")
    probes = magnitude * np.asarray(directions, float)
    one = state.select(slice(point, point + 1))
    if supports(rev):
        sig = strain_responses(rev, one, probes)
    else:
        sig = rev.step(one.select(np.zeros(n, dtype=np.int64)), probes).sig
    return Envelope("strain", probes, sig - one.sig[0])


def stress_envelope(rev: Rev, state: RevState, n: int = 72, magnitude: float = 1e-3,
                    point: int = 0) -> Envelope:
    """Strain responses to ``n`` stress probes dσ = magnitude·p·u from material point
    ``point``, u on the circle of :func:`section_directions` ((cos t, sin t, 0) in 2D, the
    Rendulic plane in 3D; the other components held), mixed control solved per probe; NaN
    where no response exists."""
    _check(n, magnitude)
    if not supports(rev):
        raise InputError("stress probes need a compiled cell solver (the closed form or a meso "
                         "surrogate; in 3D the closed-form bi-hexagon)")
    one = state.select(slice(point, point + 1))
    dsig = magnitude * float(one.p[0]) * section_directions(n, rev.n_components)
    deps = stress_responses(rev, one, one.sig[0] + dsig, SETTINGS)
    return Envelope("stress", deps, dsig)
