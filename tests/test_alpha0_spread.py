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
from hmodel.rev import Rev, Rev3D, Sphere
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
    with pytest.raises(InputError, match="implemented for the closed-form bi-hexagon"):
        Rev3D(Params(alpha0_spread=0.5), Sphere(order=7), get_solver("surrogate"))


def test_3d_cells_take_the_weighted_quantiles_of_the_spread():
    # bi-hexagons of unequal weights: each at the middle of its share of the cumulative weight,
    # so their weighted mean is alpha0 and their weighted sum of a function the midpoint rule of
    # its mean over the uniform distribution (which the density map integrates exactly)
    from hmodel.rev.density import initial_volume

    p = Params(alpha0=math.radians(50.0), alpha0_spread=0.5, sliding_rhs="equilibrium")
    rev = Rev3D(p, Sphere(order=17, n_azimuth=2))
    a = rev.initial(1).cells.values[0, :, 2]
    np.testing.assert_array_equal(a, rev.initial(1).cells.values[0, :, 10])  # both hexagons
    h = p.alpha0_half_width
    assert h == pytest.approx(math.radians(10.0))
    assert float(rev.weights @ a) / rev.weights.sum() == pytest.approx(p.alpha0, rel=1e-12)
    assert a.min() > p.alpha0 - h and a.max() < p.alpha0 + h and len(np.unique(a)) == rev.n_cells
    assert float(rev.volumes0[0]) / rev.weights.sum() == pytest.approx(initial_volume(p, 3), rel=1e-5)
    # weights-ordered quantiles by hand: three cells, weights 1, 2, 1 in golden order 0, 2, 1
    from hmodel.rev.directions import weighted_opening_angles

    q = weighted_opening_angles(p, np.array([1.0, 2.0, 1.0]))
    # c * GOLDEN mod 1 for c = 0, 1, 2: 0, 0.618, 0.236 -> order 0, 2, 1; cumulative midpoints 1/8, 3/8, 3/4
    np.testing.assert_allclose(q, p.alpha0 + h * (2.0 * np.array([1 / 8, 3 / 4, 3 / 8]) - 1.0), rtol=1e-14)
    np.testing.assert_array_equal(weighted_opening_angles(p.with_(alpha0_spread=0.0), np.ones(5)),
                                  np.full(5, p.alpha0))


def test_3d_spread_runs_compiled_as_generic_and_moves_the_response():
    p = Params(alpha0=math.radians(50.0), alpha0_spread=0.5, sliding_rhs="equilibrium")
    sphere = Sphere(order=11, n_azimuth=2)
    compiled = run_triaxial(p, [2e5], 0.01, sphere=sphere, step=1e-3).point(0)
    generic = run_triaxial(p, [2e5], 0.01, sphere=sphere, step=1e-3, compiled=False).point(0)
    np.testing.assert_allclose(compiled["sig11"], generic["sig11"], rtol=1e-9)
    # the order of the α0 over the cells carries little fabric, less on a finer sphere (measured:
    # 1.4 % of p at order 11 with 2 azimuths, 0.17 % at the default sphere)
    defect = []
    for s in (sphere, Sphere()):
        c = run_triaxial(p, [2e5], 1e-3, sphere=s, step=1e-3).point(0).stage("consolidation")
        normal = [c["sig11"][-1], c["sig22"][-1], c["sig33"][-1]]
        defect.append((max(normal) - min(normal)) / c["p"][-1])
    assert defect[1] < 5e-3 and defect[1] < defect[0] / 3
    single = run_triaxial(p.with_(alpha0_spread=0.0), [2e5], 0.01, sphere=sphere, step=1e-3).point(0)
    assert abs(single["q"][-1] - compiled["q"][-1]) > 1e-3 * abs(single["q"][-1])


def test_cli_runs_with_a_spread(tmp_path):
    out = tmp_path / "r"
    assert main(["run", "biaxial", "--p0", "200kPa", "--axial-strain", "0.005", "-p", "n_theta=36",
                 "-p", "alpha0_spread=0.5", "--out", str(out)]) == 0
    assert (out / "result.csv").exists()
    assert main(["run", "triaxial", "--p0", "200kPa", "--axial-strain", "0.005", "--order", "7",
                 "-p", "alpha0_spread=0.5", "--out", str(tmp_path / "t")]) == 0
