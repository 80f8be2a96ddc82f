"""Rebirth at the REV's mean box area (``renewal="mix"``, docs/mechanisms.md, "Rebirth at the
mean box area"): the neutral angle and the branches of the rebirth angle, the stress left as it
was and the box volume moved by w(P̄ - P) at each rebirth, compiled and generic drivers alike,
and a steady state that forgets whether the sample started dense or loose."""

import math

import numpy as np
import pytest

from hmodel import Params
from hmodel.cell.renewal import BRANCH_2D, NEUTRAL, box_at_contact, mix_angle
from hmodel.errors import InputError
from hmodel.loading.lab_tests import run_biaxial
from hmodel.rev import Rev, Rev3D, Sphere

TWO_R = 2.0
#: The cells of the notes and the benchmark (benchmarks/mechanisms/critical_state_2d.py).
MIX = Params(kn=1.4e8, kt_kn=0.5, sliding_rhs="equilibrium", n_theta=72, renewal="mix")


def test_the_neutral_angle_is_where_the_unloaded_cells_box_is_largest():
    """cos α_n = (√33 - 1)/8 against a central difference of P_C(α) = 8r²(1 + 2 cos α) sin α,
    and against P_C at its neighbours; 53.62°."""
    h = 1e-5
    slope = (box_at_contact(NEUTRAL + h, TWO_R) - box_at_contact(NEUTRAL - h, TWO_R)) / (2 * h)
    assert abs(slope) < 1e-8 * box_at_contact(NEUTRAL, TWO_R)
    for d in (1e-3, 0.1):
        assert box_at_contact(NEUTRAL, TWO_R) > box_at_contact(NEUTRAL + d, TWO_R)
        assert box_at_contact(NEUTRAL, TWO_R) > box_at_contact(NEUTRAL - d, TWO_R)
    assert math.degrees(NEUTRAL) == pytest.approx(53.62, abs=0.005)
    assert box_at_contact(0.7, TWO_R) == pytest.approx(8 * (1 + 2 * math.cos(0.7)) * math.sin(0.7))


def test_the_rebirth_angle_has_the_area_on_the_branch_where_the_cell_carries():
    lo, hi = BRANCH_2D
    top = box_at_contact(NEUTRAL, TWO_R)
    rng = np.random.default_rng(0)
    for compressed, end in ((True, lo), (False, hi)):
        for area in rng.uniform(box_at_contact(end, TWO_R), top, 50):
            a = mix_angle(area, compressed, TWO_R)
            assert (a < NEUTRAL) if compressed else (a > NEUTRAL)
            assert box_at_contact(a, TWO_R) == pytest.approx(area, rel=1e-12)
        assert mix_angle(0.99 * box_at_contact(end, TWO_R), compressed, TWO_R) == end
        assert mix_angle(1.01 * top, compressed, TWO_R) == NEUTRAL


def _opening_step(params, least=3):
    """A 2D REV consolidated by strain and sheared isochorically (generic steps, renewal
    ``params.renewal``) up to the first step in which at least ``least`` cells open: the state
    before that step, the step's strain increment, and the step with renewal none."""
    rev, none = Rev(params), Rev(params.with_(renewal="none"))
    state = rev.initial(1)
    for _ in range(10):
        state = rev.step(state, np.array([[-1e-5, -1e-5, 0.0]]))
    deps = np.array([[2e-3, -2e-3, 0.0]])
    for _ in range(300):
        plain = none.step(state, deps)
        if (plain.flags.flags[0, :, 1] | plain.flags.flags[0, :, 2]).sum() >= least:
            return rev, state, deps, plain
        state = rev.step(state, deps)
    raise AssertionError("no step opened enough cells")


def test_a_rebirth_keeps_the_stress_and_moves_the_box_volume_by_the_area_gap():
    """From one state, the same increment with renewal none and mix: the stress is the same
    (the reborn cells, like the opened ones, carry nothing), the reborn cells are the opened
    ones, at contact and force-free with the box area P̄ of the state the increment started
    from (none clipped here), and Σ w l1 l2 moves by Σ_reborn w (P̄ - P_i)."""
    rev, state, deps, none = _opening_step(MIX.with_(alpha0=math.radians(40)))
    mix = rev.step(state, deps)
    np.testing.assert_array_equal(mix.sig, none.sig)
    w = rev.weights[0]
    v0, vn, vm = state.cells.values[0], none.cells.values[0], mix.cells.values[0]
    opened = none.flags.flags[0, :, 1] | none.flags.flags[0, :, 2]
    area = (w @ (v0[:, 6] * v0[:, 7])) / w.sum()
    np.testing.assert_allclose(vm[opened, 6] * vm[opened, 7], area, rtol=1e-12)
    np.testing.assert_array_equal(vm[opened, :2], TWO_R)
    np.testing.assert_array_equal(vm[opened, 3:6], 0.0)
    np.testing.assert_array_equal(vm[~opened], vn[~opened])
    gap = w[opened] @ (area - vn[opened, 6] * vn[opened, 7])
    assert abs(gap) > 0
    assert w @ (vm[:, 6] * vm[:, 7]) - w @ (vn[:, 6] * vn[:, 7]) == pytest.approx(gap, rel=1e-9)


def test_the_compiled_and_the_generic_drivers_agree_with_mix():
    p = MIX.with_(alpha0=math.radians(40))
    a = run_biaxial(p, [2e5], 0.1, step=2e-3)
    b = run_biaxial(p, [2e5], 0.1, step=2e-3, compiled=False)
    np.testing.assert_allclose(a["q_p"], b["q_p"], rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(a["eps_v"], b["eps_v"], rtol=1e-6, atol=1e-9)


def test_dense_and_loose_samples_end_in_one_steady_state_with_mix_and_not_without():
    """Drained at 200 kPa from α0 = 40° (dense, it dilates) and 55° (loose): with mix both end
    (mean over the last 20 % of 60 % axial strain, as q/p oscillates about its steady value) at
    one q/p within 5 % and without volume change (|dε_v/dε₁| < 0.05); the published cells end
    at q/p apart by a factor of 3 at 25 %."""
    ends = {}
    for renewal, strain in (("mix", 0.6), ("none", 0.25)):
        for a0 in (40, 55):
            r = run_biaxial(MIX.with_(renewal=renewal, alpha0=math.radians(a0)), [2e5], strain,
                            step=1e-3).stage("shear")
            e, qp, ev = r["eps11"], r["q_p"], r["eps_v"]
            last = e >= e[-1] - 0.2
            ends[renewal, a0] = (qp[last].mean(), np.polyfit(e[last], ev[last], 1)[0])
    assert ends["mix", 40][0] == pytest.approx(ends["mix", 55][0], rel=0.05)
    assert abs(ends["mix", 40][1]) < 0.05 and abs(ends["mix", 55][1]) < 0.05
    assert ends["none", 40][0] > 3 * ends["none", 55][0]


def test_mix_is_refused_where_it_is_not_derived():
    with pytest.raises(InputError, match="volume=hexagon"):
        Params(renewal="mix", volume="box")
    with pytest.raises(InputError, match="2D H-cell"):
        Rev3D(Params(renewal="mix"), Sphere(order=9, n_azimuth=2))
