"""Hertz-Mindlin cells updated together (:mod:`hmodel.cell.hertz_batch`): the batch's new
states are the one-cell update's to the last bit, over cells that stick, slide, are force-free
and meet a contact at zero force; its pieces without branches are the one-cell solve's."""

import math

import numpy as np
import pytest

from hmodel import Params
from hmodel.cell import hertz
from hmodel.cell import hertz_batch as hb
from hmodel.cell.closed_form import MECH_ANY, cell_increment_hertz
from hmodel.loading import consolidate
from hmodel.loading.compiled import trial
from hmodel.rev import Rev


def _one_by_one(values, dl, p):
    out = np.empty_like(values)
    flags = np.zeros((len(values), 5), bool)
    ok = [cell_increment_hertz(values, i, dl[i, 0], dl[i, 1], p, out, flags, MECH_ANY, 0)
          for i in range(len(values))]
    return out, flags, np.array(ok)


def _batch(values, dl, p):
    out = np.empty_like(values)
    flags = np.zeros((len(values), 5), bool)
    work = hb.work(len(values))
    work[hb.DL1], work[hb.DL2] = dl[:, 0], dl[:, 1]
    ok = hb.update(values, work, p, out, flags, MECH_ANY, 0)
    carrying = int(((values[:, 3] > 0) & (values[:, 4] > 0)).sum())
    return out, flags, ok, work[hb.SETTLED, :carrying]  # the carrying cells' first pass


@pytest.mark.parametrize("renewal", ["none", "rebirth"])
def test_the_batch_is_the_one_cell_update_to_the_last_bit(renewal):
    """Along a sheared path (cells that stick, slide and open), at each state: random length
    increments of both signs and sizes, the batch against the one-cell update, bit for bit;
    the path must reach cells of every kind, each path of the batch taken."""
    params = Params(contact="hertz-mindlin", n_theta=72, renewal=renewal)
    rev = Rev(params)
    state = consolidate(rev, [2e5])
    geo, p = rev.kernel_inputs()
    geo, p = geo[0], p[0]
    values = np.ascontiguousarray(state.cells.values.reshape(-1, 8))
    rng = np.random.default_rng(5)
    eps = np.zeros(3)
    settled = unsettled = sliding = free = 0
    for step in range(60):
        for scale in (1e-7, 1e-5, 1e-3):
            dl = rng.normal(size=(len(values), 2)) * scale * values[:, 6:8]
            one = _one_by_one(values, dl, p)
            out, flags, ok, done = _batch(values, dl, p)
            assert ok == one[2].all()
            np.testing.assert_array_equal(out, one[0])
            np.testing.assert_array_equal(flags, one[1])
            settled += int(done.sum())
            unsettled += int((done == 0).sum())
        sliding += int(flags[:, 0].sum())
        free += int((values[:, 3] == 0).sum())
        deps = np.array([2e-3, -1.5e-3, 5e-4])
        out = np.empty_like(values)
        flags = np.zeros((len(values), 5), bool)
        trial(values, eps, deps, geo, p, rev.mode, rev.volume0, out, flags, np.empty(3),
              np.empty((len(values), 0)))
        values, eps = out, eps + deps
    assert min(settled, unsettled, sliding, free) > 0, (settled, unsettled, sliding, free)


@pytest.mark.parametrize("y", [1e-30, 2.5e-12, 1.0, 7.3e40])
@pytest.mark.parametrize("rel", [0.0, 1e-12, 1e-7, 5e-5])
def test_the_gap_root_is_the_cube_root_near_the_gap(y, rel):
    """From a gap within 10^-4 of the root's square, gap_root reaches y^(1/3) to round-off
    (checked against the cube of the root) and says it is near; overlap_root returns it."""
    gap = (y ** (2 / 3)) * (1 + rel)
    u, near = hertz.gap_root(y, gap)
    assert near
    assert u * u * u == pytest.approx(y, rel=1e-14)
    assert hertz.overlap_root(y, 1.0, gap) == u


def test_a_far_gap_is_not_near_and_overlap_root_still_finds_the_root():
    y = 8.0
    u, near = hertz.gap_root(y, 9.0)  # the overlap is y^(2/3) = 4
    assert not near
    assert hertz.overlap_root(y, 1.0, 9.0) == pytest.approx(2.0, rel=1e-14)


