"""The initial packing of a DEM sample: seeded radii and a granular gas of disks or spheres
without overlap."""

from __future__ import annotations

import math

import numpy as np

from .settings import SampleSettings


def radii(settings: SampleSettings, rng: np.random.Generator) -> np.ndarray:
    """The grains' radii, in random order."""
    a, b = settings.r_min, settings.r_max
    u = rng.random(settings.disks)
    if settings.distribution == "uniform" or a == b:
        return a + (b - a) * u
    return settings.grains.graded_radii(a, b, u)  # equal-area disks, equal-volume spheres


def initial_packing(settings: SampleSettings) -> tuple[np.ndarray, np.ndarray, tuple[float, ...]]:
    """(radii, centres (n, dim), cell size): a granular gas, every grain inside its own square
    (cube) of a jittered lattice of spacing 2.1 r_max (no overlap), in random sites."""
    rng = np.random.default_rng(settings.seed)
    r = radii(settings, rng)
    n, dim = settings.disks, settings.grains.dim
    shape = settings.grains.lattice(n)
    s = 2.1 * settings.r_max
    sites = rng.permutation(math.prod(shape))[:n]
    ij = np.stack(np.unravel_index(sites, shape, order="F"), axis=1).astype(float)
    slack = (0.5 * s - r)[:, None]
    pos = (ij + 0.5) * s + rng.uniform(-1.0, 1.0, (n, dim)) * slack
    return r, pos, tuple(k * s for k in shape)


def mean_diameter(r: np.ndarray) -> float:
    return float(2.0 * np.mean(r))
