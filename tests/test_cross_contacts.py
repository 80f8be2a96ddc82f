"""Contacts between the two hexagons of a bi-hexagon (``cross_contacts``, docs/mechanisms.md):
off, the published bi-hexagon bit for bit; on, grain balances and the Love-Weber stress rebuilt
from the ten grain centres as 3D vectors, an energy's finite differences, the mirror symmetry
of equal hexagons, the compiled 3D path, refusals, and the DEM bi-hexagon of spheres."""

import math

import numpy as np
import pytest

from hmodel import Params
from hmodel.cell import BiHexSolver, CellState, ClosedFormSolver
from hmodel.cell.closed_form import hertz_constants
from hmodel.cell.cross import cross_balance
from hmodel.errors import InputError

SOLVER = BiHexSolver()
ON = Params(cross_contacts="frictionless", sliding_rhs="equilibrium")
HERTZ = ON.with_(contact="hertz-mindlin")
A, B = slice(0, 8), slice(8, 16)
# the eight pairs of a grain of A and one of B that face each other (docs/model3d.md's table)
PAIRS = ((2, 7), (2, 10), (3, 8), (3, 9), (6, 7), (6, 10), (5, 8), (5, 9))


def centres(v):
    """Grain centres (docs/model3d.md's table) of the lateral grains of state v (16,)."""
    d2a, l2, d2b, l3 = v[1], v[7], v[9], v[15]
    return {2: np.array([-d2a / 2, l2 / 2, 0.0]), 3: np.array([d2a / 2, l2 / 2, 0.0]),
            6: np.array([-d2a / 2, -l2 / 2, 0.0]), 5: np.array([d2a / 2, -l2 / 2, 0.0]),
            7: np.array([-d2b / 2, 0.0, l3 / 2]), 8: np.array([d2b / 2, 0.0, l3 / 2]),
            10: np.array([-d2b / 2, 0.0, -l3 / 2]), 9: np.array([d2b / 2, 0.0, -l3 / 2])}


def law(p: Params, overlap: float) -> float:
    """Normal force of two grains at ``overlap`` (zero apart): kn δ or Hertz's c δ^(3/2)."""
    if overlap <= 0:
        return 0.0
    if p.contact == "hertz-mindlin":
        return hertz_constants(p)[0] * overlap ** 1.5
    return p.kn * overlap


def cross_forces(p: Params, v):
    """{(i, j): force on j by i} of the eight cross pairs, from the grain centres."""
    x = centres(v)
    out = {}
    for i, j in PAIRS:
        b = x[j] - x[i]
        dist = np.linalg.norm(b)
        out[(i, j)] = law(p, 2 * p.radius - dist) * b / dist
    return out


def cross_on_grain(p: Params, v, grain: int) -> np.ndarray:
    """Sum of the cross forces on ``grain`` (3D vector)."""
    total = np.zeros(3)
    for (i, j), f in cross_forces(p, v).items():
        if j == grain:
            total += f
        if i == grain:
            total -= f
    return total


def loaded_states(p: Params, n=40, steps=25, seed=1, amp=4e-4):
    """Random compressive paths from the unloaded bi-hexagon, each its own δl (d2 of A and B
    apart, cells that slide): the states before and after the last increment, and the flags."""
    rng = np.random.default_rng(seed)
    s = SOLVER.initial(p, (n,))
    l0 = s.values[:, [6, 7, 15]]
    direction = np.column_stack([np.ones(n), rng.uniform(-0.3, 1.0, (n, 2))])  # some slide
    for _ in range(steps):
        dl = -l0 * amp * direction * (1 + 0.3 * rng.random((n, 3)))
        prev = s
        s, f = SOLVER.step(p, s, *dl.T)
    return prev, s, f


def test_off_is_two_2d_cells_bit_for_bit():
    # with cross_contacts none a bi-hexagon is exactly two 2D H-cells sharing dl1
    p = Params(sliding_rhs="equilibrium")
    before, _, _ = loaded_states(p, steps=10)
    rng = np.random.default_rng(7)
    dl = rng.normal(0, 2e-3, (before.values.shape[0], 3))
    after, _ = SOLVER.step(p, before, *dl.T)
    two_d = ClosedFormSolver()
    a, _ = two_d.step(p, CellState(before.values[:, A].copy()), dl[:, 0], dl[:, 1])
    b, _ = two_d.step(p, CellState(before.values[:, B].copy()), dl[:, 0], dl[:, 2])
    np.testing.assert_array_equal(after.values[:, A], a.values)
    np.testing.assert_array_equal(after.values[:, B], b.values)


