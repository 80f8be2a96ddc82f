"""The persistent YADE process of the DEM cell solver (``yade -n -j1 -x yade_server.py``).

Copied as text into a temporary folder by :mod:`hmodel.dem.server` and executed by YADE's own
Python, so it needs only the standard library and the copied :mod:`hmodel.dem.yade_common`
(YADE is imported in :func:`main`). It reads one JSON request per line on stdin and answers one line on stdout
prefixed by :data:`MARK` (YADE's own output is ignored by the client); an empty line or EOF
ends it.

A request is *one increment* of many independent cells, each given by its full state: grain
radii, centres (cell frame), drives, current lengths (l1, l2), the increment (dl1, dl2) and the
tangential force ``ft`` of every closed contact (``[i, j, ft]``, sign as in
:mod:`hmodel.dem.yade_script`). The scene is rebuilt from it (``O.reset()``), so the answer is
a function of the request only:

1. grains at their centres, every degree of freedom blocked; one time step creates the
   contacts of touching grains (detection margin ``detect_margin``) with their normal forces
   (the contact law is elastic in the normal direction, so those follow from the positions);
2. the tangential forces are restored (``phys.shearForce = ft (e_y, -e_x)``, e the unit
   branch vector), the detection margin is dropped and the drives of
   :mod:`hmodel.dem.yade_script` apply: driving at constant velocity over ``substeps`` steps,
   then relaxation (Cundall damping) until the unbalanced-force ratio of each cell is <= tol;
3. the criterion is max(|F_free| - f_round, 0) / mean |f| <= tol, with f_round = 1000 eps kn
   |x| the force that round-off of the coordinates x alone can cause (cells sit on a square
   grid centred on the origin); a cell that meets it is frozen at once (all its degrees of freedom blocked), so
   its result does not depend on the other cells of the request.

Contact law, stiffnesses and the shear increment are those of :mod:`hmodel.dem.yade_script`;
contact rows and the unbalanced-force ratio come from :mod:`hmodel.dem.yade_common`.
"""

import json
import math
import os
import sys
import time

try:  # from hmodel (tests, docs)
    from .yade_common import contacts, steps, unbalanced
except ImportError:  # in YADE: yade_common.py is copied into the working directory
    sys.path.insert(0, os.getcwd())
    from yade_common import contacts, steps, unbalanced

MARK = "@@HMODEL-DEM@@ "


def _freeze(O, cell):
    for bid in cell["ids"]:
        b = O.bodies[bid]
        b.state.vel = (0.0, 0.0, 0.0)
        b.state.blockedDOFs = "xyzXYZ"


