"""The finite elements' fast paths against the paths they replace: the
sparse-product assembly against scikit-fem's forms, and the fused compiled Gauss-point trials
against batched ``Rev.step`` calls with their finite-difference tangent."""

import numpy as np
import pytest

from hmodel import Params
from hmodel.errors import HModelError
from hmodel.fem.assembly import Operators, internal_force, stiffness, strain_hm
from hmodel.fem.material import HModelMaterial
from hmodel.fem.mesh import Domain
from hmodel.rev import Rev


@pytest.mark.parametrize("element", ["q4", "q8", "t6"])
def test_sparse_assembly_equals_scikit_fem_forms(element):
    basis = Domain(0.05, 0.1, 3, 4, element).basis()
    ops = Operators(basis)
    rng = np.random.default_rng(7)
    u = rng.normal(size=basis.N)
    sig = rng.normal(size=(basis.dx.size, 3))
    D = rng.normal(size=(basis.dx.size, 3, 3))  # not symmetric: the order of B^T D B matters
    np.testing.assert_allclose(ops.strain(u), strain_hm(basis, u), rtol=0, atol=1e-12 * np.abs(u).max() / 0.01)
    f = internal_force(basis, sig)
    np.testing.assert_allclose(ops.internal_force(sig), f, rtol=0, atol=1e-12 * np.abs(f).max())
    K = stiffness(basis, D).toarray()
    np.testing.assert_allclose(ops.stiffness(D).toarray(), K, rtol=0, atol=1e-12 * np.abs(K).max())


def _material(step=None):
    rev = Rev([Params(n_theta=24), Params(n_theta=24, phi_g=np.radians(25), alpha0=np.radians(55))])
    return HModelMaterial(rev, np.array([0, 1, 1, 0, 1, 0]), 2e5, step)


def test_fused_trials_equal_rev_step_calls():
    fused = _material()
    calls = _material(step=lambda rev, state, deps: rev.step(state, deps))  # a step: REV calls
    assert fused._inputs is not None and calls._inputs is None
    rng = np.random.default_rng(3)
    for scale in (1e-4, 2e-3, 5e-3):  # from sticking contacts to sliding and opening ones
        deps = rng.normal(size=(6, 3)) * scale
        a, b = fused.trial(deps), calls.trial(deps)
        np.testing.assert_array_equal(a.sig, b.sig)
        # the exact tangent against Rev.step's forward differences (h = 1e-8: their truncation
        # is about h times the stress's curvature, 1e-6 of the tangent)
        np.testing.assert_allclose(a.D, b.D, rtol=0, atol=1e-5 * np.abs(b.D).max())
        np.testing.assert_array_equal(a.state.cells.values, b.state.cells.values)
        np.testing.assert_array_equal(a.state.flags.flags, b.state.flags.flags)
        np.testing.assert_array_equal(a.state.eps, b.state.eps)
        fused.commit(a)
        calls.commit(b)
    assert fused.state.flags.flags[..., 0].any()  # some cells slide: the test saw the sliding branch


def test_lazy_tangent_is_the_tangent_of_the_trial_state():
    # the tangent asked for after the material moved on is still the one of the trial's start
    mat = _material()
    deps = np.full((6, 3), 1e-4) * np.array([1.0, -0.3, 0.2])
    t = mat.trial(deps)
    mat.commit(mat.trial(10 * deps))
    t_ref = _material().trial(deps)
    np.testing.assert_array_equal(t.D, t_ref.D)
    h = 1e-6  # and it is the stress's slope: a central difference of the stress itself
    for j in range(3):
        e = np.zeros(3)
        e[j] = h
        ref = _material()
        slope = (ref.trial(deps + e).sig - ref.trial(deps - e).sig) / (2 * h)
        np.testing.assert_allclose(t.D[:, :, j], slope, rtol=1e-4, atol=1e-4 * np.abs(t.D).max())


def test_fused_trial_refuses_what_rev_step_refuses():
    mat = _material()
    deps = np.zeros((6, 3))
    deps[2, 0] = np.nan
    with pytest.raises(HModelError):
        mat.trial(deps)


def test_stall_detection_fires_on_cycling_not_on_converging_newton():
    from hmodel.fem.newton import _stalled

    def trials(counts):
        return [(c, None, None, None, None) for c in counts]
    # the band study's cycling: one good correction, then cells open and close between iterates
    assert _stalled([3e-3, 3e-5, 3e-5, 1e-5], trials([110888, 110876, 110878, 110876]))
    # converging, even slowly at first (a restoration of equilibrium after an event)
    assert not _stalled([3e-3, 2e-3, 3e-4], trials([5, 6, 6]))
    assert not _stalled([3e-3, 7e-6, 1e-8], trials([5, 6, 7]))
    # slow but no cell changes regime between iterates: not an event to commit
    assert not _stalled([3e-3, 2e-3, 1.5e-3], trials([5, 5, 5]))
    assert not _stalled([3e-3, 3e-3], trials([5, 6]))  # too early to tell


def test_a_singular_tangent_cuts_the_step_and_ends_the_run_cleanly():
    # a mechanism (no stiffness at all): the factorization fails, the run stops with the reason
    from hmodel.fem.mesh import dofs_where, gauss_points
    from hmodel.fem.newton import GlobalNewtonSettings, Problem, run_steps
    from test_fem import LinearElastic, _distorted_basis

    basis = _distorted_basis("q4")
    mat = LinearElastic(gauss_points(basis)[1].size, 0.0, 0.0)
    fixed = dofs_where(basis, 1, lambda x: np.abs(x[1]) < 1e-9)
    g = np.zeros(basis.N)
    f_ext = np.zeros(basis.N)
    f_ext[dofs_where(basis, 1, lambda x: np.abs(x[1] - 1) < 1e-9)] = 1.0
    out = run_steps(Problem(basis, mat, fixed, g, f_ext), 2, lambda s, lam: None,
                    GlobalNewtonSettings(max_cuts=1))
    assert out.n_steps == 0 and "singular tangent" in out.stopped
