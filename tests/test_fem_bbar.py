"""The B-bar bilinear quadrilateral (``--element q4b``, :func:`hmodel.fem.assembly.bbar`): the
patch test, the mean-dilatation property of its strain operator, and volumetric locking on
Lamé's thick cylinder against the closed-form solution."""

from __future__ import annotations

import numpy as np
import pytest
from skfem import Basis, ElementQuad1, ElementVector, MeshQuad

from hmodel import Params
from hmodel.fem import GlobalNewtonSettings, biaxial
from hmodel.fem.assembly import Operators, internal_force, strain_operator
from hmodel.fem.mesh import dofs_where, gauss_points
from hmodel.fem.newton import Problem, run_steps
from test_fem import EXPECTED, A, LinearElastic, _distorted_basis, _errors, _linear_field


def _vol_dev(eps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """2D volumetric strain eps11 + eps22 and the deviatoric rest (B, 3)."""
    vol = eps[:, 0] + eps[:, 1]
    dev = eps.copy()
    dev[:, :2] -= 0.5 * vol[:, None]
    return vol, dev


def test_bbar_keeps_the_deviator_and_takes_the_element_mean_of_the_dilatation():
    basis = _distorted_basis("q4")
    u = np.random.default_rng(5).normal(size=basis.N) * 1e-3  # not a linear field
    full = (strain_operator(basis) @ u).reshape(-1, 3)
    bar = Operators(basis, b_bar=True).strain(u)
    v_full, d_full = _vol_dev(full)
    v_bar, d_bar = _vol_dev(bar)
    np.testing.assert_allclose(d_bar, d_full, atol=1e-15)
    dx = basis.dx  # (elements, points)
    mean = (v_full.reshape(dx.shape) * dx).sum(axis=1) / dx.sum(axis=1)
    np.testing.assert_allclose(v_bar.reshape(dx.shape), np.repeat(mean[:, None], dx.shape[1], axis=1),
                               atol=1e-15)
    assert np.ptp(v_full.reshape(dx.shape), axis=1).max() > 1e-4  # the full strain's did vary


def test_bbar_patch_test():
    basis = _distorted_basis("q4")
    B = gauss_points(basis)[1].size
    mat = LinearElastic(B, 3e7, 2e7)
    boundary = lambda x: (np.abs(x[0]) < 1e-9) | (np.abs(x[0] - 1) < 1e-9) | (np.abs(x[1]) < 1e-9) | (np.abs(x[1] - 1) < 1e-9)  # noqa: E731
    fixed = np.concatenate([dofs_where(basis, c, boundary) for c in range(2)])
    g = _linear_field(basis, A)
    pb = Problem(basis, mat, fixed, g, internal_force(basis, mat.sig), b_bar=True)
    steps = []
    assert run_steps(pb, 1, lambda s, lam: steps.append(s), GlobalNewtonSettings(rtol=1e-11)).stopped is None
    np.testing.assert_allclose(steps[0].du, g, atol=1e-14)
    np.testing.assert_allclose(pb.ops.strain(steps[0].du), np.tile(EXPECTED, (B, 1)), atol=1e-14)


def _cylinder_pressure(b_bar: bool, nu: float, n: int = 8) -> tuple[float, float]:
    """A quarter of a thick cylinder (radii 1 and 2, plane strain, E = 1) whose inner surface is
    pushed out radially by a = 1e-3, its outer surface free: the inner pressure from the FE
    reactions, and Lamé's (u_r = C1 r + C2 / r with sigma_rr(2) = 0 and u_r(1) = a)."""
    ri, ro, a = 1.0, 2.0, 1e-3
    m = MeshQuad.init_tensor(np.linspace(ri, ro, n + 1), np.linspace(0, np.pi / 2, 2 * n + 1))
    r, t = m.p
    mesh = MeshQuad(np.array([r * np.cos(t), r * np.sin(t)]), m.t)
    basis = Basis(mesh, ElementVector(ElementQuad1()), intorder=2)
    E = 1.0
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    mat = LinearElastic(gauss_points(basis)[1].size, lam, mu)
    rad = lambda x: np.hypot(x[0], x[1])  # noqa: E731
    inner = lambda x: np.abs(rad(x) - ri) < 1e-9  # noqa: E731
    ix, iy = dofs_where(basis, 0, inner), dofs_where(basis, 1, inner)
    sx = dofs_where(basis, 0, lambda x: np.abs(x[0]) < 1e-9)  # symmetry: u_x = 0 on x = 0
    sy = dofs_where(basis, 1, lambda x: np.abs(x[1]) < 1e-9)  # u_y = 0 on y = 0
    g = np.zeros(basis.N)
    g[ix] = a * basis.doflocs[0, ix] / ri  # radially outwards (FE displacements, tension positive)
    g[iy] = a * basis.doflocs[1, iy] / ri
    pb = Problem(basis, mat, np.unique(np.concatenate([ix, iy, sx, sy])), g, np.zeros(basis.N), b_bar=b_bar)
    steps = []
    assert run_steps(pb, 1, lambda s, lam: steps.append(s), GlobalNewtonSettings(rtol=1e-10)).stopped is None
    f = pb.ops.internal_force(mat.sig)  # the committed state's
    # the reactions' radial resultant on the inner arc is p ri pi / 2; radial components leave
    # out the end nodes' reactions along the symmetry planes (the hoop stress across them)
    x, y = basis.doflocs[:, ix]
    p_fe = abs(np.sum(f[ix] * x / ri + f[iy] * y / ri)) / (ri * np.pi / 2)
    c2 = a / (ri + mu * ri / ((lam + mu) * ro ** 2))
    c1 = mu * c2 / ((lam + mu) * ro ** 2)
    p_exact = 2 * mu * c2 / ri ** 2 - 2 * (lam + mu) * c1
    return p_fe, p_exact


def test_bbar_relieves_volumetric_locking_on_lames_cylinder():
    # compressible: both elements close to Lamé on 8 x 16 elements
    for b_bar in (False, True):
        p, exact = _cylinder_pressure(b_bar, 0.3)
        assert abs(p / exact - 1) < 0.005
    # nearly incompressible: the full-integration Q4 locks (five times too stiff), B-bar does not
    p4, exact = _cylinder_pressure(False, 0.4999)
    pb, _ = _cylinder_pressure(True, 0.4999)
    assert abs(pb / exact - 1) < 1e-3
    assert p4 / exact > 3


@pytest.mark.parametrize("undrained", [False, True])
def test_homogeneous_biaxial_q4b_equals_material_point(undrained):
    params = Params(n_theta=36, sliding_rhs="equilibrium")
    res = biaxial(params, 2e5, 0.02, mesh=(2, 4), element="q4b", n_steps=40, undrained=undrained)
    assert res.stopped is None
    eq, ev = _errors(res)
    assert eq.max() < 1e-6 and ev.max() < 1e-8
