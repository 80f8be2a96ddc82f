"""The compiled segment kernel against the generic Python driver (same algorithm, same numbers)."""

import numpy as np
import pytest

from hmodel import Params, SolverError
from hmodel.cell import ClosedFormSolver
from hmodel.loading import Recorder, Segment, consolidate, run_segment
from hmodel.loading.compiled import CompiledSegment, supports
from hmodel.loading.control import Tangent
from hmodel.rev import Rev, Rev3D, Sphere

SMALL = Params(n_theta=36)

SEGMENTS = {
    "drained": Segment.components("ESE", [0.03, 2e5, 0.0], 150, "shear"),
    "undrained": Segment((False, False, False), np.array([[1.0, 0, 0], [1.0, 1.0, 0], [0, 0, 1.0]]),
                         np.array([0.03, 0.0, 0.0]), 150, "shear"),
    "constant-p": Segment((False, True, False), np.array([[1.0, 0, 0], [0.5, 0.5, 0], [0, 0, 1.0]]),
                          np.array([0.02, 2e5, 0.0]), 100, "shear"),
    "shear-stress": Segment.components("EES", [0.0, 0.0, 4e4], 40, "shear"),
    "lateral-unloading": Segment.components("SEE", [1.2e5, 0.0, 0.0], 40, "shear"),
}


def _both(params, seg, p0=(2e5,), **kw):
    """The segment from consolidation at p0, compiled then generic: [(state, result)] * 2;
    ``params``: a Params or a REV (tests/test_compiled3d.py passes a Rev3D)."""
    rev = Rev(params) if isinstance(params, Params) else params
    s0 = consolidate(rev, list(p0))
    out = []
    for compiled in (True, False):
        rec = Recorder()
        s = run_segment(rev, s0, seg, recorder=rec, compiled=compiled, **kw).state
        out.append((s, rec.result()))
    return out


@pytest.mark.parametrize("name", sorted(SEGMENTS))
@pytest.mark.parametrize("rule", ["report", "equilibrium"])
def test_compiled_equals_generic(name, rule):
    (sc, rc), (sg, rg) = _both(SMALL.with_(sliding_rhs=rule), SEGMENTS[name])
    for col in ("eps11", "eps22", "eps12", "sig11", "sig22", "sig12", "frac_sliding", "frac_open"):
        np.testing.assert_allclose(rc[col], rg[col], rtol=1e-7, atol=1e-9 * np.abs(rg["p"]).max())
    np.testing.assert_allclose(sc.cells.values, sg.cells.values, rtol=1e-7, atol=1e-12)
    np.testing.assert_array_equal(rc["step"], rg["step"])


@pytest.mark.parametrize("volume", ["hexagon", "rectangle", "box", "hexagon-consistent"])
def test_compiled_equals_generic_for_every_volume_option(volume):
    (sc, rc), (sg, rg) = _both(SMALL.with_(volume=volume), SEGMENTS["drained"], p0=(1e5, 3e5))
    np.testing.assert_allclose(rc["sig11"], rg["sig11"], rtol=1e-7)
    np.testing.assert_allclose(rc["eps22"], rg["eps22"], rtol=1e-7, atol=1e-12)


