"""The probe of carrying bi-hexagons that turn towards the major compression
(benchmarks/model3d/fabric_turn.py, docs/notes/2026-12-07-fabric-turn.md)."""

import math

import numpy as np
import pytest

from benchmarks.model3d.critical_state import parse_mechanisms, segment
from benchmarks.model3d.carrying_census import SAND
from benchmarks.model3d.fabric_turn import FORCES, band_split, dem_split, perp, run, turn
from hmodel import Params
from hmodel.loading import Recorder, consolidate, run_segment
from hmodel.rev import Rev3D, Sphere

COMPRESSION = np.diag([1e-3, -4e-4, -4e-4])  # axial compression (compression positive), dilating


def random_rev(seed: int, C: int = 40):
    rng = np.random.default_rng(seed)
    n = rng.normal(size=(C, 3))
    n /= np.linalg.norm(n, axis=1)[:, None]
    w = rng.uniform(0.5, 1.5, C)
    return n, w / w.sum(), rng.uniform(0.1, 2.0, (C, 16)), rng.random(C) < 0.6


def test_turning_keeps_the_weights_and_every_weighted_field_and_moves_only_carrying_cells_towards_the_axis():
    n, w, v, carry = random_rev(1)
    w2, v2, moved = turn(n, w, v, COMPRESSION, carry, 20.0, math.radians(15.0))
    assert moved > 0.0
    assert w2.sum() == pytest.approx(1.0, abs=1e-14)
    # Σ w x of every field is what the rule conserves (the receiving cell takes the weighted mean)
    np.testing.assert_allclose((w2[:, None] * v2).sum(0), (w[:, None] * v).sum(0), rtol=1e-13)
    lost = w2 < w - 1e-15
    assert lost.any() and np.all(carry[lost])
    # the weight flows towards the compression axis: the weighted mean of n1² rises
    assert (w2 * n[:, 0] ** 2).sum() > (w * n[:, 0] ** 2).sum()
    # no carrying cell, or no deviatoric strain: nothing moves
    assert turn(n, w, v, COMPRESSION, np.zeros(len(w), bool), 20.0, 0.3)[2] == 0.0
    assert turn(n, w, v, np.eye(3) * 1e-3, carry, 20.0, 0.3)[2] == 0.0


def test_one_turn_by_hand():
    # two directions, the axis and one at 30 degrees; turned by 25 degrees the tilted one's
    # target (5 degrees from the axis) is the axis: f = κ |Δε_I - Δε_III| sin² 30°
    t = math.radians(30.0)
    n = np.array([[1.0, 0.0, 0.0], [math.cos(t), math.sin(t), 0.0]])
    w = np.array([0.25, 0.75])
    v = np.array([np.full(16, 2.0), np.full(16, 6.0)])
    w2, v2, moved = turn(n, w, v, COMPRESSION, np.array([False, True]), 10.0, math.radians(25.0))
    df = 10.0 * 1.4e-3 * 0.25 * 0.75
    assert moved == pytest.approx(df, rel=1e-14)
    np.testing.assert_allclose(w2, [0.25 + df, 0.75 - df], rtol=1e-14)
    np.testing.assert_allclose(v2[0], (0.25 * 2.0 + df * 6.0) / (0.25 + df), rtol=1e-14)
    np.testing.assert_array_equal(v2[1], v[1])


def test_perp_moves_weight_from_stretched_empty_cells_and_keeps_the_weighted_forces():
    n, w, v, carry = random_rev(2)
    v[np.ix_(~carry, list(FORCES))] = 0.0  # cells that do not carry hold no force (as the model's)
    e = np.einsum("ci,ij,cj->c", n, COMPRESSION, n)
    w2, v2, moved = perp(n, w, v, COMPRESSION, carry, 5.0)
    assert moved == pytest.approx(float((5.0 * w * -e)[~carry & (e < 0)].sum()), rel=1e-13)
    assert w2.sum() == pytest.approx(1.0, abs=1e-14)
    f = list(FORCES)
    np.testing.assert_allclose((w2[:, None] * v2[:, f]).sum(0), (w[:, None] * v[:, f]).sum(0), rtol=1e-13)
    assert np.all(w2[carry] >= w[carry] - 1e-15)


def test_the_probe_with_the_rule_off_is_the_generic_driver_s_drained_test():
    params = Params(alpha0=math.radians(50.0), **parse_mechanisms(SAND))
    sphere = Sphere(order=7, n_azimuth=2)
    path = run(params, 1e5, 0.01, 1e-3, "off", sphere=sphere)
    rev = Rev3D([params], sphere)
    p = np.array([1e5])
    start = consolidate(rev, p)
    rec = Recorder()
    run_segment(rev, start, segment(False, p, 0.01, 10, "equal"), rec, compiled=False)
    c = rec.result().point(0).columns
    np.testing.assert_array_equal(path["q"][1:], c["q"])
    np.testing.assert_allclose(path["eps11"][1:], c["eps11"] - start.eps[0, 0], rtol=1e-12)
    assert path["moved"] == 0.0 and np.all(path["F11"] == pytest.approx(1.0 / 3.0, abs=1e-12))


