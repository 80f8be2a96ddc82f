"""Hertz-Mindlin contacts of the H-cell (``contact="hertz-mindlin"``, docs/mechanisms.md): the
normal law held exactly whatever the increment, grain 2's equilibrium with a stiffness per
contact, the linear law recovered to first order at the tangent stiffness, the exact tangent,
the small-strain stiffness growing as p^(1/3), and the command line."""

import math

import numpy as np
import pytest

from hmodel import Params
from hmodel.cell import ClosedFormSolver
from hmodel.cell.bihex import BiHexSolver
from hmodel.cell.closed_form import (
    P_HERTZ,
    P_MINDLIN,
    cell_update,
    hertz_constants,
    kernel_params,
)
from hmodel.cell.conformance import check_cell_solver
from hmodel.cell.hertz import extra_force
from hmodel.cell.mesostress import contact_vsigma
from hmodel.loading import consolidate
from hmodel.rev import Rev, Rev3D, Sphere

#: Grains of 1 mm, quartz-like (G = 29 GPa, ν = 0.2).
HERTZ = Params(contact="hertz-mindlin", radius=1e-3, shear_modulus=29e9, poisson=0.2,
               sliding_rhs="equilibrium")


def _solver(dim):
    return ClosedFormSolver() if dim == 2 else BiHexSolver()


def _hertz_state(params, delta1, delta2, alpha, t1_cone):
    """A loaded cell (d1, d2, α, N1, N2, T1, l1, l2) at the overlaps delta1, delta2 [m], its
    forces on the law, T1 a fraction ``t1_cone`` of the Coulomb bound."""
    c = hertz_constants(params)[0]
    two_r = 2 * params.radius
    d1, d2 = two_r - delta1, two_r - delta2
    n1, n2 = c * delta1 ** 1.5, c * delta2 ** 1.5
    return (d1, d2, alpha, n1, n2, t1_cone * params.tan_phi * n1, 2 * d1 * math.cos(alpha) + d2,
            2 * d1 * math.sin(alpha))


@pytest.mark.parametrize("n_steps", [400, 2], ids=["many small", "few large"])
def test_every_contact_force_is_hertz_of_its_overlap_whatever_the_step(dim, n_steps):
    """Isotropic compression from unloaded cells (the first increment starts from zero force):
    each contact's force is c δ^(3/2) of its branch length, δ = 2r - d, to 1e-10."""
    solver = _solver(dim)
    params = HERTZ
    c = hertz_constants(params)[0]
    state = solver.initial_cells(params, np.radians([40.0, 50.0, 60.0]))
    lengths = [6, 7] if dim == 2 else [6, 7, 15]
    strain = 2e-3 / n_steps  # 0.2 % of cell strain in all
    for _ in range(n_steps):
        v = state.values
        state, flags = solver.step(params, state, *(-strain * v[:, k] for k in lengths))
    v = state.values
    two_r = 2 * params.radius
    for first in ([0] if dim == 2 else [0, 8]):  # each hexagon's d1, d2 and N1, N2
        for d, n in ((first, first + 3), (first + 1, first + 4)):
            assert np.all(v[:, n] > 0)
            np.testing.assert_allclose(v[:, n], c * (two_r - v[:, d]) ** 1.5, rtol=1e-10, atol=0)


def test_grain_2_is_in_equilibrium_with_the_laws_forces():
    """Eq. 1.6 with a stiffness per contact, in forces: cos α ΔN1 - ΔN2 + (T1 cos α - N1 sin α) δα
    + (g2 + sin α) ΔT1 = 0, where ΔN follows Hertz's law exactly and ΔT1 Mindlin's stiffness or
    the Coulomb cone (the equilibrium λ), on random cells and increments from 1e-4 to 10 times
    the smaller overlap: sticking and sliding both ways."""
    rng = np.random.default_rng(7)
    p = kernel_params(HERTZ)
    regimes = set()
    for _ in range(400):
        delta = rng.uniform(1e-8, 1e-5, 2)
        state = _hertz_state(HERTZ, *delta, rng.uniform(math.radians(32), math.radians(80)),
                             rng.uniform(-1, 1))
        dl = rng.normal(size=2) * delta.min() * 10 ** rng.uniform(-4, 1)
        r = cell_update(*state, *dl, p)
        assert r[0]
        if r[10] or r[11]:
            continue  # an open cell carries nothing
        d1, d2, a, n1, n2, t1 = state[:6]
        ca, sa = math.cos(a), math.sin(a)
        terms = (ca * (r[4] - n1), -(r[5] - n2), (t1 * ca - n1 * sa) * (r[3] - a), sa * (r[6] - t1))
        assert abs(sum(terms)) <= 1e-9 * sum(map(abs, terms)) + 1e-13 * (n1 + n2)
        regimes.add(r[9] and np.sign(r[6]))
    assert regimes == {False, 1.0, -1.0}


