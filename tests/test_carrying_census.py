"""The census of carrying bi-hexagons (benchmarks/model3d/carrying_census.py)."""

import math

import pytest

from benchmarks.model3d.carrying_census import census
from hmodel import Params


def test_census_of_a_consolidated_rev_counts_every_cell_carrying_and_its_weights_sum_to_one():
    # isotropically consolidated, then 0.2 % of axial strain: every bi-hexagon still has both
    # hexagons closed and loaded (the published cell opens only after its forces fall to zero)
    r = census(Params(alpha0=math.radians(50.0)), 1e5, 0.002, 1e-4, "free")
    assert r["w_both"] + r["w_one"] + r["w_none"] == pytest.approx(1.0, abs=1e-12)
    assert r["w_both"] == pytest.approx(1.0, abs=1e-12)
    assert r["w_positive"] == pytest.approx(1.0, abs=1e-12)
    assert 49.0 < r["alpha_a_min"] <= r["alpha_a_mean"] <= r["alpha_a_max"] < 51.0
    assert r["q_p"] > 0.0


def test_census_of_a_dense_sand_rev_finds_the_few_axial_cells_that_carry_after_its_peak():
    # the drained dense REV with the sand variant's mechanisms sheds most of its cells by 5 %
    # (docs/notes/2026-12-07-box-density-map-learned-loop-rebuild.md); the count must see that
    p = Params(alpha0=math.radians(45.0), contact="hertz-mindlin", lateral="axisymmetric", renewal="mix",
               sliding_rhs="equilibrium")
    r = census(p, 1e5, 0.05, 1e-4, "equal")
    assert r["w_both"] + r["w_one"] + r["w_none"] == pytest.approx(1.0, abs=1e-12)
    assert 0.0 < r["w_both"] < 0.3
