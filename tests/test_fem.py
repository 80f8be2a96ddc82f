"""Finite elements with the H-model at the Gauss points: patch tests, the homogeneous biaxial
test against the material-point driver, equilibrium, Newton's convergence rate, bad input."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from skfem import Basis, ElementQuad1, ElementQuadS2, ElementTriP2, ElementVector, MeshQuad

from hmodel import Params
from hmodel.cli.app import main
from hmodel.fem import GlobalNewtonSettings, biaxial, footing, material_point_curve
from hmodel.fem.assembly import internal_force, strain_hm
from hmodel.fem.bands import band_inclination, concentration, peak_angles, theory_angles
from hmodel.fem.material import HModelMaterial, Trial
from hmodel.fem.mesh import dofs_where, gauss_points
from hmodel.fem.newton import Problem, run_steps
from hmodel.loading import consolidate
from hmodel.rev import Rev


class LinearElastic:
    """Isotropic linear elasticity (plane strain) with Lamé constants: the patch test's law (any
    material with ``trial``/``commit``/``checkpoint``/``restore`` and a ``state`` runs in the FEM
    Newton)."""

    state = None  # no cells

    def __init__(self, n_points: int, lam: float, mu: float, sig0: np.ndarray | None = None):
        self.D = np.array([[lam + 2 * mu, lam, 0.0], [lam, lam + 2 * mu, 0.0], [0.0, 0.0, 2 * mu]])
        self.sig0 = np.zeros((n_points, 3)) if sig0 is None else np.array(sig0, float)
        self.eps = np.zeros((n_points, 3))

    @property
    def n_points(self) -> int:
        return self.eps.shape[0]

    @property
    def sig(self) -> np.ndarray:
        return self.sig0 + self.eps @ self.D.T

    def trial(self, deps: np.ndarray) -> Trial:
        return Trial(deps, self.sig0 + (self.eps + deps) @ self.D.T, np.broadcast_to(self.D, (len(deps), 3, 3)))

    def commit(self, trial: Trial) -> None:
        self.eps = self.eps + trial.deps

    def checkpoint(self) -> np.ndarray:
        return self.eps

    def restore(self, eps: np.ndarray) -> None:
        self.eps = eps


FAST = Params(n_theta=36)
SMOOTH = Params(n_theta=36, sliding_rhs="equilibrium")  # no cell events: a unique response


def _distorted_basis(kind: str) -> Basis:
    """A 3x3 patch on the unit square whose interior nodes are moved off the grid."""
    m = MeshQuad.init_tensor(np.linspace(0, 1, 4), np.linspace(0, 1, 4))
    p = m.p.copy()
    interior = (p[0] > 1e-9) & (p[0] < 1 - 1e-9) & (p[1] > 1e-9) & (p[1] < 1 - 1e-9)
    rng = np.random.default_rng(3)
    p[:, interior] += rng.uniform(-0.08, 0.08, (2, interior.sum()))
    m = MeshQuad(p, m.t)
    elem, order = {"q4": (ElementQuad1(), 2), "q8": (ElementQuadS2(), 4), "t6": (ElementTriP2(), 2)}[kind]
    if kind == "t6":
        m = m.to_meshtri()
    return Basis(m, ElementVector(elem), intorder=order)


def _linear_field(basis: Basis, A: np.ndarray) -> np.ndarray:
    """Nodal values of u = A x (FEM convention)."""
    u = np.zeros(basis.N)
    for c in range(2):
        d = dofs_where(basis, c, lambda x: np.ones(x.shape[1], bool))
        u[d] = A[c] @ basis.doflocs[:, d]
    return u


def _patch(basis: Basis, material, A: np.ndarray, n_steps: int = 1):
    boundary = lambda x: (np.abs(x[0]) < 1e-9) | (np.abs(x[0] - 1) < 1e-9) | (np.abs(x[1]) < 1e-9) | (np.abs(x[1] - 1) < 1e-9)  # noqa: E731
    fixed = np.concatenate([dofs_where(basis, c, boundary) for c in range(2)])
    g = _linear_field(basis, A)
    pb = Problem(basis, material, fixed, g, internal_force(basis, material.sig))
    steps = []
    out = run_steps(pb, n_steps, lambda s, lam: steps.append(s), GlobalNewtonSettings(rtol=1e-11))
    assert out.stopped is None
    return g, sum(s.du for s in steps), steps


A = np.array([[1.0e-3, 0.4e-3], [-0.2e-3, -2.0e-3]])  # grad u: stretch x, compress y, shear
EXPECTED = -np.array([A[1, 1], A[0, 0], 0.5 * (A[0, 1] + A[1, 0])])  # hmodel's (11, 22, 12)


@pytest.mark.parametrize("kind", ["q4", "q8", "t6"])
def test_patch_linear_elastic(kind):
    basis = _distorted_basis(kind)
    B = gauss_points(basis)[1].size
    g, u, _ = _patch(basis, LinearElastic(B, 3e7, 2e7), A)
    np.testing.assert_allclose(u, g, atol=1e-14)  # interior nodes on the linear field
    np.testing.assert_allclose(strain_hm(basis, u), np.tile(EXPECTED, (B, 1)), atol=1e-14)


def test_patch_hmodel_uniform_state():
    """The H-model at every Gauss point of a distorted patch: a homogeneous boundary motion
    leaves every point in the state of one material point given that strain."""
    basis = _distorted_basis("q4")
    B = gauss_points(basis)[1].size
    rev = Rev(FAST)
    mat = HModelMaterial(rev, np.zeros(B, np.int64), 1e5)
    g, u, steps = _patch(basis, mat, A, n_steps=4)
    np.testing.assert_allclose(strain_hm(basis, u), np.tile(EXPECTED, (B, 1)), atol=1e-12)
    one = consolidate(rev, [1e5])
    for _ in range(4):
        one = rev.step(one, (EXPECTED / 4)[None, :])
    np.testing.assert_allclose(mat.state.sig, np.tile(one.sig, (B, 1)), rtol=1e-7, atol=1e-3)


def test_surrogate_trial_runs_the_network_once_per_committed_state():
    """A trial's increment and its three tangent perturbations start from one committed state:
    the shipped surrogate's network sees each of its cells once, and so do later iterates
    of the same load step, until a commit gives new states."""
    from hmodel.surrogate.shipped import load_shipped
    from hmodel.surrogate.solver import SurrogateSolver

    solver = SurrogateSolver(load_shipped())
    params = Params(n_theta=36)
    B = 3
    mat = HModelMaterial(Rev(params, solver=solver), np.zeros(B, np.int64), 2e5)
    before = solver.counts["network_cells"]
    deps = np.array([[-2e-4, 1e-4, 0.0], [-1e-4, 5e-5, 2e-5], [-3e-4, 0.0, -1e-5]])
    t1 = mat.trial(deps)
    used = solver.counts["network_cells"] - before
    assert 0 < used <= B * params.n_theta
    mat.trial(0.5 * deps)
    assert solver.counts["network_cells"] - before == used
    mat.commit(t1)
    mat.trial(deps)
    assert solver.counts["network_cells"] - before > used
    # the finite-difference tangent is the response's: a small increment along it is predicted
    h = 1e-6 * np.array([1.0, -0.5, 0.2])
    t2 = mat.trial(deps + h)
    t0 = mat.trial(deps)
    np.testing.assert_allclose(t2.sig - t0.sig, t0.D @ h, rtol=1e-3, atol=1e-3)


def _errors(res):
    c = material_point_curve(res.reference)
    assert np.allclose(res.column("eps11"), c["eps11"])  # same increments (no cut steps)
    upto = np.argmax(c["q"]) + 1
    scale = c["q"].max()
    return (np.abs(res.column("q") - c["q"])[:upto] / scale,
            np.abs(res.column("eps_v") - c["eps_v"])[:upto])


@pytest.mark.parametrize("mesh", [(1, 1), (2, 4)])
@pytest.mark.parametrize("undrained", [False, True])
def test_homogeneous_biaxial_equals_material_point(mesh, undrained):
    """Smooth platens, no imperfection: every Gauss point follows run_biaxial with the same
    increments, q within 1e-6 of peak q and eps_v within 1e-8."""
    res = biaxial(SMOOTH, 2e5, 0.02, mesh=mesh, n_steps=40, undrained=undrained)
    assert res.stopped is None and len(res) == 41
    eq, ev = _errors(res)
    assert eq.max() < 1e-6 and ev.max() < 1e-8
    if not undrained:  # the lateral pressure is held by the traction
        np.testing.assert_allclose(res.column("sig22"), 2e5, rtol=1e-7)


def test_homogeneous_biaxial_with_the_learned_dem_cell_equals_its_material_point():
    """The shipped richer-cell surrogate at the Gauss points (the generic REV step) follows the
    material-point test (its compiled meso kernel) with the same increments."""
    from hmodel.solvers import get_solver

    res = biaxial(Params(n_theta=12, sliding_rhs="equilibrium"), 2e5, 0.005, mesh=(1, 1), n_steps=10,
                  solver=get_solver("surrogate:hexagon-center"))
    dq, dv = _errors(res)
    assert dq.max() <= 1e-3 and dv.max() <= 1e-6, (dq.max(), dv.max())
    assert res.column("q")[-1] > 1e5


def test_homogeneous_biaxial_report_closure_events():
    """The report's sliding closure has stress jumps (cell events): an increment whose
    equilibrium lies at a jump may end on either side, in the FEM and in the material-point
    driver alike. Every other row agrees within 0.5 % of peak q, and the row after an event
    agrees again."""
    res = biaxial(Params(n_theta=90), 2e5, 0.02, mesh=(2, 4), n_steps=40)
    eq, _ = _errors(res)
    off = np.flatnonzero(eq > 5e-3)
    assert len(off) <= 0.1 * len(eq)
    assert all(eq[i + 1] < 1e-4 for i in off if i + 1 < len(eq))


def test_equilibrium_reactions_match_gauss_stresses():
    """With a weak zone the field is not homogeneous; at equilibrium the mean stresses from
    the boundary forces equal the volume averages of the Gauss-point stresses (average-stress
    theorem: int sig dV = sum_a x_a f_a), and the lateral pressure is p0 on average."""
    res = biaxial(FAST, 2e5, 0.01, mesh=(4, 8), n_steps=10,
                  imperfection="alpha0=50@0.0,0.05,0.012", reference=False, n_saved=10)
    assert res.stopped is None
    last = res.snapshots[-1]
    avg = (res.gauss_dx @ last.sig) / res.gauss_dx.sum()
    assert np.std(last.sig[:, 0]) > 1e-3 * avg[0]  # not homogeneous
    np.testing.assert_allclose(res.column("sig11")[-1], avg[0], rtol=1e-6)
    np.testing.assert_allclose(res.column("sig22")[-1], 2e5, rtol=1e-6)
    np.testing.assert_allclose(avg[1], 2e5, rtol=1e-6)


def test_newton_converges_quadratically():
    """Consistent tangent: in a step without cell events, each residual is about the square of
    the previous one (relative to the reference force)."""
    res = biaxial(SMOOTH, 2e5, 0.02, mesh=(2, 4), n_steps=20, reference=False)
    rates = [np.log(r[2]) / np.log(r[1]) for r in res.residuals if len(r) >= 3 and r[1] < 1e-2 and r[2] > 1e-14]
    assert rates and np.median(rates) > 1.7


def test_stopped_run_keeps_converged_steps(tmp_path):
    res = biaxial(FAST, 2e5, 0.02, mesh=(1, 1), n_steps=5, reference=False,
                  settings=GlobalNewtonSettings(max_iter=1, max_cuts=1))
    assert res.stopped is not None and "did not converge at axial strain" in res.stopped
    assert 1 <= len(res) < 6
    assert np.all(res.column("residual") <= 1e-8)


def test_cli_writes_outputs_and_refuses_bad_input(tmp_path, capsys):
    out = tmp_path / "fem"
    assert main(["fem", "biaxial", "--axial-strain", "0.004", "--mesh", "1x2", "--steps", "4",
                 "-p", "n_theta=36", "--out", str(out)]) == 0
    names = {p.name for p in out.iterdir()}
    assert {"result.csv", "fields.pvd", "fields.png", "curve.png", "fields_00000.vtu"} <= names
    rows = np.genfromtxt(out / "result.csv", delimiter=",", names=True)
    assert len(rows) >= 5 and rows["eps11"][-1] == pytest.approx(0.004)
    for bad in (["--mesh", "0x2"], ["--mesh", "1.5x2"], ["--imperfection", "alpha0=50@1,1,0.01"],
                ["--solver", "nonsense"], ["--element", "q5"]):
        bad_out = tmp_path / "bad"
        assert main(["fem", "biaxial", "--steps", "1", "-p", "n_theta=36", *bad, "--out", str(bad_out)]) == 1
        err = capsys.readouterr().err.strip()
        assert err.startswith("hmodel: error:") and "\n" not in err
        assert not bad_out.exists()
    assert main(["fem", "footing", "--width", "2", "--out", str(tmp_path / "bad")]) == 1


def test_footing_refinement_softens_towards_the_limit():
    """Displacement-based elements are too stiff: while the response is close to elastic,
    refining the mesh lowers the load a settlement needs (10x5 -> 20x10 elements, s/B up to
    0.004); the three-mesh study to s/B = 0.05 is in docs/fem.md."""
    params = Params(n_theta=36, sliding_rhs="equilibrium")
    coarse = footing(params, 1e5, 0.004, mesh=(10, 5), n_steps=4)
    fine = footing(params, 1e5, 0.004, mesh=(20, 10), n_steps=4)
    assert coarse.stopped is None and fine.stopped is None
    pc, pf = coarse.column("pressure"), fine.column("pressure")
    assert pc[0] == pf[0] == 1e5 and np.all(np.diff(pf) > 0)
    assert np.all(pf[1:] < pc[1:])



# ---------------------------------------------------------------- shear bands (hmodel.fem.bands)

def _grid(n=60):
    g = (np.arange(n) + 0.5) / n
    X, Y = np.meshgrid(g, g)
    return np.stack([X.ravel(), Y.ravel()]), np.full(n * n, 1.0 / n**2)


@pytest.mark.parametrize("angle", [30.0, 55.0, 62.0, 80.0])
def test_band_inclination_of_a_straight_strip(angle):
    """A strip 0.06 wide through the centre at a known inclination: the measured one within 1°."""
    x, dx = _grid()
    a = np.radians(angle)
    dist = np.abs(-(x[0] - 0.5) * np.sin(a) + (x[1] - 0.5) * np.cos(a))
    values = np.where(dist < 0.03, 1.0, 0.01)
    assert band_inclination(x, values, dx, top=0.05) == pytest.approx(angle, abs=1.0)


def test_concentration_is_the_peak_over_the_volume_average():
    x, dx = _grid(20)
    assert concentration(np.full(dx.size, 3.0), dx) == pytest.approx(1.0)
    values = np.where(x[0] < 0.25, 2.0, 1.0)  # twice the rest on a quarter: 2 / 1.25
    assert concentration(values, dx) == pytest.approx(1.6)


def test_classical_band_angles_and_the_peak_angles_of_a_curve():
    assert theory_angles(30.0, 10.0) == {"coulomb": 60.0, "roscoe": 50.0, "arthur": 55.0}
    # q/2p = sin 30° at the peak; around it de1 = 2e-3 and deps_v = -5e-4 (dilation):
    # sin psi = 5e-4 / (2 * 2e-3 + 5e-4)
    curve = {"q": np.array([50.0, 90.0, 100.0, 95.0]), "p": np.full(4, 100.0),
             "eps11": np.array([0.0, 1e-3, 2e-3, 3e-3]), "eps_v": np.array([0.0, 1e-4, -1e-4, -4e-4])}
    phi, psi = peak_angles(curve)
    assert phi == pytest.approx(30.0) and psi == pytest.approx(math.degrees(math.asin(5e-4 / 4.5e-3)))


def test_biaxial_specimen_reports_its_band_between_roscoe_and_coulomb(tmp_path, capsys):
    """An edge imperfection at mid-height localizes the post-peak strain in one band, whose
    inclination lies within the classical range (the local model follows Roscoe's angle,
    docs/fem.md); the CLI prints it and writes it to meta.json."""
    out = tmp_path / "band"
    assert main(["fem", "biaxial", "--mesh", "8x16", "-p", "n_theta=60", "-p", "sliding_rhs=equilibrium",
                 "--axial-strain", "0.08", "--steps", "40", "--imperfection", "phi_g=25,alpha0=55@0,0.05,0.01",
                 "--out", str(out)]) == 0
    assert "shear band at" in capsys.readouterr().out
    band = json.loads((out / "meta.json").read_text())["band"]
    assert band["concentration"] > 2 and band["from_step"] >= band["peak_step"] > 0
    assert band["roscoe"] - 3 <= band["angle_deg"] <= band["coulomb"] + 3
