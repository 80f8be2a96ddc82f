"""The compiled 3D path against the generic driver: the same Newton on six
components, its trials the fused bi-hexagon kernel (hmodel.rev.kernels3d) instead of Rev3D.step;
results agree to Newton's tolerance."""

import numpy as np
import pytest
from test_compiled import _both

from hmodel import Params, SolverError
from hmodel.loading import Recorder, Segment, consolidate, run_segment
from hmodel.loading.compiled import any_trial, supports
from hmodel.loading.compiled3d import CompiledSegment3D, kernel_inputs3d
from hmodel.loading.control import Tangent
from hmodel.rev import Rev3D, Sphere

SPHERE = Sphere(order=7, n_azimuth=2)  # small; pinned, not the default rule
P0 = 2e5
E, S = False, True


def _rows(*rows):
    return np.array(rows, float)


SHEAR = _rows([0, 0, 0, 1, 0, 0], [0, 0, 0, 0, 1, 0], [0, 0, 0, 0, 0, 1])
B = 0.5  # true triaxial: (s2 - s3) / (s1 - s3) held at b
SEGMENTS = {
    # axial strain; sig22, sig33 held
    "drained": Segment((E, S, S, E, E, E), np.eye(6), np.array([0.02, P0, P0, 0, 0, 0]), 100, "shear"),
    # axial strain; no volume change; sig22 = sig33
    "undrained": Segment((E, E, S, E, E, E), np.vstack([_rows([1, 0, 0, 0, 0, 0], [1, 1, 1, 0, 0, 0],
                                                               [0, 1, -1, 0, 0, 0]), SHEAR]),
                         np.array([0.02, 0, 0, 0, 0, 0]), 100, "shear"),
    "extension": Segment((E, S, S, E, E, E), np.eye(6), np.array([-0.015, P0, P0, 0, 0, 0]), 100,
                         "shear"),
    # axial strain; p held; sig22 = sig33
    "constant-p": Segment((E, S, S, E, E, E), np.vstack([_rows([1, 0, 0, 0, 0, 0], [1 / 3, 1 / 3, 1 / 3, 0, 0, 0],
                                                               [0, 1, -1, 0, 0, 0]), SHEAR]),
                          np.array([0.02, P0, 0, 0, 0, 0]), 100, "shear"),
    # axial strain; p held; s2 - s3 = b (s1 - s3)
    "true-triaxial": Segment((E, S, S, E, E, E), np.vstack([_rows([1, 0, 0, 0, 0, 0], [1 / 3, 1 / 3, 1 / 3, 0, 0, 0],
                                                                  [-B, 1, B - 1, 0, 0, 0]), SHEAR]),
                             np.array([0.02, P0, 0, 0, 0, 0]), 100, "shear"),
}
COLUMNS = ("eps11", "eps22", "eps33", "eps23", "eps13", "eps12", "sig11", "sig22", "sig33", "sig23",
           "sig13", "sig12", "frac_sliding", "frac_open", "frac_contact14", "frac_contact26")


def _cells_agree(a, b, rtol=1e-7):
    """Cell states to rtol 1e-7, each field to 1e-9 of its largest value: a sliding cell's forces
    follow the strain, met to Newton's tolerance of the macro stress, i.e. of the largest forces."""
    scale = np.abs(b).reshape(-1, b.shape[-1]).max(axis=0)
    scale[scale == 0] = 1.0
    np.testing.assert_allclose(a / scale, b / scale, rtol=rtol, atol=1e-9)


def _agree(rc, rg, sc, sg, rtol=1e-7, strain_atol=1e-12):
    scale = np.abs(rg["p"]).max()
    for col in COLUMNS:
        np.testing.assert_allclose(rc[col], rg[col], rtol=rtol, atol=1e-9 * scale if col.startswith("sig")
                                   else strain_atol, err_msg=col)
    _cells_agree(sc.cells.values, sg.cells.values, rtol)
    np.testing.assert_array_equal(sc.flags.flags, sg.flags.flags)
    np.testing.assert_array_equal(rc["step"], rg["step"])


def test_the_3d_rev_runs_compiled():
    rev = Rev3D(Params(), SPHERE)
    assert supports(rev) and rev.kernel is not None and not rev.kernel.learned
    s0 = consolidate(rev, [P0])
    runner = CompiledSegment3D(rev, s0, SEGMENTS["drained"].stress_rows, np.eye(6), s0.sig,
                               SEGMENTS["drained"].values[None], 10, Tangent())
    rec = runner.run(1, 11)
    assert rec.shape == (10, 1, 16) and runner.states == []
    assert Tangent is not None and runner.tangent.K.shape == (1, 6, 6)