def test_at_a_fixed_force_the_law_is_the_linear_one_at_its_tangent_to_first_order():
    """Both contacts at the force N, the Hertz increment agrees with the linear law of
    kn = kn(N) = 3/2 c^(2/3) N^(1/3) and kt_kn = 2(1 - ν)/(2 - ν) to first order: the relative
    difference of the increments halves with the increment."""
    delta = 1e-6
    state = _hertz_state(HERTZ, delta, delta, math.radians(50), 0.2)
    p = kernel_params(HERTZ)
    c, n = p[P_HERTZ], state[3]
    linear = kernel_params(HERTZ.with_(contact="linear", kn=1.5 * c ** (2 / 3) * n ** (1 / 3),
                                       kt_kn=p[P_MINDLIN]))
    errors = []
    for h in (1e-2, 5e-3, 2.5e-3):
        dl = (-h * delta, -0.5 * h * delta)
        a = np.array(cell_update(*state, *dl, p)[1:7]) - state[:6]
        b = np.array(cell_update(*state, *dl, linear)[1:7]) - state[:6]
        scale = np.array([delta, delta, delta / state[0], n, n, n]) * h  # each field's increment
        errors.append(np.max(np.abs(a - b) / scale))
    assert errors[0] < 1e-2
    assert errors[0] / errors[1] == pytest.approx(2.0, rel=0.05)
    assert errors[1] / errors[2] == pytest.approx(2.0, rel=0.05)


def _vsigma(r, params):
    """(V σnn, V σtt) of a cell_update result r, extra contacts of Hertz's law included."""
    c, two_r = hertz_constants(params)[0], 2 * params.radius
    vnn, vtt = contact_vsigma.py_func(r[1], r[2], np.cos(r[3]), np.sin(r[3]), r[4], r[5], r[6])
    if r[7] <= two_r:
        vnn += extra_force.py_func(params.kn, c, two_r - r[7]) * r[7]
    if r[8] <= two_r:
        vtt += 2.0 * extra_force.py_func(params.kn, c, two_r - r[8]) * r[8]
    return np.array([vnn, vtt])


def _cases(params):
    """name -> (state, dl) of each regime of the update."""
    r = params.radius
    a = math.radians(60)
    loaded = _hertz_state(params, 4e-4 * r, 2e-4 * r, a, 0.1)
    squeezed = loaded[:6] + (0.98 * 2 * r, 0.99 * 2 * r)
    opening = (2 * r * (1 + 1e-3),) + loaded[1:3] + (0.0,) + loaded[4:]
    return {
        "sticking": (loaded, (-1e-6 * r, 2e-6 * r)),
        "sliding +": (_hertz_state(params, 4e-4 * r, 2e-4 * r, a, 0.999), None),
        "sliding -": (_hertz_state(params, 4e-4 * r, 2e-4 * r, a, -0.999), None),
        "open": (opening, (1e-5 * r, -1e-5 * r)),
        "over-compressed": (squeezed, (-1e-6 * r, -2e-6 * r)),
    }


@pytest.mark.parametrize("volume", ["hexagon", "hexagon-consistent"])
@pytest.mark.parametrize("regime", ["sticking", "sliding +", "sliding -", "open", "over-compressed"])
def test_cell_jacobian_of_hertz_contacts_is_the_central_difference(volume, regime, jacobian_check):
    params = HERTZ.with_(volume=volume)
    state, dl = _cases(params)[regime]
    jacobian_check(state, dl, regime, kernel_params(params), 2 * params.radius, lambda r: _vsigma(r, params),
                   params.radius * 1e-4, 1e-6)


def test_the_closed_form_cells_of_hertz_contacts_keep_the_solver_contract(dim):
    """The conformance check (the compiled law is step's increment, the exact tangent its
    central difference) with Hertz-Mindlin contacts."""
    check_cell_solver(_solver(dim), HERTZ)


def _bulk_moduli(rev, pressures):
    """Δp/Δεv of an isotropic strain probe of 1e-6 from isotropic states at each pressure."""
    state = consolidate(rev, pressures)
    deps = np.zeros((len(pressures), rev.n_components))
    deps[:, :3 if rev.n_components == 6 else 2] = 1e-6  # the normal components
    after = rev.step(state, deps)
    return (after.p - state.p) / deps.sum(axis=1)


@pytest.mark.parametrize("contact, ratio", [("hertz-mindlin", 4 ** (1 / 3)), ("linear", 1.0)])
def test_small_strain_stiffness_grows_as_p_to_one_third_with_hertz_contacts(dim, contact, ratio):
    """At a fixed fabric kn ∝ N^(1/3) ∝ p^(1/3): the bulk modulus at 400 kPa over that at
    100 kPa is 4^(1/3) = 1.587 with Hertz-Mindlin contacts, 1 with linear ones (within 1 %)."""
    params = HERTZ.with_(contact=contact, radius=1.0)
    rev = Rev(params.with_(n_theta=36)) if dim == 2 else Rev3D(params, Sphere(order=9, n_azimuth=2))
    k100, k400 = _bulk_moduli(rev, [1e5, 4e5])
    assert k400 / k100 == pytest.approx(ratio, rel=0.01)


