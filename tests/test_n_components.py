"""The loading layer on n components: a REV whose states have 6 components (3D)
plugs into the one Newton, the generic driver, the segment runner and the result tables.

The REV here is an isotropic linear-elastic material point, whose answers are hand algebra:
drained triaxial compression has Young's modulus E = mu (3 lambda + 2 mu)/(lambda + mu) and
Poisson's ratio nu = lambda / (2 (lambda + mu)); constant-p compression keeps p exactly.
"""

import numpy as np
import pytest

from hmodel.cell import CellFlags, CellSolver, CellState
from hmodel.loading import (
    Control,
    Recorder,
    Segment,
    Tangent,
    consolidate,
    run_segment,
    solve_increment,
    strain_path,
)
from hmodel.loading.newton import free_direction, solve
from hmodel.loading.result import columns_for, lode_b
from hmodel.rev import RevState
from hmodel.rev.state import deviatoric_stress, equivalent_stress, mean_stress

LAM, MU = 40e6, 25e6  # Lame constants [Pa]
E = MU * (3 * LAM + 2 * MU) / (LAM + MU)
NU = LAM / (2 * (LAM + MU))
# components (11, 22, 33, 23, 13, 12), tensor shear: sig_ij = lam tr(eps) delta_ij + 2 mu eps_ij
D = 2 * MU * np.eye(6)
D[:3, :3] += LAM


class _Solver(CellSolver):
    """No cells to step: the REV below answers with its stress directly."""

    name = "elastic-3d"
    stress_rtol = 0.0

    def initial(self, params, shape=()):
        raise NotImplementedError

    def step(self, params, state, *lengths):
        raise NotImplementedError


class ElasticRev3D:
    """The REV interface the generic driver uses, for 6-component states."""

    n_components = 6
    solver = _Solver()
    kernel = None  # no compiled increment: the generic driver

    def initial(self, n: int, sig0: float = 1e5) -> RevState:
        sig = np.zeros((n, 6))
        sig[:, :3] = sig0
        return RevState(CellState(np.zeros((n, 1, 8))), CellFlags.none((n, 1)), np.zeros((n, 6)), sig)

    def stress(self, cells, eps: np.ndarray, sets=None) -> np.ndarray:
        """The stress at strain eps of a point unloaded at zero strain."""
        return eps @ D.T

    def step(self, state: RevState, deps: np.ndarray) -> RevState:
        deps = np.asarray(deps, float)
        return RevState(state.cells, state.flags, state.eps + deps, state.sig + deps @ D.T, state.sets)


def test_drained_triaxial_on_six_components_is_hand_algebra():
    rev = ElasticRev3D()
    s0 = rev.initial(2, 1e5)
    rows = np.eye(6)
    seg = Segment((False, True, True, False, False, False), rows,
                  np.array([0.01, 1e5, 1e5, 0.0, 0.0, 0.0]), 20, "shear")
    rec = Recorder()
    out = run_segment(rev, s0, seg, rec, compiled=False)
    s = out.state
    assert out.increments == 20 and s.n_components == 6
    np.testing.assert_allclose(s.sig[:, 0] - 1e5, E * 0.01, rtol=1e-9)
    np.testing.assert_allclose(s.eps[:, 1], -NU * 0.01, rtol=1e-9)
    np.testing.assert_allclose(s.eps[:, 2], -NU * 0.01, rtol=1e-9)
    np.testing.assert_allclose(s.sig[:, 1:3], 1e5, rtol=1e-9)
    res = rec.result()
    assert tuple(res.columns)[:len(columns_for(6))] == columns_for(6)
    # triaxial compression: q = sig_a - sig_r = sqrt(3 J2), the Lode angle 0 and b = 0
    np.testing.assert_allclose(res["q"], res["sig11"] - res["sig22"], rtol=1e-12)
    np.testing.assert_allclose(res["q_eq"], res["q"], rtol=1e-9)
    np.testing.assert_allclose(res["lode"], 0.0, atol=1e-6)
    np.testing.assert_allclose(res["eps_v"], res["eps11"] + res["eps22"] + res["eps33"], rtol=1e-12)


def test_constant_p_row_on_six_components():
    rev = ElasticRev3D()
    s0 = rev.initial(1, 2e5)
    M = np.eye(6)
    M[1] = [1 / 3, 1 / 3, 1 / 3, 0, 0, 0]  # p = (sig11 + sig22 + sig33)/3, a stress row
    M[2] = [0, 1, -1, 0, 0, 0]  # eps22 = eps33, a strain row
    seg = Segment((False, True, False, False, False, False), M,
                  np.array([0.005, 2e5, 0.0, 0.0, 0.0, 0.0]), 10, "constant p")
    s = run_segment(rev, s0, seg, compiled=False).state
    np.testing.assert_allclose(s.p, 2e5, rtol=1e-10)
    # deps_v = 0 at constant p for a linear material: the lateral strains are -eps11/2
    np.testing.assert_allclose(s.eps[0, 1], -0.0025, rtol=1e-9)