def test_fused_trial_is_rev3d_step():
    # One trial of the kernel against Rev3D.step, from a loaded state where cells slide.
    rev = Rev3D([Params(sliding_rhs="equilibrium", volume="box"), Params(volume="box", kn=5e7)], SPHERE)
    s = rev.initial(2)
    rng = np.random.default_rng(3)
    geo, p = kernel_inputs3d(rev)
    for _ in range(6):
        deps = np.array([1e-3, 2e-4, -3e-4, 0, 0, 0]) + rng.normal(0, 2e-4, (2, 6))
        ref = rev.step(s, deps)
        for b in range(2):
            values = np.ascontiguousarray(s.cells.values[b])
            out, flags, sig = np.empty_like(values), np.empty((rev.n_cells, 11), bool), np.empty(6)
            assert any_trial(values, s.eps[b], deps[b], geo[0], p[b], rev.mode, rev.volumes0[b], out,
                             flags, sig, np.empty((rev.n_cells, 0)))
            np.testing.assert_allclose(out, ref.cells.values[b], rtol=1e-10, atol=1e-15)  # sums in another order
            np.testing.assert_array_equal(flags, ref.flags.flags[b])
            np.testing.assert_allclose(sig, ref.sig[b], rtol=1e-12, atol=1e-9 * np.abs(ref.sig).max())
        s = ref
    assert s.flags.sliding.any()


# Every path with either sliding rule: with the report's λ a cell that slides with T1 < 0 makes
# the stress jump, and the event loop crosses those jumps in both drivers (it counts hexagons:
# test_a_hexagon_opening_beside_its_open_twin_is_an_event_both_drivers_cross).
CASES = [(name, rule) for rule in ("equilibrium", "report") for name in sorted(SEGMENTS)]


@pytest.mark.parametrize("name, rule", CASES)
def test_compiled_equals_generic(name, rule):
    rev = Rev3D(Params(sliding_rhs=rule), SPHERE)
    (sc, rc), (sg, rg) = _both(rev, SEGMENTS[name])
    # with the report's λ the drivers commit cell events, each at a trial met to Newton's
    # tolerance, and the paths go on from there: they agree to a few 1e-7 (1e-10 absolute for
    # a strain that passes near zero), not to round-off
    report = rule == "report"
    _agree(rc, rg, sc, sg, rtol=1e-6 if report else 1e-7, strain_atol=1e-10 if report else 1e-12)
    seg = SEGMENTS[name]
    M = np.asarray(seg.matrix)
    held = sc.sig[0] @ M[list(seg.stress_rows)].T
    np.testing.assert_allclose(held, seg.values[list(seg.stress_rows)], rtol=0, atol=1e-9 * P0)


def test_compiled_equals_generic_at_the_default_rule():
    rev = Rev3D(Params(sliding_rhs="equilibrium"))
    (sc, rc), (sg, rg) = _both(rev, SEGMENTS["drained"])
    _agree(rc, rg, sc, sg)


@pytest.mark.parametrize("volume", ["rectangle", "box"])
def test_compiled_equals_generic_for_every_volume_option(volume):
    rev = Rev3D(Params(volume=volume), SPHERE)
    (sc, rc), (sg, rg) = _both(rev, SEGMENTS["drained"], p0=(1e5, 3e5))
    _agree(rc, rg, sc, sg)


def test_parameter_sets_batched_equal_single_points():
    eq = Params(sliding_rhs="equilibrium")
    sets = [eq, eq.with_(kn=5e7, alpha0=np.radians(55)), eq.with_(phi_g=np.radians(20))]
    rev = Rev3D(sets, SPHERE)
    p0 = [1e5, 2e5, 4e5]
    seg = Segment((E, S, S, E, E, E), np.eye(6), np.array([[0.02, p, p, 0, 0, 0] for p in p0]), 80, "shear")
    (sc, rc), (sg, rg) = _both(rev, seg, p0=p0)
    _agree(rc, rg, sc, sg)
    for k, params in enumerate(sets):  # each point alone, in a REV of its own set
        one = Rev3D(params, SPHERE)
        s1 = consolidate(one, [p0[k]])
        out = run_segment(one, s1, Segment(seg.stress_rows, seg.matrix, seg.values[k], 80, "shear")).state
        np.testing.assert_allclose(out.sig[0], sc.sig[k], rtol=1e-7, atol=1e-9 * p0[k])
        _cells_agree(out.cells.values[0], sc.cells.values[k])


