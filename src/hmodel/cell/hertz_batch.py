"""Hertz-Mindlin cells updated together: the secant solve's first pass as vector operations
across the cells of a REV trial (docs/mechanisms.md, "The secant solve").

One cell's Hertz-Mindlin increment (:func:`hmodel.cell.closed_form._hertz_regime`) is a chain
of square roots and divisions, each waiting for the one before: the overlaps' roots from their
forces, the start, the third row's evaluation, the series-reversion step, the law at the
solution; and once more where the cell slides. Cell after cell, a REV trial waits on every
link. The chains of different cells are independent, so :func:`update` runs them in turns,
each over every cell it concerns:

1. per cell, what the committed state and the increment fix (the angle's rows of eq. 1.7 and
   their affine solution for δd2, δα, :func:`hmodel.cell.hertz.affine`), for the cells whose
   two contacts carry (the others, force-free or with one contact at zero force, are left to
   step 5);
2. across them, without branches, the overlaps' roots (:func:`hmodel.cell.hertz.gap_root`)
   and the first pass of the solve without sliding (:func:`hmodel.cell.hertz.first_pass`),
   which the compiler makes a loop of vector operations;
3. per cell, the Coulomb check: the new state of a cell that sticks, the sliding row of one
   that slides;
4. across the sliding cells, the first pass of their solve;
5. per cell, the new state of the sliding cells, that of the force-free cells in closed form
   (:func:`hmodel.cell.hertz.free_regime`), then the one-cell update
   (:func:`hmodel.cell.closed_form.cell_increment_hertz`) of every cell not settled on the way.

Steps 2 and 4 evaluate the one-cell solve's expressions in its order, so every cell's result is
the one-cell update's to the last bit (``tests/test_hertz_batch.py``). No step calls the
one-cell update or the cell's rebirth inside its loop: their code in a loop slowed every cell
of it, taken or not (a cell that opens under ``renewal=rebirth`` takes the one-cell update).
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
    _sliding_force,
    angle_rows,
    cell_increment_hertz,
    finish_update_mech,
    write_update,
)
from .renewal import RENEW_CELL

#: Rows of a work array (:func:`work`): each cell's length increments (the caller's, column i
#: for cell i), then, column j for the j-th carrying cell, its inputs and its first pass's
#: results.
(DL1, DL2, N1, N2, GAP1, GAP2, Q, DA0, W, E0, CA, G, GS, D1, COEF, GT, FLAM, XI, U1, U2, KT,
 X, DD2, DA, F1, F2, SETTLED) = range(27)
ROWS = 27


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
    :func:`hmodel.cell.closed_form.cell_increment_hertz` writes them, the same values to the
    last bit; ``s`` a :func:`work` array. Returns False when a cell's increment failed."""
    index = np.empty((4, values.shape[0]), np.int64)  # carrying, sliding, force-free, others
    carrying, sliding, free, others = index[0], index[1], index[2], index[3]
    m, n_free, n_others = _rows(values, s, p, h, carrying, free, others)
    _stick(s, m, p[P_HERTZ], p[P_MINDLIN])
    # a cell that opens under renewal=rebirth is left to the one-cell update (_write_state)
    rebirth = mech != MECH_NONE and p[P_RENEW] == RENEW_CELL
    ok, n_sliding, n_others = _coulomb(values, s, m, p, out, flags, rebirth, h, carrying, sliding,
                                       others, n_others)
    _slide(s, n_sliding, p[P_HERTZ])
    ok2, n_others = _finish_sliding(values, s, n_sliding, p, out, flags, rebirth, h, sliding,
                                    others, n_others)
    ok &= ok2
    ok3, n_others = _free(values, s, p, out, flags, rebirth, h, free, n_free, others, n_others)
    ok &= ok3
    for j in range(n_others):
        i = others[j]
        ok &= cell_increment_hertz(values, i, s[DL1, i], s[DL2, i], p, out, flags, mech, h)
    return ok


@njit(cache=True, error_model="numpy")
def _rows(values, s, p, h, carrying, free, others):
    """Step 1: what each carrying cell's committed state and increment fix, into column j of
    ``s`` for the j-th (``carrying[j]`` its index); the force-free cells' indices into
    ``free``, the others' into ``others``. Returns the three counts."""
    two_r = 2.0 * p[P_R]
    k = N_FIELDS * h
    m = 0
    n_free = 0
    n_others = 0
    for i in range(values.shape[0]):
        d1 = values[i, k]
        n1 = values[i, k + 3]
        n2 = values[i, k + 4]
        if not (n1 > 0.0 and n2 > 0.0):
            if n1 == 0.0 and n2 == 0.0 and values[i, k + 5] == 0.0:
                free[n_free] = i
                n_free += 1
            else:
                others[n_others] = i
                n_others += 1
            continue
        ca, sa, gs, a11, a13, a21, a23 = angle_rows(d1, values[i, k + 2], p)
        q, da0, w, e0 = hertz.affine(a11, a13, a21, a23, s[DL1, i], s[DL2, i])
        carrying[m] = i
        s[N1, m] = n1
        s[N2, m] = n2
        s[GAP1, m] = two_r - d1
        s[GAP2, m] = two_r - values[i, k + 1]
        s[Q, m] = q
        s[DA0, m] = da0
        s[W, m] = w
        s[E0, m] = e0
        s[CA, m] = ca
        s[G, m] = values[i, k + 5] * ca - n1 * sa
        s[GS, m] = gs
        s[D1, m] = d1
        m += 1
    return m, n_free, n_others


