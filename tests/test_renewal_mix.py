"""Rebirth at the REV's mean box area (``renewal="mix"``, docs/mechanisms.md, "Rebirth at the
mean box area"): the neutral angles and the branches of the rebirth angle, the stress left as it
was and the box volume moved by w(P̄ - P) at each rebirth (2D and 3D), compiled and generic
drivers alike, and, in 2D, a steady state that forgets whether the sample started dense or
loose."""

import math

import numpy as np
import pytest

from hmodel import Params
from hmodel.cell.renewal import BRANCH_2D, BRANCH_3D, NEUTRAL_2D, NEUTRAL_3D, box_at_contact, mix_angle
from hmodel.errors import InputError
from hmodel.loading.lab_tests import run_biaxial
from hmodel.rev.trial import point_trial
from hmodel.rev import Rev, Rev3D, Sphere

TWO_R = 2.0
#: The cells of the notes and the benchmark (benchmarks/mechanisms/critical_state_2d.py).
MIX = Params(kn=1.4e8, kt_kn=0.5, sliding_rhs="equilibrium", n_theta=72, renewal="mix")


@pytest.mark.parametrize("dim, neutral, degrees, box", [
    (2, NEUTRAL_2D, 53.62, lambda a: 8 * (1 + 2 * math.cos(a)) * math.sin(a)),
    (3, NEUTRAL_3D, 64.26, lambda a: 32 * (1 + 2 * math.cos(a)) * math.sin(a) ** 2)])
def test_the_neutral_angle_is_where_the_unloaded_cells_box_is_largest(dim, neutral, degrees, box):
    """2D cos α_n = (√33 - 1)/8, 3D (√13 - 1)/6, against a central difference of the unloaded
    box (2D l1·l2 = 8r²(1 + 2 cos α) sin α, 3D l1·l2·l3 = 32r³(1 + 2 cos α) sin²α, r = 1) and
    against the box at its neighbours."""
    h = 1e-5
    slope = (box_at_contact(neutral + h, TWO_R, dim) - box_at_contact(neutral - h, TWO_R, dim)) / (2 * h)
    assert abs(slope) < 1e-8 * box_at_contact(neutral, TWO_R, dim)
    for d in (1e-3, 0.1):
        assert box_at_contact(neutral, TWO_R, dim) > box_at_contact(neutral + d, TWO_R, dim)
        assert box_at_contact(neutral, TWO_R, dim) > box_at_contact(neutral - d, TWO_R, dim)
    assert math.degrees(neutral) == pytest.approx(degrees, abs=0.005)
    assert box_at_contact(0.7, TWO_R, dim) == pytest.approx(box(0.7))


@pytest.mark.parametrize("dim, neutral, branch", [(2, NEUTRAL_2D, BRANCH_2D), (3, NEUTRAL_3D, BRANCH_3D)])
def test_the_rebirth_angle_has_the_area_on_the_branch_where_the_cell_carries(dim, neutral, branch):
    top = box_at_contact(neutral, TWO_R, dim)
    rng = np.random.default_rng(0)
    for compressed, end in ((True, branch[0]), (False, branch[1])):
        for area in rng.uniform(box_at_contact(end, TWO_R, dim), top, 50):
            a = mix_angle(area, compressed, TWO_R, dim)
            assert (a < neutral) if compressed else (a > neutral)
            assert box_at_contact(a, TWO_R, dim) == pytest.approx(area, rel=1e-12)
        assert mix_angle(0.99 * box_at_contact(end, TWO_R, dim), compressed, TWO_R, dim) == end
        assert mix_angle(1.01 * top, compressed, TWO_R, dim) == neutral


def _rev(params, dim):
    return Rev(params) if dim == 2 else Rev3D(params, Sphere(order=9, n_azimuth=2))


def _opened(flags, dim):
    """The cells a mix rebirth takes: 2D an open contact, 3D open contacts in both hexagons."""
    a = flags[..., 1] | flags[..., 2]
    return a if dim == 2 else a & (flags[..., 6] | flags[..., 7])


def _box(values, dim):
    return values[..., 6] * values[..., 7] * (1.0 if dim == 2 else values[..., 15])


