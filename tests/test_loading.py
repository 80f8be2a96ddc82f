"""Loading paths (report §1.1.2): what each path controls, step convergence, errors. A batch
equal to its separate runs and bad input refused are tested for the 2D and the 3D model alike;
the 3D laboratory tests' own physics is in test_triaxial.py."""

import math

import numpy as np
import pytest

from hmodel import InputError, Params, SolverError
from hmodel.loading import (Recorder, Segment, biaxial, consolidate, constant_p, oedometric,
                            proportional, run_biaxial, run_isotropic, run_segment,
                            run_strain_path, run_triaxial, run_true_triaxial, strain_path)
from hmodel.rev import Rev, Sphere

SMALL = Params(n_theta=36)


def test_isotropic_compression_stops_exactly_at_p0():
    r = run_isotropic(SMALL, [1e5, 3e5])
    for b, p0 in enumerate((1e5, 3e5)):
        last = r.point(b)
        assert last["p"][-1] == pytest.approx(p0, rel=1e-9)
        np.testing.assert_allclose(last["eps11"], last["eps22"], rtol=0, atol=1e-15)
        assert np.all(np.diff(last["p"]) > 0)


def test_drained_biaxial_holds_lateral_stress():
    r = run_biaxial(SMALL, [1e5, 2e5], 0.02)
    for b, p0 in enumerate((1e5, 2e5)):
        sh = r.point(b).stage("shear")
        assert np.max(np.abs(sh["sig22"] - p0)) / p0 <= 1e-8
        assert sh["eps11"][-1] - r.point(b).stage("consolidation")["eps11"][-1] == pytest.approx(0.02)
        assert sh["q"].max() > 0.5 * p0


def test_undrained_biaxial_is_isochoric_after_consolidation():
    r = run_biaxial(SMALL, [1e5], 0.02, undrained=True)
    ev0 = r.stage("consolidation")["eps_v"][-1]
    np.testing.assert_allclose(r.stage("shear")["eps_v"], ev0, rtol=0, atol=1e-13)


P3, S = Params(sliding_rhs="equilibrium"), Sphere(order=9)  # the 3D commands' default rule
COLUMNS = ("eps11", "eps22", "sig11", "sig22", "sig33", "q", "eps_v")


def _lab_test(dim, rule="equilibrium", compiled=None):
    """The drained biaxial (2D) or triaxial (3D) test to 1 % as a function of the points' p0."""
    if dim == 2:
        return lambda p0: run_biaxial(SMALL.with_(sliding_rhs=rule), p0, 0.01, compiled=compiled)
    return lambda p0: run_triaxial(P3.with_(sliding_rhs=rule), p0, 0.01, sphere=S, compiled=compiled)


@pytest.mark.parametrize("dim, rule, compiled, points", [
    pytest.param(2, rule, compiled, (1,), id=f"2d-{rule}-{'compiled' if compiled is None else 'generic'}")
    for rule in ("equilibrium", "report") for compiled in (None, False)
] + [pytest.param(3, "equilibrium", None, (0, 1), id="3d-equilibrium-compiled")])
def test_batch_equals_separate_runs(dim, rule, compiled, points):
    # Each point's Newton iteration ignores the others, so a batch changes no number.
    run = _lab_test(dim, rule, compiled)
    both = run([1e5, 2e5])
    for b in points:
        one = run([(1e5, 2e5)[b]])
        for c in (c for c in COLUMNS if c in one.columns):
            np.testing.assert_allclose(both.point(b)[c], one[c], rtol=1e-9, atol=1e-14, err_msg=c)


def test_oedometric_and_constant_p_paths():
    rev = Rev(SMALL)
    s0 = consolidate(rev, [1e5])
    rec = Recorder()
    s = oedometric(rev, s0, 0.005, recorder=rec)
    r = rec.result()
    np.testing.assert_allclose(r["eps22"], s0.eps[0, 1], atol=1e-15)
    assert s.sig[0, 0] > s.sig[0, 1] > s0.sig[0, 1]  # lateral stress builds up
    rec = Recorder()
    constant_p(rev, s0, 0.01, recorder=rec)
    np.testing.assert_allclose(rec.result()["p"], 1e5, rtol=1e-9)


def test_proportional_path_follows_its_direction():
    rev = Rev(SMALL)
    rec = Recorder()
    proportional(rev, rev.initial(1), [1.0, 0.25, 0.1], 0.003, recorder=rec)
    r = rec.result()
    d = np.array([1.0, 0.25, 0.1]) / np.linalg.norm([1.0, 0.25, 0.1])
    np.testing.assert_allclose(np.column_stack([r["eps11"], r["eps22"], r["eps12"]])[-1], 0.003 * d, rtol=1e-12)


def test_mixed_control_stress_target_on_shear_component():
    # sig12 driven to a target while eps11, eps22 are held: the driver finds eps12.
    rev = Rev(SMALL)
    s0 = consolidate(rev, [2e5])
    seg = Segment.components("EES", [0.0, 0.0, 3e4], 10, "shear")
    s = run_segment(rev, s0, seg).state
    assert s.sig[0, 2] == pytest.approx(3e4, rel=1e-9)
    assert s.eps[0, 2] > 0