@njit(cache=True, error_model="numpy")
def _stick(s, m, c, mindlin):
    """Step 2, without branches: the overlaps' roots of the first ``m`` columns (Mindlin's
    tangential stiffness from the first) and their first pass without sliding; ``s[SETTLED]``
    1 where it is the solution (the roots' gaps near enough too), else 0."""
    # seven rows written, every one after the reads: the compiler checks at run time that
    # the rows written do not overlap those read, and gives up the vector loop where a write
    # comes between reads or the rows written are more (the overlaps' roots are found again
    # for the few cells that slide)
    for j in range(m):
        n1 = s[N1, j]
        n2 = s[N2, j]
        gap1 = s[GAP1, j]
        gap2 = s[GAP2, j]
        g = s[G, j]
        gs = s[GS, j]
        d1 = s[D1, j]
        da0 = s[DA0, j]
        q = s[Q, j]
        e0 = s[E0, j]
        w = s[W, j]
        ca = s[CA, j]
        y1 = n1 / c  # closed_form.hertz_overlaps, hertz.overlap_root
        y2 = n2 / c
        u1, near1 = hertz.gap_root(y1, gap1)
        u2, near2 = hertz.gap_root(y2, gap2)
        kt = mindlin * 1.5 * c * u1
        gt = g + gs * kt * d1  # closed_form._hertz_regime
        ok, x, dd2, da, f1, f2 = hertz.first_pass(c, u1, u2, n1, n2, da0, q, e0, w, ca, gt, 0.0)
        s[KT, j] = kt
        _store(s, j, ok & near1 & near2 & (y1 > 0.0) & (y2 > 0.0), x, dd2, da, f1, f2)


@njit(cache=True, inline="always", error_model="numpy")
def _store(s, j, ok, x, dd2, da, f1, f2):
    """A first pass's results into column j of ``s``."""
    s[X, j] = x
    s[DD2, j] = dd2
    s[DA, j] = da
    s[F1, j] = f1
    s[F2, j] = f2
    s[SETTLED, j] = 1.0 if ok else 0.0


@njit(cache=True, error_model="numpy")
def _coulomb(values, s, m, p, out, flags, rebirth, h, carrying, sliding, others, n_others):
    """Step 3: each settled cell's Coulomb check (:func:`hmodel.cell.closed_form._hertz_regime`'s):
    the new state of a cell that sticks into ``out`` and ``flags``, the sliding row of one that
    slides into the next sliding column of ``s`` (its index into ``sliding``), the index of a
    cell not settled, or opened under ``renewal=rebirth``, into ``others``. Returns (ok, the
    sliding cells' count, the others').

    The sliding rows overwrite the carrying cells' columns in place: the k-th sliding cell's
    column k is at most the column j of its own first pass, the columns before j are used up by
    then, and column j is read whole before any is written."""
    tanphi = p[P_TAN]
    c = p[P_HERTZ]
    k = N_FIELDS * h
    ok = True
    n_sliding = 0
    for j in range(m):
        i = carrying[j]
        if s[SETTLED, j] == 0.0:
            others[n_others] = i
            n_others += 1
            continue
        d1 = values[i, k]
        t1 = values[i, k + 5]
        da = s[DA, j]
        kt = s[KT, j]
        t1_new = t1 + kt * d1 * da
        xi = 1.0 if t1_new >= 0.0 else -1.0
        if abs(t1_new) >= tanphi * s[F1, j]:  # it slides: eq. 1.7's third row on the cone
            gs = s[GS, j]
            n1 = s[N1, j]
            n2 = s[N2, j]
            u1 = hertz.gap_root(n1 / c, s[GAP1, j])[0]
            u2 = hertz.gap_root(n2 / c, s[GAP2, j])[0]
            coef = s[CA, j] + xi * tanphi * gs
            g = s[G, j]
            q, da0, w, e0 = s[Q, j], s[DA0, j], s[W, j], s[E0, j]
            col = n_sliding
            s[N1, col] = n1
            s[N2, col] = n2
            s[Q, col] = q
            s[DA0, col] = da0
            s[W, col] = w
            s[E0, col] = e0
            s[KT, col] = kt
            s[U1, col] = u1
            s[U2, col] = u2
            s[COEF, col] = coef
            s[GT, col] = g
            s[FLAM, col] = _sliding_force(gs, n1, t1, xi, p)
            s[XI, col] = xi
            sliding[col] = i
            n_sliding += 1
            continue
        written, good = _write_state(values, i, k, h, s[DL1, i], s[DL2, i], s[X, j], s[DD2, j],
                                     da, s[F1, j], s[F2, j], t1_new, False, xi, p, out, flags,
                                     rebirth)
        ok &= good
        if not written:
            others[n_others] = i
            n_others += 1
    return ok, n_sliding, n_others