def solve(req, yade):
    O, utils, w = yade
    O.reset()
    kn, kt_kn, r_ref = req["kn"], req["kt_kn"], req["r_ref"]
    mat = O.materials.append(w.FrictMat(young=kn / r_ref, poisson=kt_kn, density=req["density"],
                                        frictionAngle=req["phi_g"]))
    cells, owner = req["cells"], {}
    # cells on a square grid centred on the origin: small coordinates, small round-off
    pitch = 2.0 * max(max(c["half_width"] for c in cells), max(c["half_height"] for c in cells)) + req["gap"]
    side = int(math.ceil(math.sqrt(len(cells))))
    eps = 2.220446049250313e-16
    for c, cell in enumerate(cells):
        origin = ((c % side - 0.5 * (side - 1)) * pitch, (c // side - 0.5 * (side - 1)) * pitch)
        cell["_origin"] = origin
        # unbalanced force that round-off of the coordinates alone can cause
        cell["f_abs"] = 1e3 * eps * kn * (abs(origin[0]) + abs(origin[1]) + pitch)
        cell["ids"] = []
        for (pn, pt), r in zip(cell["pos"], cell["radii"]):
            b = utils.sphere((origin[0] + pn, origin[1] + pt, 0.0), r, material=mat)
            b.state.blockedDOFs = "xyzXYZ"
            b.state.mass = req["mass"]
            cell["ids"].append(O.bodies.append(b))
        for k, bid in enumerate(cell["ids"]):
            owner[bid] = (c, k)
        cell["f_floor"] = 1e-12 * kn * r_ref
    enlarge = 1.0 + req["detect_margin"]
    collider = w.InsertionSortCollider([w.Bo1_Sphere_Aabb(aabbEnlargeFactor=enlarge)])
    ig2 = w.Ig2_Sphere_Sphere_ScGeom(interactionDetectionFactor=enlarge, avoidGranularRatcheting=False)
    ip2 = w.Ip2_FrictMat_FrictMat_FrictPhys(kn=w.MatchMaker(algo="val", val=kn),
                                            ks=w.MatchMaker(algo="val", val=kt_kn * kn))
    law = w.Law2_ScGeom_FrictPhys_CundallStrack(neverErase=True)
    O.engines = [w.ForceResetter(), collider, w.InteractionLoop([ig2], [ip2], [law]),
                 w.NewtonIntegrator(damping=req["damping"], gravity=(0, 0, 0))]
    O.dt = req["dt"] if req.get("dt") else req["dt_safety"] * utils.PWaveTimeStep()
    O.step()  # contacts of touching grains, nothing moves
    ig2.interactionDetectionFactor = 1.0
    for f in collider.boundDispatcher.functors:
        f.aabbEnlargeFactor = 1.0
    # restore the tangential forces of the closed contacts
    ft = {}
    for c, cell in enumerate(cells):
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
    substeps, dt = req["substeps"], O.dt
    for cell in cells:
        dl = cell["increment"]
        for k, bid in enumerate(cell["ids"]):
            st = O.bodies[bid].state
            drive = cell["drive"][k]
            st.blockedDOFs = "zXYZ" + ("x" if drive == "n" else "y" if drive == "t" else "")
            axis = {"n": 0, "t": 1}.get(drive)
            if axis is None:
                continue
            rel = st.pos[axis] - cell["_origin"][axis]
            v = [0.0, 0.0, 0.0]
            v[axis] = rel * dl[axis] / cell["l"][axis] / (substeps * dt)
            st.vel = v
    steps(O, substeps)
    for cell in cells:
        for k, bid in enumerate(cell["ids"]):
            if cell["drive"][k] != "free":
                O.bodies[bid].state.vel = (0.0, 0.0, 0.0)
    pending = list(range(len(cells)))
    ratios = [0.0] * len(cells)
    iters = [0] * len(cells)
    it = 0
    while True:
        cons = contacts(O, cells, owner)
        still = []
        for c in pending:
            ratios[c] = unbalanced(O, cells[c], cons[c], cells[c]["f_abs"])[0]
            if ratios[c] > req["tol"]:
                still.append(c)
            else:
                _freeze(O, cells[c])
                iters[c] = it
        pending = still
        if not pending or it >= req["max_iter"]:
            break
        steps(O, req["check_every"])
        it += req["check_every"]
    if pending:
        return {"status": "no-equilibrium",
                "message": (f"equilibrium not reached within {req['max_iter']} iterations "
                            f"(unbalanced force ratio {max(ratios[c] for c in pending):.3g} > "
                            f"{req['tol']:g} in {len(pending)} of {len(cells)} cell(s))")}
    out = []
    for c, cell in enumerate(cells):
        pos = [[O.bodies[b].state.pos[0] - cell["_origin"][0], O.bodies[b].state.pos[1] - cell["_origin"][1]]
               for b in cell["ids"]]
        out.append({"pos": pos, "contacts": cons[c], "unbalanced": ratios[c], "iterations": iters[c]})
    return {"status": "ok", "message": "", "dt": O.dt, "cells": out}


def main():
    from yade import O, utils
    import yade.wrapper as w

    stdin = sys.stdin
    write = sys.__stdout__.write
    write(MARK + json.dumps({"status": "ready"}) + "\n")
    sys.__stdout__.flush()
    for line in stdin:
        line = line.strip()
        if not line:
            break
        t0 = time.time()
        try:
            res = solve(json.loads(line), (O, utils, w))
        except Exception as e:  # answered, not fatal: the client raises a one-line error
            res = {"status": "error", "message": f"{type(e).__name__}: {e}".splitlines()[0]}
        res["wall_s"] = time.time() - t0
        write(MARK + json.dumps(res) + "\n")
        sys.__stdout__.flush()


if __name__ == "__main__":
    main()
