"""Task ``bihex`` (YADE side, see :mod:`hmodel.dem.yade.scripts`): bi-hexagons of spheres, the
3D H-model's cell (docs/model3d.md), each from its state under its own increments of
(l1, l2, l3) (:mod:`hmodel.dem.bihex`: the cell solver ``dem:bihexagon`` and ``hmodel dem
validate --dim 3``).

Scene. Ten spheres per cell, cell frame (n, t1, t2) = (x, y, z): grains 1 and 4 (indices 0, 3)
on n, hexagon A's grains 2, 3, 5, 6 (1, 2, 4, 5) in the plane z = 0, hexagon B's grains 7, 8,
9, 10 (6, 7, 8, 9) in the plane y = 0. Material, contact law, stiffnesses, shear kinematics,
detection margin and time step are the 2D cells' (:mod:`~hmodel.dem.yade.scripts.cell_scene`):
rotations are blocked for the same reason (eq. 1.8's tangential displacement is that of the
branch vector's ends without spin). Each grain's driven axis is kinematic: 1 and 4 along n with
l1, A's grains along t1 with l2, B's along t2 with l3 (affine about the cell centre). Grains 1
and 4 are free across n (as in 2D); a lateral grain is free along n (grain 2's balance, eq. 1.5)
and held in its hexagon's plane, where the mirror symmetry t2 -> -t2 (t1 -> -t1 for B) keeps it:
free, a grain pressed by its two neighbours in the plane would buckle out of it at the first
round-off (its contacts push it further out, nothing pulls it back). With ``cross`` false, A's and B's lateral grains never interact (collision masks:
A 1, B 2, grains 1 and 4 both): the cell of the closure, whose twelve contacts the state holds;
with ``cross`` true they touch where they meet (the closure ignores those contacts), with the
scene's friction, or none where the cell's ``cross_friction`` is false (A's lateral grains, B's
and grains 1 and 4 then have three materials alike but for a MatchMaker that sets the friction
of A-B pairs to zero: the frictionless cross contacts of ``cross_contacts=frictionless``).

Request: the scene's settings (:func:`hmodel.dem.scene.scene_settings`) and ``cells``, each
with ``radii``, ``pos`` (10 rows (n, t1, t2), cell frame), ``drive`` (``"n"``, ``"t1"``,
``"t2"`` per grain), ``l`` = (l1, l2, l3), ``shear`` rows [i, j, fx, fy, fz] (tangential force
on grain j by grain i, i < j, of a closed contact), ``increments`` (S rows (dl1, dl2, dl3), S
the same for every cell), ``cross`` and ``cross_friction``.

1. grains at their centres, every degree of freedom blocked; one time step creates the contacts
   of touching grains with their normal forces, then the tangential forces are restored;
2. per increment: the driven grains move at constant velocity over ``substeps`` time steps,
   then the scene relaxes (each grain free but along its driven axis and, for a lateral grain,
   across its hexagon's plane); a cell is frozen (every degree of freedom blocked, at rest) as soon
   as max(max |F_free| - f_round, 0) / mean |f| <= ``tol`` (f_round = 10^4 eps kn r_ref, a bound
   of the force that round-off of the coordinates can cause, the same for every cell; cells on a
   square grid centred on the origin), so that its answer does not depend on the other cells;
   the next increment frees it.

Answer: for every cell one record per increment: ``pos`` (cell frame), contact rows
[i, j, fn, fx, fy, fz, bx, by, bz] (i < j, f the force on j by i, b = x_j - x_i, fn = f.b/|b|,
compression positive), ``unbalanced``, ``iterations`` (relaxation steps); ``dt``.
``status = "no-equilibrium"`` past ``max_iter`` relaxation steps of an increment.
"""

import math

try:  # pytest collecting the package's doctests
    from .cell_scene import contact_pairs, material, relax, start
    from .common import steps
except ImportError:  # in YADE: the scripts lie side by side in the working directory
    from cell_scene import contact_pairs, material, relax, start
    from common import steps

