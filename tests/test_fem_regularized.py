"""The regularized H-model in the finite elements (hmodel.fem.regularization): the 1D softening
bar against its analytical band width, the homogeneous specimen against the material point,
the coupled Newton's convergence rate, the band-width measurement and the command line."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.sparse.linalg import spsolve

from hmodel import Params
from hmodel.cli.app import main
from hmodel.errors import InputError
from hmodel.fem import biaxial, material_point_curve
from hmodel.fem.bands import band_width
from hmodel.fem.material import Trial
from hmodel.fem.mesh import Domain, dofs_where, gauss_points
from hmodel.fem.newton import GlobalNewtonSettings, Problem, run_steps
from hmodel.fem.regularization import NonlocalProblem, parse_regularization

SMOOTH = Params(n_theta=30, sliding_rhs="equilibrium")  # no cell events: a unique response


class BilinearSoftening:
    """A bar's law on component 11 (compression positive): elastic E up to f_y, then the stress
    falls with modulus H (plasticity with linear softening, plastic modulus H_p = E H / (E + H)
    so that d sig / d eps = -H while loading); elastic unloading. Components 22 and 12 are
    linear elastic (E) and uncoupled, so that a strip loaded along 11 is a 1D bar."""

    state = None  # no cells

    def __init__(self, fy: np.ndarray, E: float, H: float):
        self.E, self.fy, self.Hp = E, fy, E * H / (E + H)
        n = len(fy)
        self.eps, self.ep, self.sig = np.zeros((n, 3)), np.zeros(n), np.zeros((n, 3))

    def trial(self, deps: np.ndarray) -> Trial:
        E, Hp = self.E, self.Hp
        eps = self.eps + deps
        s = E * (eps[:, 0] - self.ep)
        dl = np.maximum(s - (self.fy - Hp * self.ep), 0.0) / (E - Hp)
        sig = np.column_stack([s - E * dl, E * eps[:, 1], E * eps[:, 2]])
        D = np.zeros((len(eps), 3, 3))
        D[:, 0, 0] = np.where(dl > 0, -E * Hp / (E - Hp), E)
        D[:, 1, 1] = D[:, 2, 2] = E
        t = Trial(deps, sig, D)
        t.committed = (eps, self.ep + dl, sig)
        return t

    def commit(self, t: Trial) -> None:
        self.eps, self.ep, self.sig = t.committed

    def checkpoint(self):
        return self.eps, self.ep, self.sig

    def restore(self, saved) -> None:
        self.eps, self.ep, self.sig = saved


def band_width_1d(ell: float, E: float, H: float, length: float, m: float = 1.0) -> float:
    """Width of the loading zone of a bar of ``length`` with the nonlocal inelastic stress of
    share m (docs/fem.md, Regularization, derived there): inside, gbar = a cos(kx) + const with
    (k ell)^2 = H / (m (E + H) - H); outside, gbar = b cosh((L/2 - x)/ell) (natural condition at
    the bar's ends); gbar, gbar' continuous and the strain increment zero at the edge x = w/2
    give tan(k w/2) = -k ell tanh((L/2 - w/2)/ell), the root in (pi/2, pi)."""
    kl = math.sqrt(H / (m * (E + H) - H))
    k = kl / ell
    f = lambda h: math.tan(k * h) + kl * math.tanh((length / 2 - h) / ell)  # noqa: E731
    return 2 * brentq(f, (math.pi / 2 + 1e-9) / k, (math.pi - 1e-12) / k)


def _bar(n: int, ell: float, nonlocal_: bool, E=1e8, fy=1e5, H=2.5e7, length_ells=30, steps=80, m=1.0):
    """A strip one element wide and ``n`` long along y (axis 11), bottom held, top pushed to
    twice the yield strain on average, f_y 5 % weaker in a Gaussian bump of width ell at mid
    length. Returns the Gauss points' y, their strain increment in the last step and the
    elements' mean stress."""
    L = length_ells * ell
    basis = Domain(0.5 * ell, L, 1, n, "q4").basis()
    x, dx = gauss_points(basis)
    mat = BilinearSoftening(fy * (1 - 0.05 * np.exp(-((x[1] - L / 2) / ell) ** 2)), E, H)
    tol = 1e-9 * L
    top = dofs_where(basis, 1, lambda p: p[1] > L - tol)
    fixed = np.unique(np.concatenate([dofs_where(basis, 1, lambda p: p[1] < tol), top,
                                      dofs_where(basis, 0, lambda p: (p[1] < tol) & (p[0] < tol))]))
    g = np.zeros(basis.N)
    g[top] = -2 * fy / E * L
    if nonlocal_:
        pb = NonlocalProblem(basis, mat, fixed, g, np.zeros(basis.N), ell=ell, m=m,
                             D_e=np.tile(np.diag([E, E, E]), (dx.size, 1, 1)))
    else:
        pb = Problem(basis, mat, fixed, g, np.zeros(basis.N))
    last = {}

    def on_step(step, lam):
        last["deps"] = (step.trial.local if nonlocal_ else step.trial).deps[:, 0]
        last["sig"] = step.trial.sig[:, 0]  # the stress in the equilibrium
    out = run_steps(pb, steps, on_step, GlobalNewtonSettings(max_iter=30))
    assert out.stopped is None
    return x[1], last["deps"], last["sig"].reshape(n, -1).mean(axis=1)


def _zero_crossings(y, d):
    """Where the strain increment changes sign along the bar (linear interpolation between
    Gauss points): the edges of the loading zone (loading inside, elastic unloading outside)."""
    o = np.argsort(y, kind="stable")
    y, d = y[o], d[o]
    i = np.flatnonzero(np.sign(d[:-1]) * np.sign(d[1:]) < 0)
    return y[i] - d[i] * (y[i + 1] - y[i]) / (d[i + 1] - d[i])


def test_softening_bar_band_width_matches_the_analytical_one_on_three_meshes():
    """The loading zone of the nonlocal bar has the analytical width (10.7 ell for H/E = 1/4)
    within one element on 60, 120 and 240 elements; the local bar's zone is at most two
    elements wide, shrinking with the mesh (with H/E = 1/100: steeper, its one-element band
    would snap back under the platen's control)."""
    ell, E, H = 1e-3, 1e8, 2.5e7
    w = band_width_1d(ell, E, H, 30 * ell)
    assert w == pytest.approx(2 * ell * math.sqrt(E / H) * (math.pi - math.atan(math.sqrt(H / E))), rel=1e-6)
    widths = []
    for n in (60, 120, 240):
        h = 30 * ell / n
        y, d, s = _bar(n, ell, True)
        z = _zero_crossings(y, d)
        assert len(z) == 2, z  # one loading zone
        widths.append(z[1] - z[0])
        assert abs(widths[-1] - w) <= h
        assert np.ptp(s) < 1e-6 * s.max()  # equilibrium: the same force in every element
        assert 0.05 * 1e5 < s.mean() < 0.5 * 1e5  # far past the peak, softening
    assert np.ptp(widths) <= 30 * ell / 60
    # a smaller nonlocal share narrows the band (6.0 ell at m = 0.5; a bar of 20 ell, so that
    # the narrower band does not snap back)
    w = band_width_1d(ell, E, H, 20 * ell, m=0.5)
    for n in (80, 160):
        y, d, s = _bar(n, ell, True, m=0.5, length_ells=20)
        z = _zero_crossings(y, d)
        assert len(z) == 2 and abs(z[1] - z[0] - w) <= 20 * ell / n, (z, w)
    for n in (30, 60):  # softening mild enough for the local bar not to snap back (L < h (1 + E/H))
        y, d, _ = _bar(n, ell, False, H=1e6)
        loading = np.unique(np.floor(y[d > 0] / (30 * ell / n)))  # elements that still load
        assert 1 <= len(loading) <= 2


def test_regularized_homogeneous_specimen_equals_the_material_point():
    """Smooth platens, no imperfection: gbar = g everywhere, so the regularized FEM follows
    run_biaxial with the same increments (q within 1e-6 of peak q, eps_v within 1e-8), past
    its peak."""
    res = biaxial(SMOOTH, 2e5, 0.05, mesh=(2, 4), n_steps=25, regularization="nonlocal:ell=0.02")
    assert res.stopped is None and res.meta["regularization"] == "nonlocal:ell=0.02"
    c = material_point_curve(res.reference)
    assert np.allclose(res.column("eps11"), c["eps11"])
    assert np.argmax(c["q"]) < len(c["q"]) - 2  # the run goes past the peak
    scale = c["q"].max()
    assert np.abs(res.column("q") - c["q"]).max() / scale < 1e-6
    assert np.abs(res.column("eps_v") - c["eps_v"]).max() < 1e-8


def test_regularized_newton_converges_quadratically_in_an_inhomogeneous_field():
    """The coupled Jacobian is consistent: with an imperfection (gbar differs from g), each
    residual is about the square of the previous one."""
    res = biaxial(SMOOTH, 2e5, 0.03, mesh=(4, 8), n_steps=10, reference=False,
                  imperfection="phi_g=25,alpha0=55@0,0.05,0.01", regularization="nonlocal:ell=0.008")
    assert res.stopped is None
    rates = [np.log(r[2]) / np.log(r[1]) for r in res.residuals if len(r) >= 3 and r[1] < 1e-2 and r[2] > 1e-14]
    assert len(rates) >= 3 and np.median(rates) > 1.7
    sig = res.snapshots[-1].sig
    assert np.ptp(sig[:, 0]) > 1e-3 * sig[:, 0].mean()  # not homogeneous


def _grid(n=120):
    g = (np.arange(n) + 0.5) / n
    X, Y = np.meshgrid(g, g)
    return np.stack([X.ravel(), Y.ravel()]), np.full(n * n, 1.0 / n**2)


@pytest.mark.parametrize("angle", [30.0, 49.0, 62.0])
def test_band_width_of_synthetic_bands(angle):
    """A top-hat strip 0.1 wide and a Gaussian band of FWHM 0.08 through the centre: the
    measured widths within 5 %."""
    x, dx = _grid()
    a = np.radians(angle)
    dist = -(x[0] - 0.5) * np.sin(a) + (x[1] - 0.5) * np.cos(a)
    top_hat = np.where(np.abs(dist) < 0.05, 1.0, 0.02)
    assert band_width(x, top_hat, dx, angle) == pytest.approx(0.1, rel=0.05)
    s = 0.08 / (2 * math.sqrt(2 * math.log(2)))
    assert band_width(x, np.exp(-dist**2 / (2 * s * s)), dx, angle) == pytest.approx(0.08, rel=0.05)
    # the wrong direction gives another width: the measurement depends on the angle
    assert band_width(x, top_hat, dx, angle + 40) > 0.15


def test_parse_regularization_and_bad_input():
    assert str(parse_regularization(None)) == "local"
    assert parse_regularization("nonlocal:ell=0.005").ell == 0.005
    assert parse_regularization("nonlocal:0.002").ell == 0.002
    assert str(parse_regularization("nonlocal:ell=0.005,m=0.2")) == "nonlocal:ell=0.005,m=0.2"
    for bad in ("gradient:ell=1", "nonlocal:ell=0", "nonlocal:ell=-1", "nonlocal", "nonlocal:ell=abc",
                "nonlocal:len=1", "local:ell=1", "nonlocal:ell=1,m=0", "nonlocal:ell=1,m=1.5",
                "nonlocal:m=0.5", "nonlocal:ell=1,ell=2"):
        with pytest.raises(InputError):
            parse_regularization(bad)


def test_cli_regularization_option(tmp_path, capsys):
    out = tmp_path / "reg"
    assert main(["fem", "biaxial", "--axial-strain", "0.004", "--mesh", "1x2", "--steps", "2",
                 "-p", "n_theta=12", "--regularization", "nonlocal:ell=0.06", "--out", str(out)]) == 0
    meta = json.loads((out / "meta.json").read_text())
    assert meta["regularization"] == "nonlocal:ell=0.06" and meta["warnings"] == []
    capsys.readouterr()
    out2 = tmp_path / "unresolved"
    assert main(["fem", "footing", "--settlement", "0.002", "--mesh", "10x5", "--steps", "1", "-p", "n_theta=12",
                 "--regularization", "nonlocal:ell=0.01", "--out", str(out2)]) == 0
    err = capsys.readouterr().err.strip()
    assert err.startswith("hmodel: warning: the nonlocal length ell = 0.01 m is below the element size")
    assert "\n" not in err and (out2 / "result.csv").exists()
    for bad in ("nonlocal:ell=0", "nonlocal:ell=-0.01", "micropolar:ell=0.01", "nonlocal:ell=x"):
        bad_out = tmp_path / "bad"
        assert main(["fem", "biaxial", "--steps", "1", "-p", "n_theta=12", "--regularization", bad,
                     "--out", str(bad_out)]) == 1
        err = capsys.readouterr().err.strip()
        assert err.startswith("hmodel: error:") and "\n" not in err
        assert not bad_out.exists()


def _wave_extra(n: int, m: float):
    """The stress added to the local one by the average, and the derived value, for the strain
    wave cos(k y), k ell = 1, on a strip of n Q4 (a linear law E below D_e = 2E: g = E eps)."""
    E, ell = 1e8, 1.0
    L = 4 * np.pi * ell  # k L = 4 pi: the natural boundary condition admits the cosine
    k = 4 * np.pi / L
    basis = Domain(0.05 * L, L, 1, n, "q4").basis()
    x, dx = gauss_points(basis)
    mat = BilinearSoftening(np.full(dx.size, np.inf), E, 0.5 * E)  # never yields: linear E
    pb = NonlocalProblem(basis, mat, np.array([], int), np.zeros(basis.N), np.zeros(basis.N), ell=ell, m=m,
                         D_e=np.tile(np.diag([2 * E] * 3), (dx.size, 1, 1)))
    du = np.zeros(basis.N)
    ydofs = basis.nodal_dofs[1]
    du[ydofs] = 1e-4 * np.sin(k * basis.doflocs[1, ydofs]) / k  # eps_11 = -1e-4 cos(k y)
    trial, _, _ = pb.evaluate(np.concatenate([du, np.zeros(pb.n_g)]))
    g = E * trial.local.deps
    gbar = spsolve(pb.A3.tocsc(), pb.NtDx @ g.ravel())  # the Helmholtz rows solved
    trial, _, r = pb.evaluate(np.concatenate([du, gbar]))
    assert np.abs(r[pb.n_u:]).max() < 1e-9 * np.abs(pb.NtDx @ g.ravel()).max()
    exact = m * (-1e-4 * E * np.cos(k * x[1])) * (k * ell) ** 2 / (1 + (k * ell) ** 2)
    return (trial.sig - trial.local.sig)[:, 0], exact


@pytest.mark.parametrize("m", [1.0, 0.05])
def test_a_smooth_wave_gets_the_derived_gradient_stiffness(m):
    """docs/fem.md (Regularization, "a gradient term"): for a strain wave cos(k y) the averaged
    inelastic stress is g / (1 + ell^2 k^2), so the stress in the equilibrium exceeds the local
    one by m g ell^2 k^2 / (1 + ell^2 k^2) (here half of m g). The Q4 strain is constant along
    each element, so the computed term converges to the derived one at first order."""
    errors = []
    for n in (120, 240):
        extra, exact = _wave_extra(n, m)
        errors.append(np.abs(extra - exact).max() / np.abs(exact).max())
    assert errors[1] < 0.035
    assert 1.8 < errors[0] / errors[1] < 2.2  # converging to the derived value, not beside it


def test_an_ell_longer_than_the_specimen_is_refused_before_any_work():
    """ell = 1e9 m made the Helmholtz rows singular to double precision: the run "stopped early"
    at step 1 with exit 0. A length above the domain's largest dimension is refused, naming
    both; up to it the regularization is accepted."""
    from hmodel.fem import Domain
    from hmodel.fem.regularization import check_length

    domain = Domain(0.05, 0.1, 1, 2)
    check_length(parse_regularization("nonlocal:ell=0.1"), domain)
    check_length(parse_regularization("local"), domain)
    with pytest.raises(InputError, match=r"ell = 1e\+09 m exceeds the largest dimension of the 0.05 x 0.1 m "
                                         r"domain \(0.1 m\)"):
        biaxial(SMOOTH, 2e5, 0.01, mesh=(1, 2), n_steps=1, regularization="nonlocal:ell=1e9")


def test_a_run_with_no_converged_load_step_is_an_error(tmp_path, capsys, monkeypatch):
    """Only the consolidated state: nothing to report, exit 1 and no output folder (a run that
    stops later keeps its converged steps and exits 0 with a warning)."""
    import hmodel.fem
    from hmodel.fem import Domain, FemResult

    def stopped_at_once(*args, **kwargs):
        return FemResult("biaxial", Domain(0.05, 0.1, 1, 2), ("step",), {"step": np.array([0])}, [], [],
                         np.zeros((2, 0)), np.zeros(0), {"gauss_points": 4, "seconds": 0.0},
                         "step 1 did not converge at axial strain 0 with the step cut 6 times")

    monkeypatch.setattr(hmodel.fem, "biaxial", stopped_at_once)
    out = tmp_path / "o"
    assert main(["fem", "biaxial", "--mesh", "1x2", "-p", "n_theta=12", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err == ("hmodel: error: no load step converged, nothing written: step 1 did not converge at axial "
                   "strain 0 with the step cut 6 times\n")
    assert not out.exists()
