"""One parameter set across densities: α0 from a specimen's void ratio through the REV's initial
volume (hmodel.rev.density), checked against the hexagon's and the bi-hexagon's volumes by hand,
and the model variants that use it."""

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hmodel.calibrate import Test
from hmodel.calibrate.model import Model
from hmodel.errors import InputError
from hmodel.params import Params
from hmodel.rev.density import alpha0_for_void_ratio, initial_volume, loosest_alpha0
from hmodel.variants import get_variant


def hexagon_2d(a):  # eq. 1.20 with d1 = d2 = 2r, r = 1: 8 sin a (1 + cos a)
    return 8 * math.sin(a) * (1 + math.cos(a))


def bihexagon_3d(a):  # l1* l2* l3* = 2 (1 + cos a) * (4 sin a)^2, r = 1
    return 32 * (1 + math.cos(a)) * math.sin(a) ** 2


def test_initial_volumes_are_the_cells_by_hand():
    for a in (0.6, 0.8, 1.0, 1.2):
        assert initial_volume(Params(), 2, a) == pytest.approx(hexagon_2d(a), rel=1e-12)
        assert initial_volume(Params(), 3, a) == pytest.approx(bihexagon_3d(a), rel=1e-12)


def test_the_loosest_cells_by_hand():
    # d/da [sin a (1 + cos a)] = 0 at cos a = 1/2; d/da [(1 + cos a) sin^2 a] = 0 at cos a = 1/3
    assert loosest_alpha0(Params(), 2) == pytest.approx(math.pi / 3, abs=1e-6)
    assert loosest_alpha0(Params(), 3) == pytest.approx(math.acos(1 / 3), abs=1e-6)


@settings(max_examples=60, deadline=None)
@given(a_ref=st.floats(35, 65), e_ref=st.floats(0.5, 1.0), e0=st.floats(0.5, 1.1), dim=st.sampled_from([2, 3]))
def test_the_map_keeps_the_volume_ratio_or_refuses(a_ref, e_ref, e0, dim):
    p = Params(alpha0=math.radians(a_ref))
    volume = hexagon_2d if dim == 2 else bihexagon_3d
    try:
        a0 = alpha0_for_void_ratio(p, dim, e0, e_ref)
    except InputError as e:
        assert "looser than the loosest" in str(e) or "denser than the densest" in str(e) or "beyond the loosest" in str(e)
        return
    assert volume(a0) / volume(p.alpha0) == pytest.approx((1 + e0) / (1 + e_ref), rel=1e-9)
    assert (a0 - p.alpha0) * (e0 - e_ref) >= -1e-12  # denser specimen, flatter cells


def test_the_map_refuses_a_specimen_looser_than_any_cell():
    p = Params(alpha0=math.radians(54.5))
    with pytest.raises(InputError, match=r"looser than the loosest cell .*\(e0 <= 0\.8322\)"):
        alpha0_for_void_ratio(p, 2, 0.9, 0.815)
    assert math.degrees(alpha0_for_void_ratio(p, 3, 1.0, 0.815)) == pytest.approx(63.017, abs=1e-3)


def test_variants_and_their_names():
    assert get_variant(None).name == "published" and get_variant("sand") is get_variant("axisym-mix")
    with pytest.raises(InputError, match="no model 'clay'.*sand \\(= axisym-mix\\)"):
        get_variant("clay")
    p = Params(alpha0=math.radians(50))
    assert get_variant("published").initial_params(p, 3, e0=0.7, e_ref=0.8) is p
    assert get_variant("density").initial_params(p, 3, e0=0.8, e_ref=0.8).alpha0 == pytest.approx(p.alpha0)
    with pytest.raises(InputError, match="reference void ratio"):
        get_variant("density").initial_params(p, 3, e0=0.7)


def _test(e0, p0=1e5):
    e = np.linspace(0, 0.004, 5)
    return Test("drained", p0, e, 1e7 * e, None, name=f"e{e0}", e0=e0)


def test_a_calibration_model_runs_each_test_at_its_own_alpha0():
    """Two specimens at one pressure and two void ratios under the density variant give the
    curves of the published model run at the two mapped α0 (an independent run each)."""
    base = Params(n_theta=12, alpha0=math.radians(50))
    tests = (_test(0.8), _test(0.9))
    dens = Model(tests, variant=get_variant("density")).predict([base])
    assert Model(tests, variant=get_variant("density")).e_ref == pytest.approx(0.85)
    for t, q in zip(tests, dens.q):
        a0 = alpha0_for_void_ratio(base, 2, t.e0, 0.85)
        alone = Model((t,)).predict([replace(base, alpha0=a0)])
        assert np.array_equal(q, alone.q[0])
    assert not np.allclose(dens.q[0], dens.q[1])  # the looser specimen is another material
    published = Model(tests).predict([base])
    assert np.array_equal(published.q[0], published.q[1])


def test_the_density_variant_needs_every_tests_e0_and_fails_sets_it_cannot_map():
    with pytest.raises(InputError, match="has no e0"):
        Model((_test(0.8), _test(None)), variant=get_variant("density"))
    # alpha0 59 deg at e_ref 0.85: the 2D hexagon cannot carry e0 = 0.99
    pred = Model((_test(0.71), _test(0.99)), variant=get_variant("density")).predict(
        [Params(n_theta=12, alpha0=math.radians(59)), Params(n_theta=12, alpha0=math.radians(40))])
    assert "looser than the loosest" in pred.failed[0] and pred.failed[1] == ""