def _opening_step(params, dim, least=3):
    """A REV consolidated by strain and sheared isochorically (generic steps, renewal
    ``params.renewal``) up to the first step in which at least ``least`` cells open: the REV,
    the state before that step, the step's strain increment, and the step with renewal none."""
    rev, none = _rev(params, dim), _rev(params.with_(renewal="none"), dim)
    state = rev.initial(1)
    iso = [-1e-5, -1e-5, 0.0] if dim == 2 else [-1e-5] * 3 + [0.0] * 3
    for _ in range(10):
        state = rev.step(state, np.array([iso]))
    deps = np.array([[2e-3, -2e-3, 0.0]] if dim == 2 else [[2e-3, -1e-3, -1e-3, 0.0, 0.0, 0.0]])
    for _ in range(300):
        plain = none.step(state, deps)
        if _opened(plain.flags.flags[0], dim).sum() >= least:
            return rev, state, deps, plain
        state = rev.step(state, deps)
    raise AssertionError("no step opened enough cells")


@pytest.mark.parametrize("dim", [2, 3])
def test_a_rebirth_keeps_the_stress_and_moves_the_box_volume_by_the_area_gap(dim):
    """From one state, the same increment with renewal none and mix: the stress is the same
    (the reborn cells, like the opened ones, carry nothing), the reborn cells are the opened
    ones (3D: both hexagons open), at contact and force-free with the mean box P̄ of the state
    the increment started from (none clipped here), and Σ w·box moves by Σ_reborn w (P̄ - P_i)."""
    rev, state, deps, none = _opening_step(MIX.with_(alpha0=math.radians(40 if dim == 2 else 50)), dim)
    mix = rev.step(state, deps)
    np.testing.assert_array_equal(mix.sig, none.sig)
    w = rev.weights[0] if dim == 2 else rev.weights
    v0, vn, vm = state.cells.values[0], none.cells.values[0], mix.cells.values[0]
    opened = _opened(none.flags.flags[0], dim)
    area = (w @ _box(v0, dim)) / w.sum()
    np.testing.assert_allclose(_box(vm[opened], dim), area, rtol=1e-12)
    for k in ((0,) if dim == 2 else (0, 8)):
        np.testing.assert_array_equal(vm[opened, k:k + 2], TWO_R)
        np.testing.assert_array_equal(vm[opened, k + 3:k + 6], 0.0)
    np.testing.assert_array_equal(vm[~opened], vn[~opened])
    gap = w[opened] @ (area - _box(vn[opened], dim))
    assert abs(gap) > 0
    assert w @ _box(vm, dim) - w @ _box(vn, dim) == pytest.approx(gap, rel=1e-9)
    # the fused trial of the compiled paths does the same rebirths (hmodel.rev.kernels, kernels3d)
    geo, p = rev.kernel_inputs()
    out, flags, sig = np.empty_like(v0), np.empty_like(mix.flags.flags[0]), np.empty(deps.shape[1])
    assert point_trial(np.ascontiguousarray(v0), state.eps[0].copy(), deps[0].copy(), geo[0], p[0],
                       rev.mode, rev.volume0, out, flags, sig, np.empty((len(v0), 0)))
    np.testing.assert_allclose(out, vm, rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(flags, mix.flags.flags[0])
    np.testing.assert_allclose(sig, mix.sig[0], rtol=1e-10, atol=1e-10 * np.abs(sig).max())


@pytest.mark.parametrize("dim", [2, 3])
def test_a_batch_renews_the_cells_of_its_mix_sets_only(dim):
    """A REV of three parameter sets, ``mix`` in the second only, stepped from the state before
    cells open: each point's step is its own set's single REV step to the last bit, so the
    second point is reborn and the others are not (the batch looks at its mix sets alone)."""
    params = MIX.with_(alpha0=math.radians(40 if dim == 2 else 50))
    rev1, state1, deps, none = _opening_step(params, dim)
    sets = [params.with_(renewal="none"), params, params.with_(renewal="none", kt_kn=0.4)]
    batch = Rev(sets) if dim == 2 else Rev3D(sets, Sphere(order=9, n_azimuth=2))
    state = batch.initial(3)
    state.cells.values[:] = state1.cells.values[0]
    state.eps[:], state.sig[:] = state1.eps[0], state1.sig[0]
    stepped = batch.step(state, np.repeat(deps, 3, axis=0))
    singles = [none, rev1.step(state1, deps), _rev(sets[2], dim).step(state1, deps)]
    for k, one in enumerate(singles):
        np.testing.assert_array_equal(stepped.cells.values[k], one.cells.values[0])
        np.testing.assert_array_equal(stepped.sig[k], one.sig[0])
    assert not np.array_equal(stepped.cells.values[1], stepped.cells.values[0])


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