def test_pure_strain_control_on_six_components():
    rev = ElasticRev3D()
    s0 = rev.initial(3, 0.0)
    deps = np.random.default_rng(0).normal(size=(3, 6)) * 1e-4
    s = solve_increment(rev, s0, Control.strain(deps), Tangent())
    np.testing.assert_allclose(s.sig, deps @ D.T, rtol=1e-12)


def test_solve_and_free_direction_for_n_components():
    rng = np.random.default_rng(1)
    for n in (3, 4, 6):
        J = rng.normal(size=(n, n)) + n * np.eye(n)
        R = rng.normal(size=n)
        np.testing.assert_allclose(solve(J, R), np.linalg.solve(J, R), rtol=1e-10)
        S = np.zeros(n, np.bool_)
        S[n // 2] = True
        u = free_direction(S, J)
        assert len(u) == n and np.linalg.norm(u) > 0
        np.testing.assert_allclose(J[~S] @ u, 0.0, atol=1e-12 * np.abs(J).max() * np.linalg.norm(u))
    assert solve(np.zeros((6, 6)), np.ones(6)) is None


def test_invariants_are_objective_and_lode_spans_compression_to_extension():
    rng = np.random.default_rng(2)
    sig = np.array([3e5, 1e5, 1e5, 0, 0, 0.0])
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    T = np.diag(sig[:3])
    Tr = Q @ T @ Q.T
    rotated = np.array([Tr[0, 0], Tr[1, 1], Tr[2, 2], Tr[1, 2], Tr[0, 2], Tr[0, 1]])
    both = np.stack([sig, rotated])
    np.testing.assert_allclose(mean_stress(both), 5e5 / 3, rtol=1e-12)
    np.testing.assert_allclose(equivalent_stress(both), 2e5, rtol=1e-12)
    # q of DESIGN.md: sig11 - (sig22 + sig33)/2, axis 1 axial, negative in extension
    np.testing.assert_allclose(deviatoric_stress(np.array([sig, [1e5, 3e5, 3e5, 0, 0, 0]])),
                               [2e5, -2e5], rtol=1e-12)
    lode, b = lode_b(np.stack([sig, [3e5, 3e5, 1e5, 0, 0, 0], [3e5, 2e5, 1e5, 0, 0, 0], rotated]))
    np.testing.assert_allclose(b, [0.0, 1.0, 0.5, 0.0], atol=1e-9)
    np.testing.assert_allclose(lode, [0.0, 60.0, 30.0, 0.0], atol=1e-6)
    nan_row = lode_b(np.array([[np.nan] * 6, sig]))  # a dropped point's NaN row stays NaN
    assert np.isnan(nan_row[0][0]) and nan_row[0][1] == 0.0
    with pytest.raises(Exception, match="3 \\(2D\\) or 6 \\(3D\\) components"):
        mean_stress(np.zeros((1, 4)))


def test_a_segment_of_the_wrong_size_is_refused():
    rev = ElasticRev3D()
    with pytest.raises(Exception, match="3 rows for states of 6 components"):
        run_segment(rev, rev.initial(1), Segment.components("ESE", [1e-3, 1e5, 0.0], 5, "x"),
                    compiled=False)


def test_isotropic_consolidation_and_strain_path_on_six_components():
    rev = ElasticRev3D()
    s = consolidate(rev, [1e5, 3e5], state=rev.initial(2, 0.0), step=1e-4)
    np.testing.assert_allclose(s.p, [1e5, 3e5], rtol=1e-10)
    np.testing.assert_allclose(s.sig[:, :3], np.repeat(s.p[:, None], 3, 1), rtol=1e-10)  # isotropic
    np.testing.assert_allclose(s.eps[:, 0], s.p / (3 * LAM + 2 * MU), rtol=1e-9)  # K = lam + 2mu/3
    np.testing.assert_allclose(s.eps[:, 3:], 0.0, atol=1e-15)
    eps = np.array([[1e-3, 0, 0, 0, 0, 2e-4], [2e-3, -1e-3, 0, 1e-4, 0, 0]])
    end = strain_path(rev, eps, state=rev.initial(1, 0.0), max_step=1e-4)
    np.testing.assert_allclose(end.sig[0], D @ eps[-1], rtol=1e-9)
    with pytest.raises(Exception, match=r"rows of \(eps11, eps22, eps33, eps23, eps13, eps12\)"):
        strain_path(rev, eps[:, :3], state=rev.initial(1, 0.0))