def test_handed_back_increments_are_solved_by_the_generic_driver(monkeypatch):
    # A kernel that fails every increment: the generic driver must solve them all instead.
    import hmodel.loading.compiled as compiled

    def failing_kernel(*args):
        k_from, k_end, stop = args[11], args[12], args[-6]  # (..., k_rec, stop, resp, guess,
        stop[:] = np.minimum(k_from, k_end)  # trials, sets, dropped): every first increment fails

    rev = Rev(SMALL)
    s0 = consolidate(rev, [1e5, 2e5])
    end = np.array([[0.01, 1e5, 0.0], [0.01, 2e5, 0.0]])
    ref = run_segment(rev, s0, Segment((False, True, False), np.eye(3), end, 20, "shear"),
                      compiled=False).state
    monkeypatch.setattr(compiled, "_run_steps", failing_kernel)
    monkeypatch.setattr(compiled, "_run_steps_parallel", failing_kernel)
    runner = CompiledSegment(rev, s0, (False, True, False), np.eye(3), s0.sig, end, 20, Tangent())
    rec = runner.run(1, 21)
    np.testing.assert_allclose(rec[-1, :, 3:6], ref.sig, rtol=1e-9, atol=1e-3)
    np.testing.assert_allclose(runner.state().cells.values, ref.cells.values, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(rec[:, :, 4], np.broadcast_to([1e5, 2e5], (20, 2)), rtol=1e-9)


def test_compiled_kernel_reports_unsolvable_increments_through_the_generic_error():
    rev = Rev(SMALL)
    s0 = consolidate(rev, [1e5])
    seg = Segment.components("ESE", [1e-4, -5e4, 0.0], 1, "tension")
    with pytest.raises(SolverError, match="strain"):
        run_segment(rev, s0, seg, compiled=True).state


def test_compiled_run_leaves_its_input_state_untouched():
    rev = Rev(SMALL)
    s0 = consolidate(rev, [1e5])
    before = s0.cells.values.copy(), s0.eps.copy(), s0.sig.copy()
    run_segment(rev, s0, SEGMENTS["drained"], compiled=True).state
    np.testing.assert_array_equal(s0.cells.values, before[0])
    np.testing.assert_array_equal(s0.eps, before[1])
    np.testing.assert_array_equal(s0.sig, before[2])


def test_only_the_closed_form_solver_is_compiled():
    class Wrapped(ClosedFormSolver):  # the closed form without its compiled kernel
        name = "wrapped"

        def kernel(self, params):
            return None

    assert supports(Rev(SMALL))
    assert not supports(Rev(SMALL, Wrapped()))
    # A foreign solver runs through the generic driver and gives the same answer.
    rev_w, rev = Rev(SMALL, Wrapped()), Rev(SMALL)
    s0 = consolidate(rev, [1e5])
    a = run_segment(rev_w, s0, SEGMENTS["drained"]).state
    b = run_segment(rev, s0, SEGMENTS["drained"]).state
    np.testing.assert_allclose(a.sig, b.sig, rtol=1e-7, atol=1e-7 * np.abs(b.sig).max())  # sig12 is roundoff


@pytest.mark.parametrize("dim", [2, 3])
def test_compiled_consolidation_equals_the_generic_loop(dim):
    """Per-point parameters and pressures: each point stops at its own p0 after its own number
    of increments, in the kernel (all points at once) as in the batched Python loop; for the 2D
    and the 3D REV (isotropic strain increments of eps11, eps22 (and eps33))."""
    sets = [SMALL, SMALL.with_(kn=5e7, alpha0=np.radians(55)), SMALL.with_(phi_g=np.radians(20))]
    rev = Rev(sets * 2) if dim == 2 else Rev3D(sets * 2, Sphere(order=7, n_azimuth=2))
    p0 = [1e5, 2e5, 4e5, 4e5, 1e5, 2e5]
    out = []
    for compiled in (True, False):
        rec = Recorder()
        out.append((consolidate(rev, p0, step=1e-4, recorder=rec, compiled=compiled), rec.result()))
    (sc, rc), (sg, rg) = out
    np.testing.assert_allclose(sc.sig, sg.sig, rtol=1e-12, atol=1e-6)
    np.testing.assert_allclose(sc.p, p0, rtol=1e-9)
    assert np.array_equal(rc["point"], rg["point"]) and np.array_equal(rc["step"], rg["step"])
    np.testing.assert_allclose(rc["eps11"], rg["eps11"], rtol=0, atol=1e-15)
    np.testing.assert_allclose(rc["q"], rg["q"], rtol=1e-12, atol=1e-6)
    assert len(set(np.bincount(rc["point"]))) > 2  # the points did take different numbers of steps
    np.testing.assert_allclose(sc.sig[:, :dim], np.repeat(sc.p[:, None], dim, axis=1), rtol=1e-9)


def test_the_serial_and_parallel_kernels_keep_separate_cache_entries():
    """Numba names its on-disk cache after a function's qualified name and line: the parallel
    kernel made from the same Python function as the serial one loaded the serial machine code
    whenever that was cached first, and ran on one thread."""
    from hmodel.loading import compiled

    serial, parallel = compiled._run_steps, compiled._run_steps_parallel
    assert parallel.targetoptions.get("parallel") and not serial.targetoptions.get("parallel")
    assert serial.py_func.__qualname__ != parallel.py_func.__qualname__
    assert serial.py_func.__code__ is parallel.py_func.__code__  # one algorithm
