"""The 3D critical-state benchmark's volume measures and its one-line criterion
(benchmarks/model3d/critical_state.py; docs/mechanisms.md, "Three measures of the REV's volume")."""

import math

import numpy as np
import pytest

from benchmarks.model3d.critical_state import line_offset, reference_volumes, run, summary
from hmodel import Params
from hmodel.rev import Rev3D, Sphere

SPHERE = Sphere(order=11, n_azimuth=2)


def test_the_line_offset_is_zero_on_a_line_and_the_hand_value_off_it():
    on = [{"p_end": math.exp(x), "nu": 2.0 - 0.1 * x} for x in (0.0, 1.0, 2.0, 3.0)]
    assert line_offset(on, "nu") == pytest.approx(0.0, abs=1e-12)
    # least squares through (0, 0), (1, 0), (2, 0), (3, 1): nu = 0.3 x - 0.2, residuals
    # 0.2, -0.1, -0.4, 0.3 (by hand)
    off = [{"p_end": math.exp(x), "nu": y} for x, y in ((0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (3.0, 1.0))]
    assert line_offset(off, "nu") == pytest.approx(0.4, abs=1e-12)
    assert math.isnan(line_offset(off[:2], "nu"))


@pytest.fixture(scope="module")
def ends():
    sets = [Params(alpha0=math.radians(50.0), sliding_rhs="equilibrium")]
    v_ref = Rev3D(sets[0], SPHERE).volume0
    box_ref = reference_volumes(SPHERE)[1]
    out = {}
    for test in ("drained", "undrained"):
        paths, _ = run(sets, np.array([2e5]), SPHERE, test == "undrained", 0.06, 60, "equal")
        out[test] = (paths[0], summary(paths[0], v_ref, 0.02, 2e5, box_ref))
    return out


def test_the_undrained_test_keeps_the_cells_volume_and_not_the_macro_one(ends):
    path, row = ends["undrained"]
    eps = path["eps11"][-1] - path["eps11"][0]
    start = path["volume0"] * math.exp(-path["eps_v"][0]) / (path["volume"][0] / row["nu_start"])
    assert row["nu_cells_end"] == pytest.approx(start, rel=1e-12)
    # det(I - eps) of an isochoric (in increments) axisymmetric strain, by hand: eps22 = eps33 =
    # -eps/2 (up to the consolidation's strain, of order 1e-3 times eps)
    assert row["nu_end"] / row["nu_start"] == pytest.approx((1 - eps) * (1 + eps / 2) ** 2, rel=5e-4)
    assert row["nu_end"] < row["nu_start"] * (1 - 1e-3)


def _box(alpha):
    """The box l1·l2·l3 of an unloaded bi-hexagon (d1 = d2 = 2r) over (2r)³, by hand from eq. 1.2:
    l1 = 2r(1 + 2 cos α), l2 = l3 = 2·2r sin α."""
    return (1 + 2 * math.cos(alpha)) * (2 * math.sin(alpha)) ** 2


def test_the_box_measure_starts_on_the_box_of_the_45_degree_rev():
    r = Params().radius
    assert reference_volumes(SPHERE)[1] == pytest.approx((2 * r) ** 3 * _box(math.radians(45.0)), rel=1e-12)


def test_without_rebirths_the_box_measure_is_the_cells_volume_on_the_box_start(ends):
    """The two measures follow exp(-ε_v) alike (every length integrates δl = −l δε) and differ by
    their start only: the cells' measure starts on the hexagon volume, 2r(1 + cos α)·(4r sin α)²
    (eq. 1.20 lifted), the box measure on 2r(1 + 2 cos α)·(4r sin α)², each over its 45° value."""
    a, a45 = math.radians(50.0), math.radians(45.0)
    hexagon = (1 + math.cos(a)) * math.sin(a) ** 2 / ((1 + math.cos(a45)) * math.sin(a45) ** 2)
    start = _box(a) / _box(a45) / hexagon   # box over hexagon measure at the start, by hand
    assert abs(start - 1.0) > 1e-2  # the two starts differ at 50 degrees (equal at 45 only)
    for test in ("drained", "undrained"):
        path, row = ends[test]
        # up to the increments' second-order terms (a rebirth at the mean box moves it by percent)
        assert row["nu_box_end"] / (row["nu_cells_end"] * Rev3D(Params(alpha0=a), SPHERE).volume0
                                    / Rev3D(Params(alpha0=a45), SPHERE).volume0) == pytest.approx(start, rel=1e-3), test
    path, row = ends["drained"]
    assert abs(path["eps_v"][-1]) > 1e-3  # a test that did change volume
    assert row["nu_cells_end"] == pytest.approx(path["volume0"] * math.exp(-path["eps_v"][-1])
                                                / (path["volume"][0] / row["nu_start"]), rel=1e-12)


def _path(p):
    """A synthetic undrained path of mean stresses ``p`` (kPa-free units) for ``summary``."""
    n = len(p)
    e = np.linspace(0.0, 0.01 * (n - 1), n)
    return {"eps11": e, "p": np.asarray(p, float), "q": 0.5 * np.asarray(p, float), "eps_v": np.zeros(n),
            "volume": np.ones(n), "volume0": 1.0, "box_end": 1.0, "box_ratio": 1.0, "failed": None}


def test_the_phase_transformation_needs_a_fall_and_a_rise():
    from benchmarks.model3d.mechanisms_table import phase_transformation

    turn = summary(_path([100, 80, 60, 70]), 1.0, 0.02, 100.0, 1.0)   # to 0.6 p0, then up by 1/6
    assert turn["p_min_over_p0"] == pytest.approx(0.6) and turn["axial_strain_at_p_min"] == pytest.approx(0.02)
    assert turn["p_rises_after_min"] and phase_transformation(turn)
    flow = summary(_path([100, 80, 60, 62]), 1.0, 0.02, 100.0, 1.0)   # up by 3 % only: liquefying, no turn
    assert not flow["p_rises_after_min"] and not phase_transformation(flow)
    shallow = summary(_path([100, 96, 95, 100]), 1.0, 0.02, 100.0, 1.0)  # rises, but fell by 5 % only
    assert shallow["p_rises_after_min"] and not phase_transformation(shallow)


def test_the_2d_benchmark_paths_carry_what_the_summary_reads():
    """benchmarks.mechanisms.critical_state_2d shares ``summary`` with the 3D benchmark: its
    paths must give every measure (a change of the summary once broke it unnoticed). Without
    rebirths the cells' volume and the box measure agree (every length integrates δl = −l δε)."""
    from benchmarks.mechanisms.critical_state_2d import BASE
    from benchmarks.mechanisms.critical_state_2d import run as run_2d

    sets = [Params(**BASE, n_theta=24, alpha0=math.radians(45.0))]
    path = run_2d(sets, np.array([1e5]), False, 0.02, 20)[0]
    row = summary(path, path["volume"][0], 0.01, 1e5, path["box"][0])
    assert all(math.isfinite(row[k]) for k in ("nu_end", "nu_cells_end", "nu_box_end", "p_min_over_p0"))
    # the box over the shear against the volumetric strain after its first increment (1e-3 axial)
    assert path["box_ratio"] == pytest.approx(math.exp(-(path["eps_v"][-1] - path["eps_v"][0])), rel=2e-3)
    assert path["box_ratio"] != pytest.approx(1.0, abs=1e-3)  # the test moves the volume at all