def test_open_hexagons_that_touch_take_their_2d_increments():
    # Both hexagons open (every contact force zero), their grains overlapping across (α 42.5° <
    # 45°) and d2 - d2_b a round-off apart: the state a calibrated cross variant met in a dense
    # drained test. Their rows have no stiffness (Hertz: no overlap), and nothing holds grain 2
    # along n against the cross pairs, so the pairs transmit nothing along n: the two 2D
    # increments (before, the increment was refused as singular).
    hexagon = [2.028681040555, 2.030853513899, 0.742498542746, 0.0, 0.0, 0.0, 5.020235248237, 2.743390011167]
    v = np.array([hexagon + hexagon])
    v[0, 9] += 1e-12
    dl = (5.268392e-08, 1.4394997e-08, 1.4394997e-08)
    p = HERTZ.with_(radius=1.0)
    assert cross_balance(p.kn, hertz_constants(p)[0], 2.0, v[0, 1] - v[0, 9], v[0, 7], v[0, 15])[0] != 0.0
    after, flags = SOLVER.step(p, CellState(v), *dl)
    two_d = ClosedFormSolver()
    a, _ = two_d.step(p, CellState(v[:, A].copy()), dl[0], dl[1])
    b, _ = two_d.step(p, CellState(v[:, B].copy()), dl[0], dl[2])
    np.testing.assert_array_equal(after.values[:, A], a.values)
    np.testing.assert_array_equal(after.values[:, B], b.values)
    assert flags.flags[0, 10]  # the grains still overlap across: the stress keeps the pairs' forces


@pytest.mark.parametrize("p", [ON, HERTZ], ids=["linear", "hertz"])
def test_grain_balances_with_the_cross_forces_at_the_end_of_the_increment(p):
    # Grain 2's balance along n (eq. 1.5, g2 = 0) with the forces as 3D vectors: from grain 1
    # N1 (cos a, sin a) + T1 (sin a, -cos a), from grain 3 -N2, and the cross forces from grains
    # 7 and 10 at their end-of-increment positions. The closure keeps eq. 1.6 (the balance's
    # differential without the cross forces) plus the exact change of the cross forces at zero,
    # whichever regime the hexagon takes (sliding_rhs=equilibrium, T1' - T1 on the cone).
    before, after, flags = loaded_states(p)
    v0, v1 = before.values, after.values
    checked = sliding = 0
    for c in range(v0.shape[0]):
        for h, grain, axis, fl in ((A, 2, 1, 0), (B, 7, 2, 5)):
            d1, d2, a, n1, n2, t1 = v0[c, h][:6]
            _, _, a1, n1e, n2e, t1e = v1[c, h][:6]
            if flags.flags[c, fl + 1] or flags.flags[c, fl + 2]:
                continue  # an open hexagon carries no force
            eq16 = (math.cos(a) * (n1e - n1) - (n2e - n2) + (t1 * math.cos(a) - n1 * math.sin(a)) * (a1 - a)
                    + math.sin(a) * (t1e - t1))
            dcross = cross_on_grain(p, v1[c], grain)[0] - cross_on_grain(p, v0[c], grain)[0]
            scale = max(abs(n1e), abs(n2e))
            assert abs(eq16 + dcross) <= 1e-9 * scale, (c, grain, eq16, dcross)
            # the cross forces' t2 parts (A) / t1 parts (B) on the lateral grain cancel
            assert abs(cross_on_grain(p, v1[c], grain)[3 - axis]) <= 1e-9 * scale
            checked += 1
            sliding += bool(flags.flags[c, fl])
    assert checked > 40 and sliding > 5
    dcross = [cross_on_grain(p, v1[c], 2)[0] - cross_on_grain(p, v0[c], 2)[0] for c in range(v0.shape[0])]
    # the coupling is exercised: without it the balance would miss by 1000 times the tolerance
    assert max(map(abs, dcross)) > 1e-6 * np.abs(v1[:, [3, 4]]).max()


