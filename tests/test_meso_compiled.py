"""The meso surrogate's compiled trial and loading path against its NumPy way back and the
generic driver (same algorithm, same numbers), without YADE."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from hmodel.compare import run_path, standard_paths
from hmodel.loading import Recorder, Segment, consolidate, run_segment
from hmodel.loading.compiled import supports
from hmodel.rev import Rev
from hmodel.surrogate.formulations.meso import MesoFormulation
from hmodel.cell.meso_kernel import kernel_params, meso_increment, pack_outputs, pack_responses
from hmodel.surrogate.solver import SurrogateSolver
from test_meso import PARAMS, _cells


def _kernel_against_numpy(form, v, response, e):
    """The kernel's new states and flags for cell strains e (n, 2) against the NumPy way back's
    (to round-off); returns the NumPy ones."""
    dl = -e * np.array([PARAMS.l10, PARAMS.l20])
    ref, ref_flags = form.advance(v, form.apply(response, e / form.m0), dl)
    p, r = kernel_params(form, PARAMS), pack_responses(response, v)
    out, flags = np.empty_like(v), np.empty((len(v), 5), dtype=np.bool_)
    for i in range(len(v)):
        assert meso_increment(v, i, dl[i, 0], dl[i, 1], p, r, out, flags, False, 0.0, 0.0, np.empty(2))
    scale = np.abs(ref).max(axis=0) + 1e-300
    np.testing.assert_allclose(out / scale, ref / scale, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(flags, ref_flags)
    return ref, ref_flags


@pytest.mark.parametrize("cell", ["closed-form", "dem:hexagon-center"])
def test_kernel_is_the_numpy_way_back(cell):
    """Random responses on cells that stick, slide and open, strains of both signs: every
    branch of the way back (mechanisms loading or not, forces clipped at zero, the Coulomb cap,
    the loose-cage ramp of the hexagon-center cell) gives the NumPy result to round-off."""
    form = MesoFormulation(PARAMS, cell, mechanisms=3)
    rng = np.random.default_rng(0)
    v = form.summary(_cells(n=200, steps=25, seed=1).values)
    if form.richer:  # a learned meso-stress of the size of the hexagon's
        v[:, 8:10] *= rng.uniform(0.5, 1.5, (len(v), 2))
    out = rng.normal(size=(len(v), form.n_outputs))
    out[:, :2 * len(form.learned)] *= 5.0
    response = form.response(out)
    e = rng.uniform(-2e-3, 2e-3, (len(v), 2))
    ref, ref_flags = _kernel_against_numpy(form, v, response, e)
    # the branches were visited: loading and idle mechanisms, clipped forces, the cap
    A, n, c2, B = response
    load = np.einsum("nkj,nj->nk", n, e / form.m0) - c2
    assert (load > 0).any() and (load <= 0).any()
    assert (ref[:, 3] == 0).any() and (ref[:, 3] > 0).any() and ref_flags[:, 0].any()


def test_one_networks_outputs_pack_as_its_response():
    """The compiled path packs one network's outputs directly; the rows are those of its
    response (tangent, then n_k, c_k^2, B_k per mechanism, then cos and sin of alpha)."""
    for cell in ("closed-form", "dem:hexagon-center"):
        form = MesoFormulation(PARAMS, cell, mechanisms=3)
        v = form.summary(_cells(n=20, steps=5, seed=2).values)
        out = np.random.default_rng(1).normal(size=(len(v), form.n_outputs))
        a, b = pack_outputs(out, len(form.learned), v), pack_responses(form.response(out), v)
        c = slice(2 * len(form.learned) + 2, form.n_outputs, len(form.learned) + 3)  # c_k, squared by the trial
        np.testing.assert_array_equal(np.abs(a[:, c]), b[:, c])
        a[:, c] = b[:, c]
        np.testing.assert_array_equal(a, b)
        wide = np.empty((len(v), form.n_outputs + 2))
        wide[:, :-2] = out
        assert pack_outputs(wide[:, :-2], len(form.learned), v, wide) is wide  # no copy
        np.testing.assert_array_equal(wide[:, -2:], a[:, -2:])


def test_an_ensembles_mean_response_packs_every_members_mechanisms():
    form = MesoFormulation(PARAMS, "dem:hexagon-center", mechanisms=2)
    rng = np.random.default_rng(3)
    v = form.summary(_cells(n=50, steps=20).values)
    members = [form.response(rng.normal(size=(len(v), form.n_outputs))) for _ in range(3)]
    _kernel_against_numpy(form, v, form.mean_response(members), rng.uniform(-1e-3, 1e-3, (len(v), 2)))


SEGMENTS = {
    "drained": Segment.components("ESE", [0.004, 1e5, 0.0], 8, "shear"),
    "undrained": Segment((False, False, False), np.array([[1.0, 0, 0], [1.0, 1.0, 0], [0, 0, 1.0]]),
                         np.array([0.004, 0.0, 0.0]), 8, "shear"),
}


@pytest.mark.parametrize("name", sorted(SEGMENTS))
def test_compiled_meso_rev_equals_the_generic_driver(tiny_model, name):
    model, _ = tiny_model
    solver = SurrogateSolver(model, on_outside="fallback")
    rev = Rev(PARAMS, solver)
    assert supports(rev)
    s0 = consolidate(rev, [0.8e5, 1.2e5])
    runs = []
    for compiled in (True, False):
        rec = Recorder()
        runs.append((run_segment(rev, s0, SEGMENTS[name], recorder=rec, compiled=compiled).state, rec.result()))
    (sc, rc), (sg, rg) = runs
    for col in ("eps11", "eps22", "sig11", "sig22", "sig12", "frac_sliding", "frac_open"):
        np.testing.assert_allclose(rc[col], rg[col], rtol=1e-6, atol=1e-6 * np.abs(rg["p"]).max())
    np.testing.assert_allclose(sc.cells.values, sg.cells.values, rtol=1e-6, atol=1e-9 * PARAMS.kn)
    assert np.all(sc.sig[:, 0] > s0.sig[:, 0])


def test_compiled_meso_rev_checks_the_training_domain(tiny_model):
    """Each increment's states go through the network once, with the domain check of the
    generic path: ``on_outside="error"`` stops a path that leaves it."""
    from hmodel import SolverError
    model, _ = tiny_model
    paths = {p.name: p for p in standard_paths(0.05)}
    solver = SurrogateSolver(model, on_outside="error")
    with pytest.raises(SolverError, match="outside the surrogate's training domain"):
        run_path(PARAMS, replace(paths["drained"], p0=(3e5,)), solver, 1e-3, 2e-4)
    assert solver.counts["outside"] > 0


def test_trials_are_counted_and_the_previous_increment_starts_newton(tiny_model):
    """A strain-controlled increment takes one trial; a drained one starts from the point's
    previous increment, which after the first increment meets the strain rows exactly."""
    from hmodel.loading.compiled import CompiledSegment
    from hmodel.loading.control import Tangent
    model, _ = tiny_model
    rev = Rev(PARAMS, SurrogateSolver(model, on_outside="fallback"))
    s0 = consolidate(rev, [0.8e5, 1.2e5])
    for name in ("undrained", "drained"):
        seg = SEGMENTS[name]
        M = np.asarray(seg.matrix, float)
        runner = CompiledSegment(rev, s0, seg.stress_rows, M, s0.sig @ M.T,
                                 np.broadcast_to(seg.values, (2, 3)), seg.n_steps, Tangent())
        runner.run(1, seg.n_steps + 1)
        if name == "undrained":
            np.testing.assert_array_equal(runner.trials, seg.n_steps)
            assert np.isnan(runner.guess).all()  # no Newton, no first trial to remember
        else:  # the slope at no strain (one trial) and at least one trial per increment
            assert np.all(runner.trials >= seg.n_steps + 1)
            last = runner.state().eps - s0.eps
            assert np.all(np.isfinite(runner.guess))
            np.testing.assert_allclose(runner.guess[:, 0], seg.values[0] / seg.n_steps, rtol=1e-12)
            assert np.all(np.abs(runner.guess[:, 1]) < np.abs(last[:, 1]))


@pytest.mark.slow
def test_trial_slope_is_the_derivative_of_the_trial_stress(tiny_model):
    """The stress derivative a meso trial gives along a strain direction equals the central
    finite difference of the trial stress (where both step sizes agree: no regime changes in
    between), on a sheared REV's cells in every direction."""
    from hmodel.loading.compiled import trial, trial_tangent, cell_responses, kernel_inputs
    model, _ = tiny_model
    rev = Rev(PARAMS, SurrogateSolver(model, on_outside="fallback"))
    s = run_segment(rev, consolidate(rev, [1e5]), SEGMENTS["drained"]).state
    geo, p = kernel_inputs(rev)
    resp = cell_responses(rev, s.cells.values)[0]
    values, eps = s.cells.values[0], s.eps[0]
    out, flags = np.empty_like(values), np.empty((len(values), 5), dtype=np.bool_)
    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(30):
        x, u = rng.normal(0.0, 3e-4, 3), rng.normal(size=3)
        sig, slope = np.empty(3), np.empty(3)
        assert trial_tangent(values, eps, x, geo, p, rev.mode, rev.volume0, out, flags, sig, resp, u, slope)
        fd = []
        for h in (1e-7, 1e-8):
            plus, minus = np.empty(3), np.empty(3)
            trial(values, eps, x + h * u, geo, p, rev.mode, rev.volume0, out, flags, plus, resp)
            trial(values, eps, x - h * u, geo, p, rev.mode, rev.volume0, out, flags, minus, resp)
            fd.append((plus - minus) / (2 * h))
        size = np.abs(fd[0]).max()
        if np.abs(fd[0] - fd[1]).max() <= 1e-5 * size:
            np.testing.assert_allclose(slope, fd[1], rtol=0, atol=1e-5 * size)
            checked += 1
    assert checked >= 20


def test_free_direction_is_normal_to_the_strain_rows():
    from hmodel.loading.newton import free_direction as _free_direction
    for name in ("drained", "undrained"):
        seg = SEGMENTS[name]
        M = np.asarray(seg.matrix, float)
        u = _free_direction(np.asarray(seg.stress_rows), M)
        if name == "undrained":  # no stress row: nothing free
            assert u.shape == (0,)
        else:
            assert np.linalg.norm(u) > 0
            for r in range(3):
                if not seg.stress_rows[r]:
                    assert abs(M[r] @ u) <= 1e-15 * np.linalg.norm(u)
    M = np.array([[1.0, -1.0, 0.0], [0.5, 0.5, 0.0], [0.0, 0.0, 1.0]])  # consolidation's last step
    u = _free_direction(np.array([False, True, False]), M)
    np.testing.assert_allclose(u / u[0], [1.0, 1.0, 0.0])