def test_kernel_and_generic_driver_take_turns(monkeypatch):
    # A kernel that gives up every other increment: the generic driver solves those (with the
    # kernel's tangent and last increment), the kernel resumes after each; same path as either.
    import hmodel.loading.compiled as compiled

    real = compiled._run_steps_parallel
    K_FROM, K_END, STOP = 11, 12, -6  # positions in _steps' arguments

    def every_other(*args):
        k = int(args[K_FROM].min())  # the two points fail together: one k for both
        if k % 2 == 0 and k < args[K_END]:  # run increment k, then give up the next one
            real(*args[:K_END], k + 1, *args[K_END + 1:])
            k += 1
        args[STOP][:] = min(k, args[K_END])

    rev = Rev3D(Params(sliding_rhs="equilibrium"), SPHERE)
    s0 = consolidate(rev, [1e5, 2e5])
    seg = Segment((E, S, S, E, E, E), np.eye(6), np.array([[0.01, 1e5, 1e5, 0, 0, 0], [0.01, 2e5, 2e5, 0, 0, 0]]),
                  20, "shear")
    ref = run_segment(rev, s0, seg, compiled=False).state
    monkeypatch.setattr(compiled, "_run_steps_parallel", every_other)
    runner = CompiledSegment3D(rev, s0, seg.stress_rows, np.eye(6), s0.sig, seg.values, 20, Tangent())
    rec = runner.run(1, 21)
    assert runner.trials.min() > 0  # the kernel did run its share
    np.testing.assert_allclose(rec[-1, :, 6:12], ref.sig, rtol=1e-9, atol=1e-3)
    _cells_agree(runner.state().cells.values, ref.cells.values)
    np.testing.assert_allclose(rec[:, :, 7], np.broadcast_to([1e5, 2e5], (20, 2)), rtol=1e-9)


def test_unsolvable_increments_raise_the_generic_error_or_drop_the_point():
    rev = Rev3D(Params(), SPHERE)
    s0 = consolidate(rev, [1e5, 1e5])
    tension = Segment((E, S, S, E, E, E), np.eye(6), np.array([1e-4, -5e4, -5e4, 0, 0, 0]), 1, "tension")
    with pytest.raises(SolverError, match="strain"):
        run_segment(rev, s0, tension, compiled=True)
    # one point pulled apart, the other sheared: with a failure dict the first is dropped
    seg = Segment((E, S, S, E, E, E), np.eye(6), np.array([[1e-3, -5e4, -5e4, 0, 0, 0], [0.01, 1e5, 1e5, 0, 0, 0]]),
                  20, "shear")
    out = []
    for compiled in (True, False):
        failures = {}
        rec = Recorder()
        s = run_segment(rev, s0, seg, rec, failures=failures, compiled=compiled).state
        assert list(failures) == [0]
        out.append((s, rec.result()))
    (sc, rc), (sg, rg) = out
    np.testing.assert_allclose(sc.sig[1], sg.sig[1], rtol=1e-7, atol=1e-9 * 1e5)
    alone = run_segment(rev, s0.select([1]), Segment(seg.stress_rows, seg.matrix, seg.values[1], 20, "shear")).state
    np.testing.assert_allclose(sc.sig[1], alone.sig[0], rtol=1e-7, atol=1e-9 * 1e5)
    np.testing.assert_array_equal(rc["point"], rg["point"])


def test_both_drivers_stop_at_the_same_increment():
    """The lateral stress taken from p0 through zero to -p0: the REV carries no tension, and both
    drivers stop at the increment whose target is a pull, with the same path before it."""
    from hmodel.loading.segment import StageFailed

    rev = Rev3D(Params(sliding_rhs="report"), SPHERE)
    s0 = consolidate(rev, [P0])
    unloading = Segment((E, S, S, E, E, E), np.eye(6), np.array([0.0, -P0, -P0, 0, 0, 0]), 20, "unloading")
    stops = []
    for compiled in (True, False):
        rec = Recorder()
        with pytest.raises(StageFailed) as err:
            run_segment(rev, s0, unloading, rec, compiled=compiled)
        stops.append((err.value.increment, rec.result()))
    (kc, rc), (kg, rg) = stops
    assert kc == kg == 11  # targets P0 (1 - k/10): the 11th is the first pull
    np.testing.assert_allclose(rc["sig22"], rg["sig22"], rtol=1e-7, atol=1e-9 * P0)
    np.testing.assert_allclose(rc["sig11"], rg["sig11"], rtol=1e-7, atol=1e-9 * P0)