EPS = 2.220446049250313e-16
AXIS = {"n": 0, "t1": 1, "t2": 2}
#: translations held besides the driven one: a lateral grain stays in its hexagon's plane
HELD = {"n": "", "t1": "z", "t2": "y"}
#: collision masks without cross contacts: YADE lets two bodies interact when masks share a bit
MASK = {"n": 3, "t1": 1, "t2": 2}


def _origins(req):
    """Cell origins on a square grid of the plane z = 0 centred on the origin (small coordinates,
    small round-off); sets each cell's ``f_abs``, the unbalanced force that round-off of the
    coordinates can cause."""
    cells = req["cells"]
    half = max(abs(p[k]) + r for c in cells for p, r in zip(c["pos"], c["radii"]) for k in range(3))
    pitch = 2.0 * half + req["gap"]
    side = int(math.ceil(math.sqrt(len(cells))))
    out = []
    for c, cell in enumerate(cells):
        o = ((c % side - 0.5 * (side - 1)) * pitch, (c // side - 0.5 * (side - 1)) * pitch, 0.0)
        # the same for every cell, so that a cell's answer does not depend on where the request
        # puts it: 1e4 eps kn r bounds by far what round-off of coordinates up to ~100 r causes
        cell["f_abs"] = 1e4 * EPS * req["kn"] * req["r_ref"]
        out.append(o)
    return out


def _build(O, utils, w, req):
    """The grains of every cell, all blocked; engines, time step and the first step. Returns
    ``owner`` (body id -> (cell, local grain))."""
    mat = material(O, w, req)
    # the lateral grains of A and of B, materials of their own where a cell's cross contacts
    # are frictionless (identical to mat but for the A-B pairs' friction)
    lateral = {"n": mat, "t1": mat, "t2": mat}
    if any(c["cross"] and not c.get("cross_friction", True) for c in req["cells"]):
        lateral = {"n": mat, "t1": material(O, w, req), "t2": material(O, w, req)}
        req["frictionless"] = [(lateral["t1"], lateral["t2"])]
    owner = {}
    for c, (cell, o) in enumerate(zip(req["cells"], _origins(req))):
        cell["_origin"] = o
        cell["ids"] = []
        for p, r, drive in zip(cell["pos"], cell["radii"], cell["drive"]):
            own = cell["cross"] and not cell.get("cross_friction", True)
            b = utils.sphere((o[0] + p[0], o[1] + p[1], o[2] + p[2]), r,
                             material=lateral[drive] if own else mat,
                             mask=3 if cell["cross"] else MASK[drive])
            b.state.blockedDOFs = "xyzXYZ"
            b.state.mass = req["mass"]  # mass scaling: one mass for all grains
            owner[O.bodies.append(b)] = (c, len(cell["ids"]))
            cell["ids"].append(b.id)
        cell["f_floor"] = 1e-12 * req["kn"] * req["r_ref"]
    start(O, utils, w, req)
    return owner


def _restore_shear(O, cells):
    """The tangential forces of the closed contacts, from the request's ``shear`` rows."""
    want = {}
    for cell in cells:
        for i, j, fx, fy, fz in cell["shear"]:
            want[(cell["ids"][int(i)], cell["ids"][int(j)])] = (fx, fy, fz)
    for I in O.interactions:
        if not I.isReal or I.geom.penetrationDepth < 0:
            continue
        a, b = (I.id1, I.id2) if I.id1 < I.id2 else (I.id2, I.id1)
        t = want.get((a, b))
        if t is None:
            continue
        s = 1.0 if I.id1 == a else -1.0  # shearForce is the force on id2 by id1
        I.phys.shearForce = (s * t[0], s * t[1], s * t[2])


def _apply(O, cells, k, substeps):
    """Increment k of every cell: the driven grains at constant velocity over ``substeps`` time
    steps, then stopped; the lengths updated."""
    for cell in cells:
        dl = cell["increments"][k]
        for g, bid in enumerate(cell["ids"]):
            st = O.bodies[bid].state
            a = AXIS[cell["drive"][g]]
            st.blockedDOFs = "XYZ" + "xyz"[a] + HELD[cell["drive"][g]]
            v = [0.0, 0.0, 0.0]
            v[a] = (st.pos[a] - cell["_origin"][a]) * dl[a] / cell["l"][a] / (substeps * O.dt)
            st.vel = v
    steps(O, substeps)
    for cell in cells:
        dl = cell["increments"][k]
        cell["l"] = [cell["l"][a] + dl[a] for a in range(3)]
        for bid in cell["ids"]:  # every grain is driven: all stopped, as the 2D cells' driven ones
            O.bodies[bid].state.vel = (0.0, 0.0, 0.0)


def contacts(O, cells, owner):
    """Closed contacts of every cell, rows [i, j, fn, fx, fy, fz, bx, by, bz] sorted by (i, j)
    (see the module docstring)."""
    out = [[] for _ in cells]
    for c, i, j, f, b in contact_pairs(O, cells, owner):
        norm = math.sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2])
        out[c].append([i, j, (f[0] * b[0] + f[1] * b[1] + f[2] * b[2]) / norm] + f + b)
    return [sorted(o) for o in out]