@pytest.mark.parametrize("p", [ON, HERTZ], ids=["linear", "hertz"])
def test_balance_error_of_an_increment_is_second_order(p):
    # From a state, one increment h and h/2: the change of grain 2's whole balance along n
    # (3D vectors, cross forces included) is eq. 1.6's linearization error, O(h^2), while the
    # cross forces themselves change at O(h): leaving them out, or with the wrong sign, the
    # balance would change at O(h).
    _, s, _ = loaded_states(p, n=12, steps=20)
    dl = -s.values[:, [6, 7, 15]] * np.array([1e-3, 2e-3, 0.5e-3])

    def balance(v, c):
        d1, d2, a, n1, n2, t1 = v[c, :6]
        return n1 * math.cos(a) + t1 * math.sin(a) - n2 + cross_on_grain(p, v[c], 2)[0]

    changes, cross = [], []
    for h in (1.0, 0.5, 0.25):
        e, _ = SOLVER.step(p, s, *(h * dl).T)
        changes.append([balance(e.values, c) - balance(s.values, c) for c in range(12)])
        cross.append([cross_on_grain(p, e.values[c], 2)[0] - cross_on_grain(p, s.values[c], 2)[0]
                      for c in range(12)])
    changes, cross = np.abs(changes), np.abs(cross)
    assert np.all(changes[:-1] / changes[1:] > 3.5)  # second order: a quarter per halving
    ratio = np.median(changes / cross, axis=1)  # the cross term is of lower order
    assert ratio[2] < 0.5 * ratio[0]


@pytest.mark.parametrize("p", [ON, HERTZ], ids=["linear", "hertz"])
def test_stress_is_love_weber_over_the_grain_centres(p):
    # V sigma = sum over the twenty contacts of f (x) b, b = x_j - x_i, f the force on j by i:
    # hexagon A's four type-1 contacts are mirror images of 1-2 (branch d1 (cos a, sin a)),
    # its two type-2 contacts N2 along n over d2; B likewise in (n, t2); the cross pairs from
    # the grain centres.
    _, s, _ = loaded_states(p)
    vs, _ = SOLVER.meso(p, s)
    for c in range(s.values.shape[0]):
        v = s.values[c]
        if min(v[6], v[7], v[15]) <= 2 * p.radius:
            continue  # extra contacts of step 3: not built here
        total = np.zeros((3, 3))
        for h, e in ((A, 1), (B, 2)):
            d1, d2, a, n1, n2, t1 = v[h][:6]
            u = np.zeros(3)
            u[0], u[e] = math.cos(a), math.sin(a)
            tau = np.zeros(3)
            tau[0], tau[e] = math.sin(a), -math.cos(a)
            one = np.outer(n1 * u + t1 * tau, d1 * u)
            for m0 in (1, -1):
                for me in (1, -1):
                    mirror = np.ones(3)
                    mirror[0], mirror[e] = m0, me
                    total += mirror[:, None] * one * mirror[None, :]
            total[0, 0] += 2 * n2 * d2
        x = centres(v)
        for (i, j), f in cross_forces(p, v).items():
            total += np.outer(f, x[j] - x[i])
        voigt = np.array([total[0, 0], total[1, 1], total[2, 2], total[1, 2], total[0, 2], total[0, 1]])
        np.testing.assert_allclose(vs[c], voigt, rtol=1e-12, atol=1e-12 * np.abs(total).max())


