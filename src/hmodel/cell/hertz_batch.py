"""Hertz-Mindlin cells updated together: the secant solve's first pass as vector operations
across the cells of a REV trial (docs/mechanisms.md, "The secant solve").

One cell's Hertz-Mindlin increment (:func:`hmodel.cell.closed_form._hertz_regime`) is a chain
of square roots and divisions, each waiting for the one before: the overlaps' roots from their
forces, the start, the third row's evaluation, the series-reversion step, the law at the
solution. Cell after cell, a REV trial waits on every link. The chains of different cells are
independent, so :func:`update` runs them in three loops:

1. per cell (:func:`_rows`), what the committed state and the increment fix: the angle's rows
   of eq. 1.7 and their affine solution for δd2, δα (:func:`hmodel.cell.hertz.affine`);
2. across cells (:func:`_settle`), the part that a loaded contact takes without branching:
   :func:`hmodel.cell.hertz.gap_root`, :func:`~hmodel.cell.hertz.start`, one
   :func:`~hmodel.cell.hertz.newton_pass` and the law at its point, written without branches
   so that the compiler makes the loop one of vector operations;
3. per cell (:func:`_finish`), the Coulomb check and the new state; a cell the second loop did
   not settle (force-free, a contact at zero force, a pass that did not end at the solution)
   or that slides takes the one-cell update instead.

The second loop evaluates the one-cell solve's expressions in its order, so every cell's
result is the one-cell update's to the last bit (``tests/test_hertz_batch.py``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from . import hertz
from .closed_form import (
    MECH_NONE,
    N_FIELDS,
    N_FLAGS,
    P_HERTZ,
    P_MINDLIN,
    P_R,
    P_RENEW,
    P_TAN,
    angle_rows,
    cell_increment_hertz,
    finish_update_mech,
    write_update,
)
from .renewal import RENEW_CELL

#: Rows of the work array (:func:`work`): each cell's length increments (the caller's), then
#: what the first loop fixes, then what the second finds.
(DL1, DL2, N1, N2, GAP1, GAP2, A11, A13, A21, A23, COEF, G, GS, D1,
 X, DD2, DA, F1, F2, KT, SETTLED) = range(21)
ROWS = 21


@njit(cache=True, error_model="numpy")
def work(n):
    """A work array of :func:`update` for ``n`` cells, whose rows DL1 and DL2 the caller fills
    with each cell's length increments (δl1, δl2)."""
    return np.empty((ROWS, n))


@njit(cache=True, error_model="numpy")
def update(values, s, p, out, flags, mech, h):
    """Hexagon ``h`` of every cell of ``values`` (h = 0: an H-cell, or a bi-hexagon's hexagon A;
    1: its hexagon B) by its length increments ``s[DL1]``, ``s[DL2]`` with Hertz-Mindlin
    contacts: the new states into ``out`` and ``flags`` as
    :func:`hmodel.cell.closed_form.cell_increment_prepared` writes them, the same values to the
    last bit; ``s`` a :func:`work` array. Returns False when a cell's increment failed."""
    _rows(values, s, p, h)
    _settle(s, p[P_HERTZ], p[P_MINDLIN])
    return _finish(values, s, p, out, flags, mech, h)


@njit(cache=True, error_model="numpy")
def _rows(values, s, p, h):
    """The first loop: what each cell's committed state and increment fix, into ``s``."""
    two_r = 2.0 * p[P_R]
    k = N_FIELDS * h
    for i in range(values.shape[0]):
        d1 = values[i, k]
        n1 = values[i, k + 3]
        ca, sa, gs, a11, a13, a21, a23 = angle_rows(d1, values[i, k + 2], p)
        s[N1, i] = n1
        s[N2, i] = values[i, k + 4]
        s[GAP1, i] = two_r - d1
        s[GAP2, i] = two_r - values[i, k + 1]
        s[A11, i] = a11
        s[A13, i] = a13
        s[A21, i] = a21
        s[A23, i] = a23
        s[COEF, i] = ca
        s[G, i] = values[i, k + 5] * ca - n1 * sa
        s[GS, i] = gs
        s[D1, i] = d1


@njit(cache=True, error_model="numpy")
def _settle(s, c, mindlin):
    """The second loop, without branches: each sticking cell's solution where one pass of the
    solve from its start reaches it (``s[SETTLED]`` 1, else 0)."""
    for i in range(s.shape[1]):
        n1 = s[N1, i]
        n2 = s[N2, i]
        y1 = n1 / c
        y2 = n2 / c
        u1, near1 = hertz.gap_root(y1, s[GAP1, i])
        u2, near2 = hertz.gap_root(y2, s[GAP2, i])
        q, da0, w, e0 = hertz.affine(s[A11, i], s[A13, i], s[A21, i], s[A23, i], s[DL1, i],
                                     s[DL2, i])
        coef = s[COEF, i]
        kt = mindlin * 1.5 * c * u1  # closed_form.hertz_overlaps
        gt = s[G, i] + s[GS, i] * kt * s[D1, i]
        x = hertz.start(c, u1, u2, da0, q, e0, w, coef, gt, 0.0)
        done, finite, settled, x_next, dd2, da, f1, f2, b1, b2 = hertz.newton_pass(
            x, c, u1, u2, n1, n2, da0, q, e0, w, coef, gt, 0.0, hertz.FORCE_EPS * (n1 + n2))
        x = x if done else x_next
        dd2, da, f1, f2, b1, b2 = hertz.state_at(x, c, u1, u2, da0, q, e0, w)
        s[X, i] = x
        s[DD2, i] = dd2
        s[DA, i] = da
        s[F1, i] = f1
        s[F2, i] = f2
        s[KT, i] = kt
        ok = (y1 > 0.0) & (y2 > 0.0) & near1 & near2 & (done | (finite & settled))
        s[SETTLED, i] = 1.0 if ok else 0.0


@njit(cache=True, error_model="numpy")
def _finish(values, s, p, out, flags, mech, h):
    """The third loop: the Coulomb check and the new state of each settled cell that sticks;
    then the one-cell update for the others (in a loop of their own: the one-cell update's code
    in the first loop slowed every cell of it)."""
    tanphi = p[P_TAN]
    rebirth = mech != MECH_NONE and p[P_RENEW] == RENEW_CELL
    k = N_FIELDS * h
    ok = True
    others = np.empty(values.shape[0], np.int64)
    n_others = 0
    for i in range(values.shape[0]):
        d1 = values[i, k]
        da = s[DA, i]
        f1 = s[F1, i]
        t1_new = values[i, k + 5] + s[KT, i] * d1 * da
        # _hertz_regime's check: a settled cell sticks
        if s[SETTLED, i] == 0.0 or abs(t1_new) >= tanphi * f1:
            others[n_others] = i
            n_others += 1
            continue
        # the new state without renewal=rebirth, whose call in this loop slowed every cell of
        # it: a cell that opens under it takes the one-cell update below
        r = finish_update_mech(d1, values[i, k + 1], values[i, k + 2], values[i, k + 6],
                               values[i, k + 7], s[DL1, i], s[DL2, i], s[X, i], s[DD2, i], da, f1,
                               s[F2, i], t1_new, False, 1.0 if t1_new >= 0.0 else -1.0, p,
                               MECH_NONE)
        if rebirth and (r[10] or r[11]):
            others[n_others] = i
            n_others += 1
            continue
        ok &= write_update(r, out, flags, i, k, N_FLAGS * h)
    for j in range(n_others):
        i = others[j]
        ok &= cell_increment_hertz(values, i, s[DL1, i], s[DL2, i], p, out, flags, mech, h)
    return ok