@njit(cache=True, error_model="numpy")
def _slide(s, m, c):
    """Step 4, without branches: the first pass of the sliding row of the first ``m`` columns;
    ``s[SETTLED]`` 1 where it is the solution, else 0."""
    for j in range(m):
        ok, x, dd2, da, f1, f2 = hertz.first_pass(c, s[U1, j], s[U2, j], s[N1, j], s[N2, j],
                                                  s[DA0, j], s[Q, j], s[E0, j], s[W, j],
                                                  s[COEF, j], s[GT, j], s[FLAM, j])
        _store(s, j, ok, x, dd2, da, f1, f2)


@njit(cache=True, error_model="numpy")
def _finish_sliding(values, s, m, p, out, flags, rebirth, h, sliding, others, n_others):
    """Step 5's first part: the new state of each sliding cell whose row settled (T1 on the
    cone; its columns the first ``m`` of ``s``), the index of the others into ``others``.
    Returns (ok, the others' count)."""
    k = N_FIELDS * h
    ok = True
    for j in range(m):
        i = sliding[j]
        if s[SETTLED, j] == 0.0:
            others[n_others] = i
            n_others += 1
            continue
        da = s[DA, j]
        t1_new = values[i, k + 5] + s[KT, j] * values[i, k] * da
        written, good = _write_state(values, i, k, h, s[DL1, i], s[DL2, i], s[X, j], s[DD2, j],
                                     da, s[F1, j], s[F2, j], t1_new, True, s[XI, j], p, out,
                                     flags, rebirth)
        ok &= good
        if not written:
            others[n_others] = i
            n_others += 1
    return ok, n_others


@njit(cache=True, error_model="numpy")
def _free(values, s, p, out, flags, rebirth, h, free, m, others, n_others):
    """Step 5's second part: the force-free cells (no force, hence no overlap: the open and
    the reborn) in :func:`hmodel.cell.hertz.free_regime`'s closed form, as
    :func:`hmodel.cell.closed_form._hertz_regime` takes it, in a loop of their own; the index
    of a cell it does not apply to, or that opens under ``renewal=rebirth``, into ``others``.
    Returns (ok, the others' count)."""
    c = p[P_HERTZ]
    tanphi = p[P_TAN]
    k = N_FIELDS * h
    ok = True
    for j in range(m):
        i = free[j]
        d1 = values[i, k]
        dl1 = s[DL1, i]
        dl2 = s[DL2, i]
        ca, sa, gs, a11, a13, a21, a23 = angle_rows(d1, values[i, k + 2], p)
        settled, dd1, dd2, da, f1, f2, b1, b2, sliding, coef = hertz.free_regime(
            c, dl1, dl2, a11, a13, a21, a23, ca, tanphi * gs)
        written = False
        if settled:
            written, good = _write_state(values, i, k, h, dl1, dl2, dd1, dd2, da, f1, f2, 0.0,
                                         sliding, 1.0, p, out, flags, rebirth)
            ok &= good
        if not written:
            others[n_others] = i
            n_others += 1
    return ok, n_others


@njit(cache=True, inline="always", error_model="numpy")
def _write_state(values, i, k, h, dl1, dl2, dd1, dd2, da, f1, f2, t1_new, sliding, xi, p, out,
                 flags, rebirth):
    """Cell i's new state from its solution into ``out`` and ``flags`` (as
    :func:`hmodel.cell.closed_form._hertz_update` makes it, without the cell's rebirth):
    ``(written, ok)``; not written where the cell opens under ``renewal=rebirth``
    (``rebirth``), which the one-cell update then makes."""
    r = finish_update_mech(values[i, k], values[i, k + 1], values[i, k + 2], values[i, k + 6],
                           values[i, k + 7], dl1, dl2, dd1, dd2, da, f1, f2, t1_new, sliding, xi,
                           p, MECH_NONE)
    if rebirth and (r[10] or r[11]):
        return False, True
    return True, write_update(r, out, flags, i, k, N_FLAGS * h)
