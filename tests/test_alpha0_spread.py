"""A spread of opening angles α0 across directions (``alpha0_spread``): the distribution it
builds, the macro volume it starts from, its isotropy and its limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hmodel import Params
from hmodel.cli.app import main
from hmodel.errors import InputError
from hmodel.loading import run_biaxial, run_triaxial
from hmodel.rev import Rev
from hmodel.rev.directions import opening_angles
from hmodel.solvers import get_solver


def test_the_cells_alpha0_are_the_uniform_distributions_mid_quantiles():
    p = Params(n_theta=50, alpha0=math.radians(40.0), alpha0_spread=0.5)
    a = np.degrees(opening_angles(p))
    h = 0.5 * min(40.0 - 30.0, 90.0 - 40.0)  # 5°: the nearer limit is 30°
    expected = 40.0 - h + 2 * h * (np.arange(50) + 0.5) / 50
    assert np.allclose(np.sort(a), expected, rtol=0, atol=1e-12)
    assert a.min() > 35.0 and a.max() < 45.0
    # neighbouring directions do not get neighbouring quantiles
    assert np.abs(np.diff(a)).mean() > 2 * h / 50 * 5
    assert np.array_equal(opening_angles(p.with_(alpha0_spread=0.0)), np.full(50, p.alpha0))


def test_the_initial_macro_volume_is_the_mean_cell_volume_over_the_distribution():
    """V0 = Σ w_i V(α_i) (eq. 1.14) with isotropic weights against the integral of the hexagon
    meso-volume V(α) = 2 d1 sin α (d2 + d1 cos α) = 8 r² (sin α + sin 2α / 2) (eq. 1.20, d1 = d2
    = 2r) over α uniform on [α0 − h, α0 + h] (hand integration; the quantiles are a midpoint
    rule, whose error here is below 1e-7)."""
    a0, s, r = math.radians(50.0), 0.8, 1.0
    h = s * min(a0 - math.pi / 6, math.pi / 2 - a0)
    def prim(a):  # an antiderivative of V(α)
        return 8 * r * r * (-math.cos(a) - math.cos(2 * a) / 4)

    exact = (prim(a0 + h) - prim(a0 - h)) / (2 * h)
    rev = Rev(Params(n_theta=360, alpha0=a0, alpha0_spread=s))
    assert rev.volume0 == pytest.approx(exact, rel=1e-6)
    # without the spread: the one cell's volume, the standard model's V0
    assert Rev(Params(n_theta=360, alpha0=a0)).volume0 == pytest.approx(8 * (math.sin(a0) + math.sin(2 * a0) / 2), rel=1e-12)
    assert exact < Rev(Params(n_theta=360, alpha0=a0)).volume0  # V is concave in α here


def test_no_spread_is_the_standard_model_and_a_small_one_is_near_it():
    base = Params(n_theta=72)
    ref = run_biaxial(base, [2e5], 0.02).point(0).stage("shear")
    zero = run_biaxial(base.with_(alpha0_spread=0.0), [2e5], 0.02).point(0).stage("shear")
    assert np.array_equal(ref["q"], zero["q"]) and np.array_equal(ref["eps_v"], zero["eps_v"])
    tiny = run_biaxial(base.with_(alpha0_spread=1e-6), [2e5], 0.02).point(0).stage("shear")
    assert np.max(np.abs(tiny["q"] - ref["q"])) < 1e-4 * ref["q"].max()


def test_the_spread_carries_no_fabric():
    """Isotropic consolidation stays isotropic as the directions multiply: the order of the α0
    across θ has no cos 2θ component to speak of (eq. 1.17's fabric would give one of order
    alpha_omega)."""
    defect = []
    for n in (360, 3600):
        c = run_biaxial(Params(n_theta=n, alpha0_spread=0.9), [2e5], 1e-3).point(0).stage("consolidation")
        defect.append(abs(c["sig11"][-1] - c["sig22"][-1]) / c["p"][-1])
    assert defect[0] < 5e-3 and defect[1] < defect[0] / 5


def test_refusals():
    with pytest.raises(InputError, match=r"alpha0_spread must lie in \[0, 1\)"):
        Params(alpha0_spread=1.0)
    with pytest.raises(InputError, match="implemented for the closed-form H-cell"):
        Rev(Params(n_theta=12, alpha0_spread=0.5), get_solver("surrogate"))
    with pytest.raises(InputError, match="alpha0_spread is the 2D model's"):
        run_triaxial(Params(alpha0_spread=0.5), [2e5], 0.01)


def test_cli_runs_with_a_spread(tmp_path):
    out = tmp_path / "r"
    assert main(["run", "biaxial", "--p0", "200kPa", "--axial-strain", "0.005", "-p", "n_theta=36",
                 "-p", "alpha0_spread=0.5", "--out", str(out)]) == 0
    assert (out / "result.csv").exists()