def test_turning_under_compression_gathers_weight_on_the_axis_where_the_sphere_resolves_the_turn():
    params = Params(alpha0=math.radians(60.0), **parse_mechanisms(SAND))
    path = run(params, 1e5, 0.02, 1e-3, "turn", 20.0, sphere=Sphere(order=17, n_azimuth=2))
    assert path["moved"] > 0.0
    assert path["F11"][-1] > path["F11"][0] + 1e-3
    # order 7's 13 directions lie 35 degrees and more apart: a turn by 15 degrees lands on the
    # cell itself, and the rule moves nothing (a limit of the rule, docs/notes)
    coarse = run(params, 1e5, 0.02, 1e-3, "turn", 20.0, sphere=Sphere(order=7, n_azimuth=2))
    assert coarse["moved"] == 0.0


def test_band_split_by_hand():
    theta = np.array([10.0, 40.0, 40.0, 60.0, 90.0])
    s11, sr = np.array([4.0, 2.0, 2.0, 1.0, 1.0]), np.array([0.0, 1.0, 1.0, 2.0, 6.0])
    bands = band_split(theta, np.ones(5), s11, sr)
    assert [b["weight"] for b in bands] == pytest.approx([0.2, 0.4, 0.2, 0.2])
    assert [b["sig11"] for b in bands] == pytest.approx([0.4, 0.4, 0.1, 0.1])
    assert [b["sig_r"] for b in bands] == pytest.approx([0.0, 0.2, 0.2, 0.6])


def test_dem_split_of_contacts_along_the_axes(tmp_path):
    # six contacts: two along x (tilt 0) with normal force 3, four across (tilt 90) with 1;
    # branch vectors of length 2: σ11 ∝ 2 · 3 · 2, σr ∝ (4 · 1 · 2)/2; F11 = 2/6; weighted 6/10
    rows = [[0, 1, 3.0, 0, 0, 0, 2.0, 0, 0], [1, 2, 3.0, 0, 0, 0, -2.0, 0, 0],
            [0, 2, 1.0, 0, 0, 0, 0, 2.0, 0], [0, 3, 1.0, 0, 0, 0, 0, 0, 2.0],
            [1, 3, 1.0, 0, 0, 0, 0, -2.0, 0], [2, 3, 1.0, 0, 0, 0, 0, 0, -2.0],
            [3, 4, 0.0, 0, 0, 0, 2.0, 0, 0]]  # an open contact: left out
    (tmp_path / "s").mkdir()
    np.savez(tmp_path / "s" / "triaxial-drained_100kPa.npz", consolidated_contacts=np.array(rows),
             final_contacts=np.array(rows))
    r = dem_split(tmp_path, "s")["final"]
    assert r["contacts"] == 6
    assert r["sig11_over_sig_r"] == pytest.approx(12.0 / 4.0)
    assert r["F11"] == pytest.approx(2.0 / 6.0) and r["F11_force"] == pytest.approx(6.0 / 10.0)
    assert [b["sig11"] for b in r["bands"]] == pytest.approx([1.0, 0.0, 0.0, 0.0])
    assert [b["sig_r"] for b in r["bands"]] == pytest.approx([0.0, 0.0, 0.0, 1.0])


def test_every_part_of_the_probe_is_defined():
    # main() dispatches on names; a part whose function went missing fails only at the end of a
    # long run
    import benchmarks.model3d.fabric_turn as probe

    for name in ("tilt_split", "dem_part", "fixed_part", "orders_part", "extension_part", "kfs_part"):
        assert callable(getattr(probe, name))


def test_curves_follow_the_probe_in_extension_and_mark_what_it_did_not_reach():
    # an extension test's strains are negative: its curves are the probe's at the same strains
    from benchmarks.model3d.fabric_turn import curves
    from hmodel.calibrate import Kind, Test
    from hmodel.variants import get_variant

    params = Params(alpha0=math.radians(55.0), **parse_mechanisms(SAND))
    sphere = Sphere(order=7, n_azimuth=2)
    model = (get_variant(None), params, None, sphere, 1e-3)
    x = [math.log10(params.shear_modulus), params.poisson, math.degrees(params.phi_g), 55.0, 0.0]
    eps = -np.array([0.0, 0.002, 0.005, 0.01])
    test = Test(Kind("triaxial-extension"), 1e5, eps, -1e5 * np.array([0.0, 0.5, 0.8, 1.0]), np.zeros(4), name="x")
    q, ev = curves(test, x, "off", model)
    path = run(params, 1e5, 0.01, 1e-3, "off", sphere=sphere, extension=True)
    k = [int(np.argmin(np.abs(path["eps11"] - e))) for e in eps]
    np.testing.assert_allclose(q, path["q"][k], rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(ev, path["eps_v"][k], rtol=1e-9, atol=1e-12)
    assert np.all(q[1:] < 0.0)  # q = σ11 - σr < 0 in extension


def test_the_loose_rev_s_lateral_bihexagon_is_emptied_whenever_its_axial_contact_opens():
    # docs/notes/2026-12-07-fabric-turn.md, "Why the lateral bi-hexagons carry nothing": the
    # inclined contacts are pressed at every increment, the axial one hovers at 2r; a hexagon
    # with an open contact carries nothing (report Fig. 1.5)
    from benchmarks.model3d.fabric_turn import lateral_part

    r = lateral_part(strain=0.02, increments=4)
    d1 = [s["d1_minus_2r"] for s in r["steps"]]
    assert all(b < a < 0.0 for a, b in zip(d1, d1[1:]))
    assert any(any(s["open"]) for s in r["steps"]) and not all(any(s["open"]) for s in r["steps"])
    for s in r["steps"]:
        if any(s["open"]):
            assert s["N1"] == s["N2"] == 0.0 and max(s["d2_minus_2r"], 0.0) > 0.0
        else:
            assert 0.0 < s["N1"] < 1e-3 * r["carrying_mean_N1"]