def test_compiled_run_leaves_its_input_state_untouched():
    rev = Rev3D(Params(), SPHERE)
    s0 = consolidate(rev, [1e5])
    before = s0.cells.values.copy(), s0.eps.copy(), s0.sig.copy()
    run_segment(rev, s0, SEGMENTS["drained"], compiled=True)
    np.testing.assert_array_equal(s0.cells.values, before[0])
    np.testing.assert_array_equal(s0.eps, before[1])
    np.testing.assert_array_equal(s0.sig, before[2])


def test_a_stopping_criterion_ends_the_compiled_segment_on_the_same_state():
    rev = Rev3D(Params(), SPHERE)
    s0 = consolidate(rev, [P0])
    stop = lambda cols: cols["q"] >= 0.5 * P0  # noqa: E731
    a = run_segment(rev, s0, SEGMENTS["drained"], stop=stop, compiled=True)
    b = run_segment(rev, s0, SEGMENTS["drained"], stop=stop, compiled=False)
    assert a.increments == b.increments < 100
    np.testing.assert_allclose(a.state.sig, b.state.sig, rtol=1e-7, atol=1e-9 * P0)


def test_a_learned_3d_kernel_is_refused_not_ignored():
    from hmodel.cell import CellKernel
    from hmodel.errors import InputError

    rev = Rev3D(Params(), SPHERE)
    rev.kernels = (CellKernel(rev.kernel.params, responses=lambda values: values),)
    with pytest.raises(InputError, match="generic driver"):
        kernel_inputs3d(rev)


def test_the_second_event_count_is_of_hexagons():
    from hmodel.cell.state import CellFlags
    from hmodel.loading.compiled import _broken

    flags = np.zeros((3, 11), bool)
    flags[0, 1] = flags[0, 5 + 2] = True  # both hexagons of bi-hexagon 0 open
    flags[1, 5 + 1] = True                # hexagon B of bi-hexagon 1
    flags[2, 0] = flags[2, 10] = True     # sliding, hexagons touching: nothing open
    assert CellFlags(flags).open_hexagons.tolist() == [2, 1, 0]
    assert CellFlags(flags).broken.tolist() == [True, True, False]
    assert _broken(flags, False) == 2  # the kernel's first count: cells
    assert _broken(flags, True) == 3   # its second: hexagons
    h_cells = np.zeros((2, 5), bool)
    h_cells[1, 2] = True  # an H-cell: one hexagon, both counts alike
    assert _broken(h_cells, False) == 1 == _broken(h_cells, True) == CellFlags(h_cells).open_hexagons.sum()


def test_a_hexagon_opening_beside_its_open_twin_is_an_event_both_drivers_cross(monkeypatch):
    """A loose REV with Hertz-Mindlin contacts in a drained triaxial test at 51 kPa: a family of
    loaded hexagons (N2 near zero) opens while their twins are open already, so the set of broken
    bi-hexagons stays as it was and the stress jumps (σ11 by a tenth). Counted by bi-hexagon, the
    event fallback had no candidate and the increment failed near 1 % strain; the increment
    solved again counting hexagons commits the event, in both drivers (the compiled one in its
    kernel: it hands no increment back, which the test makes an error), and σ22 = σ33 = p0 hold
    on."""
    import math

    from hmodel.loading.compiled import CompiledSegment

    def handed_back(self, k, *args):
        raise AssertionError(f"increment {k} handed back to the generic driver")

    p = Params(sliding_rhs="equilibrium", contact="hertz-mindlin", shear_modulus=2.25e9, poisson=0.005,
               phi_g=math.radians(40.0), alpha0=math.radians(58.0))
    rev = Rev3D(p, Sphere(order=17, n_azimuth=2))
    p0 = 51e3
    seg = Segment((E, S, S, E, E, E), np.eye(6), np.array([0.02, p0, p0, 0, 0, 0]), 200, "shear")
    s0 = consolidate(rev, [p0])
    out = []
    for compiled in (True, False):
        rec = Recorder()
        with monkeypatch.context() as m:
            m.setattr(CompiledSegment, "_hand_back", handed_back)
            s = run_segment(rev, s0, seg, rec, compiled=compiled).state
        r = rec.result()
        np.testing.assert_allclose(r["sig22"], p0, rtol=1e-8)
        np.testing.assert_allclose(r["sig33"], p0, rtol=1e-8)
        assert len(r["eps11"]) == 200 and np.isclose(s.eps[0, 0] - s0.eps[0, 0], 0.02)
        out.append((s, r))
    (sc, rc), (sg, rg) = out
    # events committed at trials met to Newton's tolerance: the paths agree to 1e-5
    np.testing.assert_allclose(rc["sig11"], rg["sig11"], rtol=1e-5, atol=1e-8 * p0)
