"""Second-order work of increments in the REV's Voigt components, and their tensor norms.

d²W = dσ : dε = Σ dσij dεij: in the REV's Voigt components (:data:`~hmodel.loading.result.COMPONENTS`,
tensor shear components) the normal products once and the shear products twice
(:func:`shear_factors`).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from ..loading.result import COMPONENTS


def shear_factors(n: int) -> np.ndarray:
    """Weights (n,) of the Voigt components (:data:`hmodel.loading.result.COMPONENTS`) in
    a:b = Σ a_ij b_ij: 1 on the normal components, 2 on the shear ones (tensor, not
    engineering, shear components: each appears twice in the sum)."""
    if n not in COMPONENTS:
        raise InputError(f"increments have 3 (2D) or 6 (3D) components, got {n}")
    return np.array([1.0 if c[0] == c[1] else 2.0 for c in COMPONENTS[n]])


def section(x: np.ndarray) -> np.ndarray:
    """Coordinates (..., 2) of tensors x (..., n) in the plane of
    :func:`~hmodel.stability.probes.section_directions`: (x11, x22) in 2D; (x11, √2 xr),
    xr = (x22 + x33)/2, in 3D (the orthogonal projection on the Rendulic plane, in tensor
    norm)."""
    x = np.asarray(x, float)
    if x.shape[-1] != 6:
        return x[..., :2]
    return np.stack([x[..., 0], (x[..., 1] + x[..., 2]) / math.sqrt(2)], axis=-1)


def tensor_norm(x: np.ndarray) -> np.ndarray:
    """|x| = √(x:x) of tensors in Voigt components (..., 3 or 6)."""
    return np.sqrt(np.sum(shear_factors(x.shape[-1]) * x ** 2, axis=-1))


def second_order_work(deps: np.ndarray, dsig: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(d²W, d²W / (|dσ| |dε|)) of increments (..., 3 or 6): d²W = dσ:dε, the shear products
    counted twice (:func:`shear_factors`)."""
    w = np.sum(shear_factors(deps.shape[-1]) * (dsig * deps), axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return w, w / (tensor_norm(deps) * tensor_norm(dsig))


def loading_work(eps: np.ndarray, sig: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """d²W and its normalized value of the increments between consecutive rows (n-1,)."""
    return second_order_work(np.diff(eps, axis=0), np.diff(sig, axis=0))
