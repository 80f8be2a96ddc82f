"""Second-order work and response envelopes (Hill's criterion, Gudehus' envelopes) of the 2D
model, and what the 2D and 3D analyses share (bad input, the probe guard, the command's files),
tested in both dimensions."""

import math

import numpy as np
import pytest

from hmodel import InputError, Params
from hmodel.loading import consolidate
from hmodel.cell import ClosedFormSolver
from hmodel.rev import Rev, Rev3D, Sphere
from hmodel.stability import (along_biaxial, along_triaxial, first_sign_change, probe_directions,
                              second_order_work, strain_envelope, stress_envelope, tensor_norm)

P = Params(n_theta=72)


def _elastic_state():
    rev = Rev(P)
    s = consolidate(rev, [5e4])
    assert s.flags.sliding.sum() == 0 and s.flags.broken.sum() == 0  # no cell at its limit
    return rev, s


def test_elastic_state_has_positive_work_and_an_elliptic_envelope():
    rev, s = _elastic_state()
    env = strain_envelope(rev, s, 90, 1e-9)
    assert np.all(env.work > 0) and env.min_normalized > 0
    # dsig = K deps with deps on a circle: the responses lie on an ellipse (a conic through 0-centre)
    x, y = env.dsig[:, 0], env.dsig[:, 1]
    A = np.column_stack([x * x, x * y, y * y])
    coef, *_ = np.linalg.lstsq(A, np.ones_like(x), rcond=None)
    resid = A @ coef - 1
    assert np.abs(resid).max() < 1e-6
    assert coef[1] ** 2 - 4 * coef[0] * coef[2] < 0  # an ellipse, not a hyperbola


def test_probing_leaves_the_state_untouched_and_batched_equals_one_at_a_time():
    rev = Rev(P)
    s = consolidate(rev, [2e5])
    before = (s.cells.values.copy(), s.eps.copy(), s.sig.copy())
    env = strain_envelope(rev, s, 24, 1e-5)
    np.testing.assert_array_equal(s.cells.values, before[0])
    np.testing.assert_array_equal(s.sig, before[2])
    for k in range(24):
        one = rev.step(s, env.deps[k][None, :]).sig[0] - s.sig[0]
        np.testing.assert_allclose(env.dsig[k], one, rtol=1e-10, atol=1e-9)
    # the generic path (any solver) gives the same envelope
    class Wrapped(ClosedFormSolver):  # the closed form without its compiled kernel
        name = "wrapped"

        def kernel(self, params):
            return None
    env2 = strain_envelope(Rev(P, Wrapped()), s, 24, 1e-5)
    np.testing.assert_allclose(env2.dsig, env.dsig, rtol=1e-10, atol=1e-9)


@pytest.mark.slow
def test_stress_probes_invert_strain_probes_in_the_elastic_range():
    rev, s = _elastic_state()
    env = stress_envelope(rev, s, 12, 1e-4)
    assert not np.isnan(env.deps).any()
    back = np.array([rev.step(s, d[None, :]).sig[0] - s.sig[0] for d in env.deps])
    np.testing.assert_allclose(back, env.dsig, rtol=1e-6, atol=1e-6 * s.p[0])


def test_undrained_loading_work_changes_sign_at_peak_q():
    params = Params(n_theta=72, alpha0=math.radians(60), sliding_rhs="equilibrium")
    ps = along_biaxial(params, 1e5, 0.1, undrained=True, every=20, n_probes=12, step=1e-3)
    q = ps.result.stage("shear")["q"]
    peak = ps.shear_strain[np.argmax(q)]
    assert 0 < peak < 0.099  # an interior peak
    assert abs(ps.controllability - peak) <= 1e-3 + 1e-12


def test_drained_loading_work_changes_sign_at_peak_sigma11():
    ps = along_biaxial(P, 2e5, 0.1, every=25, n_probes=12, step=1e-3)
    s11 = ps.result.stage("shear")["sig11"]
    peak = ps.shear_strain[np.argmax(s11)]
    assert abs(ps.controllability - peak) <= 1e-3 + 1e-12
    assert ps.bifurcation <= ps.controllability  # the bifurcation domain is entered first


def test_shear_probes_see_the_shear_stiffness():
    rev, s = _elastic_state()
    env = strain_envelope(rev, s, 40, 1e-9, shear=True)
    assert np.abs(env.deps[:, 2]).max() > 0 and np.abs(env.dsig[:, 2]).max() > 0
    assert np.all(env.work > 0)