def test_a_drained_triaxial_test_of_hertz_contacts_runs_from_the_command_line(cli, tmp_path):
    out = tmp_path / "o"
    code, _, err = cli("run", "triaxial", "-p", "contact=hertz-mindlin", "-p", "shear_modulus=29e9",
                       "-p", "poisson=0.2", "--p0", "100e3", "--axial-strain", "0.002", "--order", "9",
                       "--azimuths", "2", "--out", out)
    assert code == 0, err
    rows = np.genfromtxt(out / "result.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    shear = rows[rows["stage"] == "shear"]
    assert shear["eps11"][-1] - shear["eps11"][0] > 0.0019
    np.testing.assert_allclose(shear["sig22"], 1e5, rtol=1e-6)
    assert shear["q"][-1] > 0


def test_a_force_free_cells_increment_is_the_root_of_its_third_row():
    """A force-free cell (open, or reborn at contact) solves eq. 1.7 in closed form
    (:func:`hmodel.cell.hertz.free_solution`); it must be the root of the third row
    coef f(-δd1) - f(-δd2) = 0, f(e) = c e |e|^(1/2), found here independently by bracketing
    (scipy's brentq), on random angles, increments and both regimes' coefficients; and the
    Newton iteration, started off the force-free shortcut (an overlap of 10^-400 m, whose
    square root is not zero), must reach the same δd1."""
    from scipy.optimize import brentq

    from hmodel.cell.closed_form import angle_rows
    from hmodel.cell.hertz import affine, law, solve

    rng = np.random.default_rng(3)
    p = kernel_params(HERTZ)
    c = p[P_HERTZ]
    for _ in range(200):
        a = rng.uniform(math.radians(32), math.radians(80))
        _, _, _, a11, a13, a21, a23 = angle_rows(2 * HERTZ.radius, a, p)
        dl = rng.normal(size=2) * 1e-6 * 10 ** rng.uniform(-3, 1)
        coef = math.cos(a) + rng.choice([0.0, HERTZ.tan_phi * (0.5 + math.sin(a))])
        ok, x, dd2, *_ = solve(c, 0.0, 0.0, 0.0, 0.0, *dl, a11, a13, a21, a23, coef, 0.0, 0.0)
        assert ok
        q, da0, w, e0 = affine(a11, a13, a21, a23, *dl)
        row = lambda y: coef * law(c, -y)[0] - law(c, -(e0 + w * y))[0]  # noqa: E731
        span = 10 * (abs(e0) + abs(x)) + 1e-30
        root = brentq(row, -span, span, xtol=1e-300, rtol=1e-14)
        assert x == pytest.approx(root, rel=1e-12, abs=0)
        assert dd2 == pytest.approx(e0 + w * x, rel=1e-14)
        newton = solve(c, 1e-200, 0.0, 0.0, 0.0, *dl, a11, a13, a21, a23, coef, 0.0, 0.0)
        assert newton[0] and newton[1] == pytest.approx(x, rel=1e-10)


def test_a_force_free_cells_regime_is_the_trials_and_coulombs():
    """The force-free cell's regime without Newton (:func:`hmodel.cell.hertz.free_regime`, the
    Coulomb check by the sign of δd1 without its cube root) against the published rule done
    by hand: the trial without sliding is the root of coef f(-δd1) - f(-δd2) = 0 with coef =
    cos α (brentq); the cell slides iff that trial leaves N1' ≤ 0 (T1' = 0), and then δd1 is
    the root with coef = cos α + tan φ (g2 + sin α). Both regimes must occur."""
    from scipy.optimize import brentq

    from hmodel.cell.closed_form import P_G2, P_TAN, _hertz_regime, angle_rows
    from hmodel.cell.hertz import affine, law

    rng = np.random.default_rng(5)
    p = kernel_params(HERTZ)
    c = p[P_HERTZ]
    two_r = 2 * HERTZ.radius
    seen = set()
    for _ in range(300):
        a = rng.uniform(math.radians(32), math.radians(80))
        d1, d2 = two_r + rng.uniform(0, 1e-5, 2) * rng.integers(0, 2)  # at contact or open
        dl = rng.normal(size=2) * 1e-6 * 10 ** rng.uniform(-3, 1)
        r = _hertz_regime(d1, d2, a, 0.0, 0.0, 0.0, *dl, p)
        assert r[0]
        _, _, _, a11, a13, a21, a23 = angle_rows(d1, a, p)
        q, da0, w, e0 = affine(a11, a13, a21, a23, *dl)

        def root(coef):
            row = lambda y: coef * law(c, -y)[0] - law(c, -(e0 + w * y))[0]  # noqa: E731
            span = 100 * abs(e0) + 1e-30
            return brentq(row, -span, span, xtol=1e-300, rtol=1e-14)

        x = root(math.cos(a))
        sliding = law(c, -x)[0] <= 0.0
        if sliding:
            x = root(math.cos(a) + p[P_TAN] * (p[P_G2] + math.sin(a)))
        assert r[7] == sliding
        assert r[1] == pytest.approx(x, rel=1e-12, abs=0)
        assert r[3] == pytest.approx(da0 + q * x, rel=1e-10, abs=1e-300)
        assert r[6] == 0.0 and r[4] == pytest.approx(law(c, -x)[0], rel=1e-10)
        seen.add(sliding)
    assert seen == {False, True}
