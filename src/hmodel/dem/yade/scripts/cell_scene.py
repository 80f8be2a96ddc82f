"""Functions shared by the two YADE-side scripts (:mod:`hmodel.dem.yade_script`, batch runs, and
:mod:`hmodel.dem.yade_server`, the persistent process).

Executed by YADE's own Python: the clients (:mod:`hmodel.dem.yade`, :mod:`hmodel.dem.server`)
copy this file next to the script, whose working directory is that folder, and the script
imports it from there. Standard library only; the YADE objects are passed in.

A cell is a dict with ``ids`` (YADE body ids of its grains), ``drive`` (``"n"``, ``"t"`` or
``"free"`` per grain) and ``f_floor`` (mean contact force below which the cell counts as
unloaded); ``owner`` maps a body id to (cell index, local grain index).
"""

import math


def contacts(O, cells, owner):
    """Closed contacts of every cell, one row [i, j, fn, ft, fx, fy, bx, by] per contact.

    i < j local grain indices; f = force on j by i (N), fn = f.e (compression positive),
    ft = f.(e_y, -e_x) with e = b/|b|, b = x_j - x_i (m). Rows sorted by (i, j).
    """
    out = [[] for _ in cells]
    for I in O.interactions:
        if not I.isReal or I.geom.penetrationDepth < 0:  # kept by neverErase but open
            continue
        c, i = owner[I.id1]
        c2, j = owner[I.id2]
        if c != c2:
            continue
        f = I.phys.normalForce + I.phys.shearForce  # force on id2 by id1
        fx, fy = f[0], f[1]
        if i > j:
            i, j, fx, fy = j, i, -fx, -fy
        pi = O.bodies[cells[c]["ids"][i]].state.pos
        pj = O.bodies[cells[c]["ids"][j]].state.pos
        bx, by = pj[0] - pi[0], pj[1] - pi[1]
        norm = math.hypot(bx, by)
        ex, ey = bx / norm, by / norm
        out[c].append([i, j, fx * ex + fy * ey, fx * ey - fy * ex, fx, fy, bx, by])
    return [sorted(o) for o in out]


def unbalanced(O, cell, rows, f_abs=0.0):
    """(ratio, unloaded): max(max |F| on a free DOF - f_abs, 0) / mean |f| over ``rows``.

    ``f_abs`` (N) is the force that round-off alone can cause; ``unloaded`` is True (ratio 0)
    when the mean contact force is at most ``cell["f_floor"]`` (nothing to balance).
    """
    mean_f = sum(math.hypot(c[4], c[5]) for c in rows) / max(len(rows), 1)
    if mean_f <= cell["f_floor"]:
        return 0.0, True
    worst = -f_abs
    for k, bid in enumerate(cell["ids"]):
        f = O.forces.f(bid)
        drive = cell["drive"][k]
        if drive != "n":
            worst = max(worst, abs(f[0]))
        if drive != "t":
            worst = max(worst, abs(f[1]))
    return max(worst, 0.0) / mean_f, False


def steps(O, n):
    """n time steps (O.step() in a loop: O.run(n, True) adds a fixed wait to every call,
    longer than the few steps a balanced cell needs)."""
    for _ in range(n):
        O.step()
