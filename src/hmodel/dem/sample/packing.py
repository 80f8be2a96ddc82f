"""The initial packing of a DEM sample: seeded radii and a granular gas without overlap."""

from __future__ import annotations

import math

import numpy as np

from .settings import SampleSettings


def radii(settings: SampleSettings, rng: np.random.Generator) -> np.ndarray:
    """The disks' radii, in random order."""
    a, b = settings.r_min, settings.r_max
    u = rng.random(settings.disks)
    if settings.distribution == "uniform" or a == b:
        return a + (b - a) * u
    return 1.0 / (1.0 / a - u * (1.0 / a - 1.0 / b))  # equal-area: pdf ~ r^-2


def initial_packing(settings: SampleSettings) -> tuple[np.ndarray, np.ndarray, tuple[float, float]]:
    """(radii, centres (n, 2), (Lx, Ly)): a granular gas, every disk inside its own square of a
    jittered lattice of spacing 2.1 r_max (no overlap), in random sites."""
    rng = np.random.default_rng(settings.seed)
    r = radii(settings, rng)
    n = settings.disks
    nx = math.ceil(math.sqrt(n))
    ny = math.ceil(n / nx)
    s = 2.1 * settings.r_max
    sites = rng.permutation(nx * ny)[:n]
    ij = np.stack([sites % nx, sites // nx], axis=1).astype(float)
    slack = (0.5 * s - r)[:, None]
    pos = (ij + 0.5) * s + rng.uniform(-1.0, 1.0, (n, 2)) * slack
    return r, pos, (nx * s, ny * s)


def mean_diameter(r: np.ndarray) -> float:
    return float(2.0 * np.mean(r))
