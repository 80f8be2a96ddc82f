"""The rebirth of opened cells (``renewal="rebirth"``, docs/mechanisms.md "Renewal").

Checked against independent constructions: the unloaded cells' volumes of
:mod:`hmodel.rev.density` (the REV's own meso-volumes), the regular hexagon's area by hand, and
a run without the mechanism (the increment before a rebirth is the published one).
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hmodel import Params
from hmodel.cell.bihex import BiHexSolver, initial_bihex
from hmodel.cell.closed_form import ClosedFormSolver
from hmodel.cell.renewal import (BRANCH_2D, BRANCH_3D, hexagon_volume, rebirth_angle,
                                 unloaded_volume)
from hmodel.cell.state import CellState
from hmodel.loading.lab_tests import run_biaxial, run_triaxial
from hmodel.rev.density import initial_volume, loosest_alpha0

R = 0.7  # a radius other than 1: the formulas must carry it


def test_regular_hexagon_by_hand():
    # six grain centres 2r apart at 60°: a regular hexagon of side 2r, area 3√3/2 (2r)²
    assert unloaded_volume(math.pi / 3, 2 * R, 2) == pytest.approx(1.5 * math.sqrt(3) * (2 * R) ** 2, rel=1e-14)
    assert hexagon_volume(2 * R, 2 * R, math.pi / 3) == pytest.approx(1.5 * math.sqrt(3) * (2 * R) ** 2, rel=1e-14)


@pytest.mark.parametrize("a_deg", [35.0, 45.0, 55.0, 60.0, 68.0])
def test_unloaded_volume_is_the_revs(dim, a_deg):
    """The rebirth's volume of an unloaded cell is the REV's meso-volume of that cell (``hexagon``
    option), computed by the cells' own code (eqs. 1.20-1.21, the bi-hexagon's l1*·l2*·l3*)."""
    if dim == 2 and a_deg > 60:
        pytest.skip("past the 2D branch")
    p = Params(radius=R, alpha0=math.radians(a_deg), n_theta=8)
    assert unloaded_volume(math.radians(a_deg), 2 * R, dim) == pytest.approx(initial_volume(p, dim), rel=1e-12)


def test_branch_ends_are_the_loosest_cells(dim):
    branch = BRANCH_2D if dim == 2 else BRANCH_3D
    assert branch[1] == pytest.approx(loosest_alpha0(Params(radius=R, n_theta=8), dim), abs=1e-6)


@settings(max_examples=60, deadline=None)
@given(f=st.floats(0.0, 1.0), dim=st.sampled_from([2, 3]))
def test_rebirth_angle_inverts_the_volume(f, dim):
    lo, hi = BRANCH_2D if dim == 2 else BRANCH_3D
    a = lo + f * (hi - lo)
    v = unloaded_volume(a, 2 * R, dim)
    back = rebirth_angle(v, 2 * R, dim)
    assert unloaded_volume(back, 2 * R, dim) == pytest.approx(v, rel=1e-13)
    if f < 0.99:  # at the loosest cell the volume is flat in α: only the volume is determined
        assert back == pytest.approx(a, abs=1e-9)


def test_rebirth_angle_outside_the_branch(dim):
    lo, hi = BRANCH_2D if dim == 2 else BRANCH_3D
    assert rebirth_angle(1.0001 * unloaded_volume(hi, 2 * R, dim), 2 * R, dim) == -1.0  # no cell fits
    assert rebirth_angle(0.5 * unloaded_volume(lo, 2 * R, dim), 2 * R, dim) == lo  # the densest


def _opening_increment():
    """A loaded H-cell and an increment that opens its contacts (a stretch along n)."""
    p = Params(radius=R, alpha0=math.radians(50))
    s = ClosedFormSolver()
    state, _ = s.step(p, s.initial(p, (1,)), -1e-3, -1e-3)  # loaded by compression
    return p, s, state, 5e-3, 0.0


def test_reborn_cell_conserves_the_volume_it_held():
    p, s, state, dl1, dl2 = _opening_increment()
    before, flags = s.step(p, state, dl1, dl2)
    assert flags.flags[0, 1] or flags.flags[0, 2]  # it opened (published: force-free from now on)
    after, _ = s.step(p.with_(renewal="rebirth"), state, dl1, dl2)
    d1, d2, a, n1, n2, t1, l1, l2 = after.values[0]
    assert (d1, d2, n1, n2, t1) == (2 * R, 2 * R, 0.0, 0.0, 0.0)  # at contact, force-free
    held = hexagon_volume(*before.values[0, :3])
    assert unloaded_volume(a, 2 * R, 2) == pytest.approx(held, rel=1e-12)
    assert (l1, l2) == pytest.approx((2 * R * (1 + 2 * math.cos(a)), 4 * R * math.sin(a)), rel=1e-14)  # eq. 1.2


def test_a_carrying_cell_is_not_reborn():
    p = Params(radius=R, alpha0=math.radians(50))
    s = ClosedFormSolver()
    state = s.initial(p, (1,))
    a, _ = s.step(p, state, -1e-3, -2e-3)
    b, _ = s.step(p.with_(renewal="rebirth"), state, -1e-3, -2e-3)
    assert np.array_equal(a.values, b.values)


def test_bihexagon_is_reborn_only_when_both_hexagons_are_open():
    p = Params(radius=R, alpha0=math.radians(55), sliding_rhs="equilibrium")
    s = BiHexSolver()
    state, _ = s.step(p, initial_bihex(p, np.array([p.alpha0])), -1e-3, -1e-3, -1e-3)
    # hexagon A stretched open along t1 only (l1 and l3 held): B keeps its forces, no rebirth
    one, f1 = s.step(p, state, 0.0, 5e-2, 0.0)
    one_r, _ = s.step(p.with_(renewal="rebirth"), state, 0.0, 5e-2, 0.0)
    assert (f1.flags[0, 1] or f1.flags[0, 2]) and not (f1.flags[0, 6] or f1.flags[0, 7])
    assert np.array_equal(one.values, one_r.values)
    # stretched along n: both open, both reborn at one angle, force-free, volume kept
    both, f2 = s.step(p, state, 5e-2, 0.0, 0.0)
    assert (f2.flags[0, 1] or f2.flags[0, 2]) and (f2.flags[0, 6] or f2.flags[0, 7])
    reborn, _ = s.step(p.with_(renewal="rebirth"), state, 5e-2, 0.0, 0.0)
    v = reborn.values[0]
    assert v[2] == v[10] and np.all(v[[3, 4, 5, 11, 12, 13]] == 0.0) and np.all(v[[0, 1, 8, 9]] == 2 * R)
    held = float(bihex_volume_of(p, both.values))
    assert unloaded_volume(v[2], 2 * R, 3) == pytest.approx(held, rel=1e-12)


def bihex_volume_of(params, values):
    from hmodel.cell.bihex import bihex_volume
    return bihex_volume(params.with_(volume="hexagon"), values)[0]


def test_rebirth_keeps_the_stress_continuous():
    """A reborn cell carried nothing before (it had opened) and carries nothing when reborn: the
    stress of every increment is the published one's until the reborn cells load again."""
    p = Params(alpha0=math.radians(40), n_theta=36, sliding_rhs="equilibrium")
    off = run_biaxial(p, 100e3, 0.2, step=2e-3)
    on = run_biaxial(p.with_(renewal="rebirth"), 100e3, 0.2, step=2e-3)
    first = np.flatnonzero(off["frac_open"] > 0)[0]
    assert np.array_equal(off["q"][: first + 1], on["q"][: first + 1])  # the increment that opens
    assert not np.array_equal(off["q"], on["q"])  # and the mechanism acts after it


def test_rebirth_runs_in_3d():
    p = Params(alpha0=math.radians(55), sliding_rhs="equilibrium")
    r = run_triaxial(p.with_(renewal="rebirth"), 100e3, 0.05, step=2e-3)
    assert np.all(np.isfinite(r["q"]))