def test_second_order_work_definitions():
    deps = np.array([[1.0, 0.0, 0.5]])
    dsig = np.array([[2.0, 3.0, 1.0]])
    w, n = second_order_work(deps, dsig)
    assert w[0] == pytest.approx(2.0 + 0.0 + 2 * 0.5)
    assert n[0] == pytest.approx(3.0 / (tensor_norm(deps)[0] * tensor_norm(dsig)[0]))
    d = probe_directions(50, shear=True)
    np.testing.assert_allclose(tensor_norm(d), 1.0)
    assert first_sign_change(np.arange(6.0), np.array([1, 1, -1, 1, -1, -1]), persist=2) == pytest.approx(3.5)


# -- what the 2D and the 3D analysis share (the 3D model's own: test_stability3d.py) ----------

P3 = Params(sliding_rhs="equilibrium")
COARSE = Sphere(order=9, n_azimuth=2)  # 38 bi-hexagons


def _rev(dim):
    return Rev(Params(n_theta=18)) if dim == 2 else Rev3D(P3, COARSE)


def test_no_probes_and_directions_of_another_dimension_are_refused(dim):
    rev = _rev(dim)
    with pytest.raises(InputError, match="probes"):
        strain_envelope(rev, rev.initial(1), 0, 1e-5)
    with pytest.raises(InputError, match="shape"):
        strain_envelope(rev, rev.initial(1), 4, 1e-6, directions=np.ones((4, 9 - rev.n_components)))


def test_probes_are_counted_before_they_run(dim, monkeypatch):
    """The probes of a state are material points of one batched call, counted by the REV's guard
    (probes x cells x the solver's bytes per cell): at the budget the test runs, one probe more
    is refused."""
    from hmodel.limits import WorkTooLarge

    rev = _rev(dim)
    along = {2: lambda n: along_biaxial(Params(n_theta=18), 2e5, 0.002, step=1e-3, n_probes=n),
             3: lambda n: along_triaxial(P3, 2e5, 0.002, sphere=COARSE, step=1e-3, n_probes=n)}[dim]
    monkeypatch.setenv("HMODEL_MEMORY_LIMIT", str(6 * rev.n_cells * rev.solver.bytes_per_cell))
    cells = {2: "18 directions", 3: "38 bi-hexagons"}[dim]
    with pytest.raises(WorkTooLarge, match=f"7 probes of {cells}"):
        along(7)
    assert len(along(6).check_step) >= 1


@pytest.mark.parametrize("args, word", [
    pytest.param(["--param", "n_theta=18", *args], word, id=f"2d-{word}") for args, word in [
        (["--probes", "0"], "probes"), (["--magnitude", "0"], "magnitude"),
        (["--at", "0.5"], "--at"), (["--at", "x"], "--at"), (["--every", "0"], "every")]
] + [
    pytest.param(args, word, id=f"3d-{word}") for args, word in [
        (["--test", "oedometer"], "--test"),
        (["--extension"], "--extension"),
        (["--order", "9"], "--order"),
        (["--no-rendulic"], "--no-rendulic"),
        (["--test", "triaxial", "-p", "n_theta=36"], "n_theta"),
        (["--test", "triaxial", "--p0", "100kPa,200kPa"], "one material point"),
        (["--test", "triaxial", "--at", "0.5"], "--at"),
        (["--test", "triaxial", "--step", "0"], "--step"),
        (["--controllability", "peak"], "--controllability"),
        (["--program", "examples/triaxial-unload-reload.toml", "--test", "triaxial"], "--program")]
])
def test_bad_stability_inputs(tmp_path, cli, args, word):
    """The 2D options' bad values, and the 3D options given to the 2D test or wrongly to the
    triaxial test: one line, nothing written."""
    out = tmp_path / "o"
    cli.refuses(["stability", "--axial-strain", "0.01", *args, "--out", out], word, out)


def test_stability_command(tmp_path, cli, dim):
    args, comps, rows = {
        2: (["--axial-strain", "0.05", "--param", "n_theta=36", "--at", "0.01,0.04", "--probes", "24"],
            ("11", "22", "12"), 1 + 2 * 2 * 24),
        3: (["--test", "triaxial", "--order", "9", "--azimuths", "2", "--axial-strain", "0.01",
             "--step", "1e-3", "--at", "0.005", "--probes", "12"],
            ("11", "22", "33", "23", "13", "12"), 1 + 2 * 12)}[dim]
    out = tmp_path / "s"
    code, _, err = cli("stability", *args, "--out", out)
    assert code == 0, err
    names = sorted(p.name for p in out.iterdir())
    assert names == ["d2W-path.png", "envelopes.csv", "envelopes.png", "path.csv", "probes.csv", "summary.csv"]
    lines = (out / "envelopes.csv").read_text().splitlines()
    assert len(lines) == rows
    assert lines[0].split(",")[3:3 + 2 * len(comps)] == [f"d{q}{c}" for q in ("eps", "sig") for c in comps]
    assert ("sig33" in (out / "path.csv").read_text().splitlines()[0]) == (dim == 3)