def test_strain_path_one_row_per_input_row():
    eps = np.array([[1e-4, 1e-4, 0], [3e-4, 2e-4, 0], [3e-4, 2e-4, 1e-4], [5e-4, 1e-4, 0]])
    r = run_strain_path(SMALL, eps)
    assert len(r) == 4
    np.testing.assert_array_equal(np.column_stack([r["eps11"], r["eps22"], r["eps12"]]), eps)
    # sub-stepping converges to the same path
    fine = run_strain_path(SMALL, eps, max_step=1e-6)
    coarse = run_strain_path(SMALL, eps, max_step=1e-5)
    assert np.max(np.abs(fine["sig11"] - coarse["sig11"])) < np.max(np.abs(fine["sig11"] - r["sig11"])) + 1e-9


def _key_figures(step, n_theta=360):
    r = run_biaxial(Params(n_theta=n_theta), [2e5], 0.1, step=step, iso_step=step / 10)
    sh, c = r.stage("shear"), r.stage("consolidation")
    return sh["q_p"].max(), sh["eps_v"][-1] - c["eps_v"][-1]


def test_default_step_is_converged():
    """Halving the default increments changes peak q/p and eps_v at 10 % by < 0.1 %."""
    from hmodel.loading import AXIAL_STEP, ISO_STEP
    assert ISO_STEP == AXIAL_STEP / 10
    qp1, ev1 = _key_figures(AXIAL_STEP)
    qp2, ev2 = _key_figures(AXIAL_STEP / 2)
    assert abs(qp1 - qp2) / abs(qp2) < 1e-3
    assert abs(ev1 - ev2) / abs(ev2) < 1e-3


def test_first_order_convergence_rate():
    # Forward-Euler increments: errors halve with the step (slope 1 on log-log axes).
    steps = [8e-4, 4e-4, 2e-4, 1e-4]
    ev = np.array([_key_figures(s, n_theta=72)[1] for s in steps])
    diffs = np.abs(np.diff(ev))
    rates = np.log2(diffs[:-1] / diffs[1:])
    assert np.all((rates > 0.7) & (rates < 1.5)), rates


def test_unreachable_stress_target_raises_with_strain():
    rev = Rev(SMALL)
    s0 = consolidate(rev, [1e5])
    seg = Segment.components("ESE", [1e-4, -5e4, 0.0], 1, "tension")  # granular: no tension
    with pytest.raises(SolverError, match="strain"):
        run_segment(rev, s0, seg).state


@pytest.mark.parametrize("bad, match", [
    pytest.param(lambda: consolidate(Rev(SMALL), [-1.0]), "p0 must be positive", id="2d-negative-p0"),
    pytest.param(lambda: consolidate(Rev(SMALL), [float("nan")]), "p0 must be finite", id="2d-nan-p0"),
    pytest.param(lambda: biaxial(Rev(SMALL), Rev(SMALL).initial(1), -0.1), "axial strain must be a positive",
                 id="2d-negative-strain"),
    pytest.param(lambda: proportional(Rev(SMALL), Rev(SMALL).initial(1), [0, 0, 0], 0.01), "not all zero",
                 id="2d-no-direction"),
    pytest.param(lambda: strain_path(Rev(SMALL), np.array([[0.0, float("inf"), 0.0]])), "finite numbers",
                 id="2d-inf-strain"),
    pytest.param(lambda: run_true_triaxial(P3, 2e5, 1.5, 0.01, sphere=S), r"b must be a number in \[0, 1\]",
                 id="3d-b"),
    pytest.param(lambda: run_triaxial(Params(alpha_omega=0.3), 2e5, 0.01, sphere=S), "Sphere\\(alpha_omega",
                 id="3d-2d-fabric"),
    pytest.param(lambda: run_triaxial(P3, 2e5, 0.01, sphere=Sphere(order=13)), "Lebedev rule order",
                 id="3d-order"),
    pytest.param(lambda: run_triaxial(Params(volume="hexagon-consistent"), 2e5, 0.01, sphere=S),
                 "hexagon, rectangle, box", id="3d-volume"),
])
def test_bad_path_inputs_raise_input_error_before_any_work(bad, match):
    with pytest.raises(InputError, match=match):
        bad()


def test_non_finite_increment_is_refused():
    rev = Rev(SMALL)
    with pytest.raises(SolverError, match="non-finite"):
        rev.step(rev.initial(1), np.array([[np.nan, 0.0, 0.0]]))


def test_reference_paths_of_the_report_code():
    """Two paths computed by the report's published code (tests/data/README.md): the strains
    replayed one row per increment give its scale-free stresses (sigma11/sigma22, and each
    stress over its value at the end of consolidation) within 1e-4."""
    import csv
    from pathlib import Path
    ref = Path(__file__).with_name("data")
    for name, a0 in (("drained-biaxial_p0-200kPa_alpha0-50.csv", 50), ("undrained-biaxial_p0-100kPa_alpha0-45.csv", 45)):
        rows = list(csv.DictReader(open(ref / name)))
        k = max(i for i, r in enumerate(rows) if r["stage"] == "consolidation")
        eps = np.array([[float(r["eps11"]), float(r["eps22"]), 0.0] for r in rows])
        sig = np.array([[float(r["sig11"]), float(r["sig22"])] for r in rows])
        params = Params(kn=2e8, kt_kn=0.5, phi_g=math.radians(30), alpha0=math.radians(a0), n_theta=360,
                        volume="hexagon", g2=0, alpha_omega=0.0, sliding_rhs="report")  # the report code's
        out = run_strain_path(params, eps)
        s = np.column_stack([out["sig11"], out["sig22"]])
        np.testing.assert_allclose(s[:, 0] / s[:, 1], sig[:, 0] / sig[:, 1], rtol=1e-4)
        np.testing.assert_allclose(s / s[k], sig / sig[k], rtol=1e-4)