@pytest.mark.parametrize("p", [ON, HERTZ], ids=["linear", "hertz"])
def test_cross_stress_is_the_energy_derivative_along_each_length(p):
    # The cross pairs' energy E(l2, l3, D) (8 x (kn/2) d^2, or 8 x (2/5) c d^(5/2)) gives
    # V sigma_kk = -L_k dE/dL_k (L = l2, l3) and V sigma_nn = -D dE/dD: central differences.
    two_r = 2 * p.radius
    c = hertz_constants(p)[0] if p.contact == "hertz-mindlin" else 0.0

    def energy(dd, l2, l3):
        gap = two_r - math.sqrt(0.25 * (dd * dd + l2 * l2 + l3 * l3))
        if gap <= 0:
            return 0.0
        return 8 * (0.4 * c * gap ** 2.5 if c else 0.5 * p.kn * gap * gap)

    v = SOLVER.initial(p).values.copy()
    v[1], v[7], v[15] = 1.99, 2.79, 2.80  # a bi-hexagon whose hexagons overlap, D = d2 - d2_b
    v[9] = 1.97
    vs, _ = SOLVER.meso(p, CellState(v[None]))
    base, _ = SOLVER.meso(p.with_(cross_contacts="none"), CellState(v[None]))
    cross = (vs - base)[0]
    dd, l2, l3 = v[1] - v[9], v[7], v[15]
    h = 1e-6
    fd = [-dd * (energy(dd + h, l2, l3) - energy(dd - h, l2, l3)) / (2 * h),
          -l2 * (energy(dd, l2 + h, l3) - energy(dd, l2 - h, l3)) / (2 * h),
          -l3 * (energy(dd, l2, l3 + h) - energy(dd, l2, l3 - h)) / (2 * h)]
    np.testing.assert_allclose(cross[:3], fd, rtol=1e-6)
    assert cross[1] > 0 and not np.any(cross[3:])
    # and the balance term Y = F D / dc, the n force on each of A's four lateral grains, which
    # move by ±δD/2 when D changes by δD: the work 4 Y δD/2 = -δE, Y = -dE/dD / 2
    y, dy = cross_balance(p.kn, c, two_r, dd, l2, l3)
    assert y == pytest.approx(-(energy(dd + h, l2, l3) - energy(dd - h, l2, l3)) / (2 * h) / 2, rel=1e-6)
    y_fd = (cross_balance(p.kn, c, two_r, dd + h, l2, l3)[0]
            - cross_balance(p.kn, c, two_r, dd - h, l2, l3)[0]) / (2 * h)
    assert dy == pytest.approx(y_fd, rel=1e-6)


@pytest.mark.parametrize("p", [ON, HERTZ], ids=["linear", "hertz"])
def test_equal_hexagons_keep_their_forces_and_add_stress(p):
    # d2 of A = d2 of B and dl2 = dl3: the mirror t1 <-> t2 keeps D = 0, so the cross forces
    # have no n part on the lateral grains and the hexagons' forces are those without cross
    # contacts (the DEM's isotropic path says so too); the stress gains 2 F l^2 / dc per axis.
    off = p.with_(cross_contacts="none")
    s_on = s_off = SOLVER.initial(p, (3,))
    strains = np.array([[1e-3, 1e-3, 1e-3], [2e-3, 1e-3, 1e-3], [1e-3, 1.5e-3, 1.5e-3]])
    dl = -s_on.values[:, [6, 7, 15]] * strains
    for _ in range(15):
        s_on, f_on = SOLVER.step(p, s_on, *dl.T)
        s_off, _ = SOLVER.step(off, s_off, *dl.T)
    np.testing.assert_allclose(s_on.values, s_off.values, rtol=1e-10, atol=1e-12)
    assert f_on.flags[:, -1].all()
    extra = SOLVER.meso(p, s_on)[0] - SOLVER.meso(off, s_off)[0]
    v = s_on.values
    dc = np.sqrt(0.25 * (v[:, 7] ** 2 + v[:, 15] ** 2))
    force = np.array([law(p, 2 * p.radius - d) for d in dc])
    np.testing.assert_allclose(extra[:, 1], 2 * force * v[:, 7] ** 2 / dc, rtol=1e-9)
    np.testing.assert_allclose(extra[:, 0], 0.0, atol=1e-6 * extra[:, 1].max())
    # unequal lateral strains couple them: B's forces move with A's loading
    dl_b = dl.copy()
    dl_b[:, 1] *= 1.5
    u_on, _ = SOLVER.step(p, s_on, *dl_b.T)
    u_off, _ = SOLVER.step(off, s_on, *dl_b.T)
    assert np.all(np.abs(u_on.values[:, 11] - u_off.values[:, 11]) > 1e-6 * np.abs(u_off.values[:, 11]))


