"""Directions of the H-cells and their weights (report eqs. 1.13-1.17).

theta_i = i*pi/n_theta, i = 0..n_theta-1, and w_i = omega(theta_i)*dtheta with
omega(theta) = (1 + alpha_omega cos 2(theta - beta_omega))/pi (eq. 1.17), so that sum w_i = 1
(eq. 1.14) for every n_theta >= 2 (and for n_theta = 1 when alpha_omega = 0).
"""

from __future__ import annotations

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
    def from_params(cls, params: Params) -> "Directions":
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
