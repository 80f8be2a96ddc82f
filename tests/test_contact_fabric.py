"""The 3D REV's stress split by its contacts' tilt (benchmarks/model3d/contact_fabric.py,
docs/notes/2026-12-07-contact-fabric.md)."""

import math

import numpy as np
import pytest

from benchmarks.model3d.contact_fabric import bihex_contacts, contact_split, distance, rev_stress_by_contacts
from benchmarks.model3d.critical_state import parse_mechanisms, segment
from benchmarks.model3d.carrying_census import SAND
from hmodel import Params
from hmodel.loading import Recorder, consolidate, run_segment
from hmodel.rev import Rev3D, Sphere
from hmodel.rev.rev3d import voigt_to_tensor


def sheared(params: Params, strain: float):
    rev = Rev3D([params], Sphere(order=17, n_azimuth=2))
    p = np.array([1e5])
    end = run_segment(rev, consolidate(rev, p), segment(False, p, strain, round(strain / 1e-3), "equal"),
                      Recorder()).state
    return rev, end


@pytest.mark.parametrize("options", [
    {**parse_mechanisms(SAND), "alpha0": math.radians(60.0)},  # Hertz, renewal=mix, lateral
    {"cross_contacts": "frictionless", "alpha0": math.radians(46.0)},  # linear, cross contacts
])
def test_the_contacts_sum_to_the_rev_s_stress(options):
    # eq. 1.11 summed contact by contact from the branch vectors against the REV's eq. 1.12 per
    # cell: two independent routes to σ, off-diagonal terms included
    params = Params(**options)
    rev, end = sheared(params, 0.03)
    v = end.cells.values[0]
    sig = rev_stress_by_contacts(params, v, rev.frames, rev.weights, float(rev.macro_volume(end.eps)[0]))
    ref = voigt_to_tensor(end.sig)[0]
    np.testing.assert_allclose(sig, ref, atol=1e-9 * abs(ref).max())
    # the case exercises what it claims: extra or cross contacts carry in the second
    if params.cross_contacts == "frictionless":
        cell, _, fn, _ = bihex_contacts(params, v, rev.frames)
        assert (fn[-8 * len(v):] > 0.0).any()


def test_one_axial_bihexagon_by_hand():
    # n = e1, α 60°: eight inclined contacts 60° from the axis, four column contacts along it;
    # d1 = d2 = 2r = 1e-3, N1 = 1, N2 = 0.5, T1 = 0.2 in both hexagons, lengths apart (no extra)
    params = Params(radius=5e-4)
    a = math.radians(60.0)
    hexagon = [1e-3, 1e-3, a, 1.0, 0.5, 0.2, 5e-3, 5e-3]
    v = np.array([hexagon + hexagon])
    r = contact_split(params, v, np.eye(3)[None], np.ones(1))
    inclined11 = 8 * 1e-3 * (math.cos(a) ** 2 + 0.2 * math.sin(a) * math.cos(a))
    column11 = 4 * 0.5 * 1e-3
    # each hexagon's four inclined contacts give 4 d1 (N1 sin² - T1 sin cos) along its own t
    inclined_r = 0.5 * 2 * 4 * 1e-3 * (math.sin(a) ** 2 - 0.2 * math.sin(a) * math.cos(a))
    assert r["contacts_weight"] == 12.0
    assert r["F11"] == pytest.approx((8 * 0.25 + 4) / 12)
    assert r["F11_force"] == pytest.approx((8 * 0.25 + 4 * 0.5) / (8 + 4 * 0.5))
    assert r["sig11_over_sig_r"] == pytest.approx((inclined11 + column11) / inclined_r)
    assert [b["weight"] for b in r["bands"]] == pytest.approx([4 / 12, 0.0, 8 / 12, 0.0])
    assert [b["sig11"] for b in r["bands"]] == pytest.approx(
        [column11 / (inclined11 + column11), 0.0, inclined11 / (inclined11 + column11), 0.0])
    assert [b["sig_r"] for b in r["bands"]] == pytest.approx([0.0, 0.0, 1.0, 0.0])


def test_open_contacts_and_empty_cells_do_not_count():
    params = Params(radius=5e-4)
    a = math.radians(60.0)
    carrying = [1e-3, 1e-3, a, 1.0, 0.5, 0.0, 5e-3, 5e-3]
    empty = [1e-3, 1e-3, a, 0.0, 0.0, 0.0, 5e-3, 5e-3]
    one = contact_split(params, np.array([carrying + carrying]), np.eye(3)[None], np.ones(1))
    # a second bi-hexagon, lateral and empty, of any weight changes nothing
    frames = np.array([np.eye(3), np.eye(3)[[1, 2, 0]]])
    two = contact_split(params, np.array([carrying + carrying, empty + empty]), frames, np.array([1.0, 5.0]))
    assert two == one


def test_distance_of_splits():
    def split(shares):
        return [{"weight": s, "sig11": s, "sig_r": s} for s in shares]

    a, b = split([1.0, 0.0, 0.0, 0.0]), split([0.0, 0.0, 0.5, 0.5])
    assert distance(a, a, "sig11") == 0.0
    assert distance(a, b, "sig_r") == 1.0
    assert distance(a, split([0.5, 0.5, 0.0, 0.0]), "weight") == pytest.approx(0.5)
    with pytest.raises(ValueError):
        distance(a, a[:3], "weight")