def test_the_start_corrects_by_the_laws_taylor_series_only_near_the_overlaps():
    """A cell whose contacts move by a small fraction of their overlaps starts off its
    solution by O(s^4) (s the fraction), one whose contact moves by more than half its overlap
    at the tangent start, uncorrected: the row at the two starts."""
    c, u1, u2, coef, gt = 3e10, 1e-3, 1.2e-3, math.cos(1.0), 0.0
    q, da0, w, e0 = hertz.affine(2 * math.cos(1.0), -2e-3 * math.sin(1.0), 2 * math.sin(1.0),
                                 2e-3 * math.cos(1.0), 0.0, 1e-9)
    k2 = 1.5 * c * u2
    tangent = -(k2 * e0 + gt * da0) / (-coef * 1.5 * c * u1 + k2 * w + gt * q)
    x = hertz.start(c, u1, u2, da0, q, e0, w, coef, gt, 0.0)
    n1, n2 = c * u1 ** 3, c * u2 ** 3

    def row(x):
        return hertz._row3(x, c, u1, u2, n1, n2, da0, q, e0, w, coef, gt, 0.0)[0]

    assert x != tangent
    assert abs(row(x)) < 1e-3 * abs(row(tangent))
    # the same increment a million times larger moves a contact beyond half its overlap
    q, da0, w, e0 = hertz.affine(2 * math.cos(1.0), -2e-3 * math.sin(1.0), 2 * math.sin(1.0),
                                 2e-3 * math.cos(1.0), 0.0, 1e-3)
    x = hertz.start(c, u1, u2, da0, q, e0, w, coef, gt, 0.0)
    assert x == -(k2 * e0 + gt * da0) / (-coef * 1.5 * c * u1 + k2 * w + gt * q)


@pytest.mark.parametrize("options", [{}, {"renewal": "rebirth"}, {"lateral": "axisymmetric"}])
def test_the_bihexagons_batch_is_their_one_cell_update_to_the_last_bit(options):
    """The 3D REV's bi-hexagons along a sheared triaxial path, as above: both hexagons of every
    cell at once against bihex_increment cell by cell, bit for bit."""
    from hmodel.cell.bihex import bihex_hertz_increments, bihex_increment
    from hmodel.rev import Rev3D, Sphere
    from hmodel.rev.kernels3d import bihex_trial

    params = Params(contact="hertz-mindlin", sliding_rhs="equilibrium", **options)
    rev = Rev3D(params, Sphere(order=9, n_azimuth=2))
    state = consolidate(rev, [2e5])
    geo, p = rev.kernel_inputs()
    geo, p = geo[0], p[0]
    values = np.ascontiguousarray(state.cells.values.reshape(-1, 16))
    n = len(values)
    rng = np.random.default_rng(7)
    eps = np.zeros(6)
    settled = sliding = free = 0
    for step in range(40):
        for scale in (1e-6, 1e-3):
            dl = rng.normal(size=(n, 3)) * scale * values[:, [6, 7, 15]]
            one, one_flags = np.empty_like(values), np.zeros((n, 11), bool)
            ok_one = all(bihex_increment(values, i, dl[i, 0], dl[i, 1], dl[i, 2], p, one, one_flags,
                                         np.empty((n, 0)), MECH_ANY) for i in range(n))
            out, flags = np.empty_like(values), np.zeros((n, 11), bool)
            work_a, work_b = hb.work(n), hb.work(n)
            work_a[hb.DL1] = work_b[hb.DL1] = dl[:, 0]
            work_a[hb.DL2], work_b[hb.DL2] = dl[:, 1], dl[:, 2]
            assert bihex_hertz_increments(values, work_a, work_b, p, out, flags) == ok_one
            np.testing.assert_array_equal(out, one)
            np.testing.assert_array_equal(flags, one_flags)
            carrying = int(((values[:, 3] > 0) & (values[:, 4] > 0)).sum())  # hexagon A's
            settled += int(work_a[hb.SETTLED, :carrying].sum())
        sliding += int(flags[:, 0].sum() + flags[:, 5].sum())
        free += int((values[:, 3] == 0).sum())
        deps = np.array([1.5e-3, -5e-4, -5e-4, 0.0, 2e-4, 0.0])
        out, flags = np.empty_like(values), np.zeros((n, 11), bool)
        bihex_trial(values, eps, deps, geo, p, rev.mode, rev.volume0, out, flags, np.empty(6))
        values, eps = out, eps + deps
    assert min(settled, sliding, free) > 0, (settled, sliding, free)
