"""Directions of the H-cells and their weights (report eqs. 1.13-1.17).

theta_i = i*pi/n_theta, i = 0..n_theta-1, and w_i = omega(theta_i)*dtheta with
omega(theta) = (1 + alpha_omega cos 2(theta - beta_omega))/pi (eq. 1.17), so that sum w_i = 1
(eq. 1.14) for every n_theta >= 2 (and for n_theta = 1 when alpha_omega = 0).

The opening angles of the cells (:func:`opening_angles`): one α0 for all (the H-model), or a
spread of them across directions (``alpha0_spread``, docs/calibration.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..params import Params


@dataclass(frozen=True)
class Directions:
    """Cell directions and the trigonometric factors the REV needs, all of shape (n_theta,)."""

    theta: np.ndarray
    weights: np.ndarray

    @classmethod
    def from_params(cls, params: Params) -> Directions:
        n = params.n_theta
        theta = np.arange(n) * np.pi / n
        omega = (1.0 + params.alpha_omega * np.cos(2.0 * (theta - params.beta_omega))) / np.pi
        return cls(theta=theta, weights=omega * np.pi / n)

    @cached_property
    def cos2(self) -> np.ndarray:
        return np.cos(self.theta) ** 2

    @cached_property
    def sin2(self) -> np.ndarray:
        return np.sin(self.theta) ** 2

    @cached_property
    def sincos(self) -> np.ndarray:
        return np.sin(self.theta) * np.cos(self.theta)


#: The golden ratio's fractional part: i·GOLDEN mod 1 (i = 0..n-1) orders the directions so that
#: neighbouring directions get distant quantiles (a Weyl sequence, equidistributed and with no
#: low-frequency correlation with θ).
GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


def opening_angles(params: Params) -> np.ndarray:
    """Initial opening angle of each direction's cell (n_theta,) [rad].

    With ``alpha0_spread`` s > 0, the cells' α0 are the n mid-quantiles
    α0 + h (2 (k + 1/2)/n − 1), k = 0..n-1, of the uniform distribution on [α0 − h, α0 + h],
    h = s · min(α0 − 30°, 90° − α0) (so every cell stays in the H-cell's (30°, 90°)); direction i
    gets the quantile k of the rank of i·GOLDEN mod 1 among the n directions: the set of α0 is
    the distribution's exactly, and its order across θ carries no fabric. s = 0: α0 everywhere.
    """
    n = params.n_theta
    a0 = params.alpha0
    if params.alpha0_spread == 0:
        return np.full(n, a0)
    h = params.alpha0_half_width
    rank = np.empty(n, np.int64)
    rank[golden_order(n)] = np.arange(n)
    return a0 + h * (2.0 * (rank + 0.5) / n - 1.0)


def golden_order(n: int) -> np.ndarray:
    """The n cells in the order of i·GOLDEN mod 1: the order in which a spread's quantiles are
    handed out, with no low-frequency component across the cells."""
    return np.argsort(np.mod(np.arange(n) * GOLDEN, 1.0), kind="stable")


def weighted_opening_angles(params: Params, weights: np.ndarray) -> np.ndarray:
    """Initial opening angle of each of C cells of weights ``weights`` (C,) [rad]: the 3D
    counterpart of :func:`opening_angles` for cells of unequal weights (the bi-hexagons on the
    sphere, docs/model3d.md).

    With ``alpha0_spread`` s > 0, cell c takes α0 + h (2 q_c − 1), q_c the middle of its share
    of the cumulative weight, the cells taken in the order of c·GOLDEN mod 1 (no order across
    the sphere: no fabric), so that Σ w_c f(α_c) is the midpoint rule of the mean of f over the
    uniform distribution on [α0 − h, α0 + h], h = :attr:`~hmodel.params.Params.alpha0_half_width`.
    s = 0: α0 everywhere."""
    w = np.asarray(weights, float)
    if params.alpha0_spread == 0:
        return np.full(len(w), params.alpha0)
    order = golden_order(len(w))
    share = w[order] / w.sum()
    q = np.cumsum(share) - 0.5 * share
    out = np.empty(len(w))
    out[order] = params.alpha0 + params.alpha0_half_width * (2.0 * q - 1.0)
    return out