def test_compiled_3d_path_equals_the_generic_driver():
    from test_compiled3d import SEGMENTS, SPHERE, _agree
    from test_compiled import _both

    from hmodel.loading import consolidate
    from hmodel.rev import Rev3D

    for p in (ON, HERTZ.with_(renewal="rebirth")):
        rev = Rev3D(p, SPHERE)
        assert consolidate(rev, [2e5]).flags.flags[..., -1].all()  # every cell's hexagons touch
        (sc, rc), (sg, rg) = _both(rev, SEGMENTS["drained"])
        _agree(rc, rg, sc, sg)


def test_refusals_are_one_line():
    from hmodel.rev import Rev, Rev3D

    with pytest.raises(InputError, match="no meaning for a 2D H-cell"):
        Rev(ON)
    with pytest.raises(InputError, match="45 deg"):
        SOLVER.step(ON.with_(alpha0=math.radians(40)), SOLVER.initial(ON), 0.0, 0.0, 0.0)
    with pytest.raises(InputError, match="45 deg"):
        Rev3D(ON.with_(alpha0=math.radians(50), alpha0_spread=0.5))
    with pytest.raises(InputError, match="cross_contacts must be one of"):
        Params(cross_contacts="yes")
    assert "cross_contacts=frictionless" in SOLVER.mechanisms
    assert "cross_contacts=frictionless" not in ClosedFormSolver.mechanisms


def test_the_cross_variant_runs_in_3d_and_is_refused_in_2d(cli, tmp_path):
    from hmodel.variants import get_variant

    assert get_variant("cross").apply(Params()).cross_contacts == "frictionless"
    args = ("--p0", "100e3", "--axial-strain", "0.004", "--order", "9", "--azimuths", "2")
    q = {}
    for model in ("hertz", "cross"):
        out = tmp_path / model
        code, _, err = cli("run", "triaxial", "--model", model, *args, "--out", out)
        assert code == 0, err
        rows = np.genfromtxt(out / "result.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
        q[model] = rows["q"][rows["stage"] == "shear"][-1]
    # the hexagons touch at the default alpha0 = 45 deg as soon as the cells are compressed:
    # the same path with them is another path
    assert q["cross"] != pytest.approx(q["hertz"], rel=1e-4)
    cli.refuses(("run", "biaxial", "--model", "cross", "--out", tmp_path / "2d"), "cross_contacts",
                tmp_path / "2d")


@pytest.mark.yade
def test_dem_bihexagon_with_cross_contacts():
    # The DEM bi-hexagon of spheres with its lateral grains free to touch (friction 30 deg on
    # every contact, the cross pairs included) against the closed form with frictionless cross
    # contacts, on the paths where they touch: isotropic (d2 of A and B equal) and unequal.
    from hmodel.dem.validate3d import validate_bihex

    v = validate_bihex(ON, strain=0.03, steps=15, paths=("isotropic", "unequal"), cross=True)
    rows = {r["path"]: r for r in v.rows if r["cross"]}
    assert rows["isotropic"]["cross_steps"] > 0 and rows["unequal"]["cross_steps"] > 0
    assert rows["isotropic"]["dev_force"] < 2e-3 and rows["isotropic"]["dev_stress"] < 2e-3
    # with d2 of A and B apart the DEM's cross contacts also carry friction, which moves load
    # between t1 and t2 (6 % measured, benchmarks/dem/dem_bihex_cross.json; the published
    # closure misses 122 %): the lateral trace, which frictionless contacts must get, agrees
    k = v.names.index("unequal")
    trace_dem = v.vsig_dem_cross[k][:, 1] + v.vsig_dem_cross[k][:, 2]
    trace_cf = v.vsig_cf[k][:, 1] + v.vsig_cf[k][:, 2]
    assert np.max(np.abs(trace_dem - trace_cf)) < 5e-3 * np.max(trace_dem)
    assert rows["unequal"]["dev_stress"] < 0.1
    # like for like: the DEM's cross contacts frictionless too; then the coupled hexagons match
    # it to the DEM's driving error, where the published closure misses the cross stress
    for setting, bound in (("frictionless", 2e-3), ("none", None)):
        v = validate_bihex(ON.with_(cross_contacts=setting), strain=0.03, steps=15, paths=("unequal",),
                           cross=True, cross_friction=False)
        (row,) = [r for r in v.rows if r["cross"]]
        assert row["cross_steps"] > 0
        if bound:
            assert row["dev_force"] < bound and row["dev_stress"] < bound
        else:
            assert row["dev_stress"] > 0.5