def _unbalanced(O, cell, rows, f_abs):
    """(ratio, unloaded): max(max |F| on a free DOF - f_abs, 0) / mean |f| over ``rows``; ratio
    0 and unloaded for a cell whose mean contact force is at most ``f_floor``."""
    mean_f = sum(math.sqrt(c[3] ** 2 + c[4] ** 2 + c[5] ** 2) for c in rows) / max(len(rows), 1)
    if mean_f <= cell["f_floor"]:
        return 0.0, True
    worst = 0.0
    for g, bid in enumerate(cell["ids"]):
        f = O.forces.f(bid)
        held = (AXIS[cell["drive"][g]], "xyz".find(HELD[cell["drive"][g]] or "-"))
        worst = max([worst] + [abs(f[a]) for a in range(3) if a not in held])
    # a cell loaded by increments of 1e-7 (Newton's finite-difference trials from the unloaded
    # state) carries forces of ~10 N, whose 1e-10 is below what round-off of the coordinates
    # alone causes (kn eps |x| ~ 1e-7 N): without the allowance it never balances
    return max(worst - f_abs, 0.0) / mean_f, False


def run(req):
    """The answer to one request (see the module docstring)."""
    from yade import O, utils
    import yade.wrapper as w

    O.reset()
    cells = req["cells"]
    owner = _build(O, utils, w, req)
    _restore_shear(O, cells)
    records = [[] for _ in cells]
    iters = [0] * len(cells)

    def settle(c, unloaded, it):  # frozen: its answer does not depend on the other cells
        iters[c] = it
        for bid in cells[c]["ids"]:
            st = O.bodies[bid].state
            st.vel = (0.0, 0.0, 0.0)
            st.blockedDOFs = "xyzXYZ"

    for k in range(len(cells[0]["increments"])):
        _apply(O, cells, k, req["substeps"])
        pending, ratios, _, rows = relax(O, cells, owner, req, settle, contacts, _unbalanced)
        if pending:
            return {"status": "no-equilibrium",
                    "message": (f"equilibrium not reached at increment {k + 1} within {req['max_iter']} "
                                f"iterations (unbalanced force ratio {max(ratios[c] for c in pending):.3g} "
                                f"> {req['tol']:g} in {len(pending)} of {len(cells)} bi-hexagon(s))")}
        for c, cell in enumerate(cells):
            o = cell["_origin"]
            pos = [[O.bodies[b].state.pos[a] - o[a] for a in range(3)] for b in cell["ids"]]
            records[c].append({"pos": pos, "contacts": rows[c], "unbalanced": ratios[c],
                               "iterations": iters[c]})
    return {"status": "ok", "message": "", "dt": O.dt, "cells": records}
