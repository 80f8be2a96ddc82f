"""Task ``increment`` (YADE side, see :mod:`hmodel.dem.yade.scripts`): one increment of many
independent cells, each given by its full state (the DEM cell solver, :mod:`hmodel.dem.solver`).

Request: the scene's settings (:func:`hmodel.dem.scene.scene_settings`) and ``cells``, each
with grain ``radii``, centres ``pos`` (cell frame), ``drive``, current lengths ``l`` = (l1, l2),
``half_width``, ``half_height``, the ``increment`` (dl1, dl2) and the tangential force of every
closed contact, ``shear`` = ``[i, j, ft]`` (sign as in
:func:`~hmodel.dem.yade.scripts.cell_scene.contacts`). The scene is rebuilt from it, so the
answer is a function of the request only:

1. grains at their centres, every degree of freedom blocked; one time step creates the
   contacts of touching grains with their normal forces (the contact law is elastic in the
   normal direction, so those follow from the positions);
2. the tangential forces are restored (``phys.shearForce = ft (e_y, -e_x)``, e the unit
   branch vector) and the cell is driven and relaxed as in
   :mod:`~hmodel.dem.yade.scripts.cell_scene`;
3. the criterion is max(|F_free| - f_round, 0) / mean |f| <= tol, with f_round = 1000 eps kn
   |x| the force that round-off of the coordinates x alone can cause (cells sit on a square
   grid centred on the origin); a cell that meets it is frozen at once (all its degrees of
   freedom blocked), so its result does not depend on the other cells of the request.

Answer: for every cell its grain positions, contact rows, unbalanced-force ratio and the
relaxation steps it took; ``dt``. ``status = "no-equilibrium"`` past ``max_iter`` steps.
"""

import math

try:  # pytest collecting the package's doctests
    from .cell_scene import apply, blocked_dofs, build, relax
except ImportError:  # in YADE: the scripts lie side by side in the working directory
    from cell_scene import apply, blocked_dofs, build, relax

EPS = 2.220446049250313e-16


def _grid(req):
    """Cell origins on a square grid centred on the origin: small coordinates, small round-off;
    sets each cell's ``f_abs``, the unbalanced force that round-off of its coordinates can cause."""
    cells = req["cells"]
    pitch = 2.0 * max(max(c["half_width"] for c in cells), max(c["half_height"] for c in cells)) + req["gap"]
    side = int(math.ceil(math.sqrt(len(cells))))
    origins = []
    for c, cell in enumerate(cells):
        origin = ((c % side - 0.5 * (side - 1)) * pitch, (c // side - 0.5 * (side - 1)) * pitch)
        cell["f_abs"] = 1e3 * EPS * req["kn"] * (abs(origin[0]) + abs(origin[1]) + pitch)
        origins.append(origin)
    return origins


def _restore_shear(O, cells):
    """The tangential forces of the closed contacts, from the request's ``shear`` rows."""
    ft = {}
    for cell in cells:
        for i, j, t in cell["shear"]:
            ft[(cell["ids"][int(i)], cell["ids"][int(j)])] = t
    for I in O.interactions:
        if not I.isReal or I.geom.penetrationDepth < 0:
            continue
        a, b = (I.id1, I.id2) if I.id1 < I.id2 else (I.id2, I.id1)
        t = ft.get((a, b))
        if not t:
            continue
        pa, pb = O.bodies[a].state.pos, O.bodies[b].state.pos
        bx, by = pb[0] - pa[0], pb[1] - pa[1]
        norm = math.hypot(bx, by)
        sx, sy = t * by / norm, -t * bx / norm  # ft (e_y, -e_x): force on b by a
        if I.id1 != a:
            sx, sy = -sx, -sy
        I.phys.shearForce = (sx, sy, 0.0)


def run(req):
    """The answer to one request (see the module docstring)."""
    from yade import O, utils
    import yade.wrapper as w

    O.reset()
    cells = req["cells"]
    owner = build(O, utils, w, req, _grid(req), lambda drive: "xyzXYZ")
    _restore_shear(O, cells)
    for cell in cells:
        for k, bid in enumerate(cell["ids"]):
            O.bodies[bid].state.blockedDOFs = blocked_dofs(cell["drive"][k])
    apply(O, cells, [c["increment"] for c in cells], req["substeps"])
    iters = [0] * len(cells)

    def settle(c, unloaded, it):
        for bid in cells[c]["ids"]:
            b = O.bodies[bid]
            b.state.vel = (0.0, 0.0, 0.0)
            b.state.blockedDOFs = "xyzXYZ"
        iters[c] = it

    pending, ratios, _, cons = relax(O, cells, owner, req, settle)
    if pending:
        return {"status": "no-equilibrium",
                "message": (f"equilibrium not reached within {req['max_iter']} iterations "
                            f"(unbalanced force ratio {max(ratios[c] for c in pending):.3g} > "
                            f"{req['tol']:g} in {len(pending)} of {len(cells)} cell(s))")}
    out = []
    for c, cell in enumerate(cells):
        origin = cell["_origin"]
        pos = [[O.bodies[b].state.pos[0] - origin[0], O.bodies[b].state.pos[1] - origin[1]]
               for b in cell["ids"]]
        out.append({"pos": pos, "contacts": cons[c], "unbalanced": ratios[c], "iterations": iters[c]})
    return {"status": "ok", "message": "", "dt": O.dt, "cells": out}
