"""The script YADE runs (``yade -n -j1 -x yade_script.py INPUT.json OUTPUT.json``).

It is copied as text into a temporary folder by :mod:`hmodel.dem.scene` and executed by YADE's
own Python, so it needs only the standard library and the copied :mod:`hmodel.dem.yade_common` (contact
rows, unbalanced-force ratio, shared with :mod:`hmodel.dem.yade_server`); YADE is imported only
inside :func:`main` (importing this module from hmodel never needs YADE).

Scene. Many independent cells side by side along x, far enough apart never to touch; each
grain is a sphere whose z translation and three rotations are blocked, so the problem is 2D
and grains do not spin. The H-model's tangential displacement kt d1 dalpha (eq. 1.8) is the
relative displacement of the branch vector's ends *without* grain spin; blocking rotations
makes the DEM contact law and eqs. 1.3-1.10 describe the same cell. The cell frame is (n, t) =
(x, y). Contacts: linear springs, Law2_ScGeom_FrictPhys_CundallStrack (Coulomb slider of angle
phi_g); kn and ks = kt_kn kn are set for every pair by MatchMakers (YADE's default, the
harmonic mean 2 E Ra Rb / (Ra + Rb), gives kn = E r only for equal radii r; the H-model's kn
is a contact constant). The shear increment is the tangential part of the relative velocity of
the centres times dt (``avoidGranularRatcheting=False``), so that dT = kt d1 dalpha exactly as in
eq. 1.8. young = kn / r_ref and poisson = kt_kn are also set so that
PWaveTimeStep sees the same stiffness.

Driving. Every cell has its own list of increments (dl1, dl2). In one increment the grains
driven along n move along n by x_n dl1 / l1 (affine in l1 about the cell centre), those driven
along t by x_t dl2 / l2, at constant velocity over ``substeps`` time steps; all other degrees
of freedom are free. Then the scene relaxes (Cundall's non-viscous damping) until, in every
cell, the unbalanced-force ratio max|F_free| / mean|f_contact| <= ``tol`` (F_free: resultant
force on a free degree of freedom); a cell without contact force counts as balanced (its
free grains are stopped). If that takes more than ``max_iter`` time steps the script writes
``status = "no-equilibrium"`` and stops.

Output (JSON): for every cell and every step (0 = initial), grain positions, contacts
``[i, j, fn, ft, fx, fy, bx, by]`` (local grain indices i < j; f = force on j by i, compression
positive fn = f.e with e = b/|b|, ft = f.(e_y, -e_x), b = x_j - x_i), the unbalanced ratio and
the number of relaxation iterations, and the resultant contact force on every grain.
"""

import json
import os
import sys
import time

try:  # from hmodel (tests, docs)
    from .yade_common import contacts, steps, unbalanced
except ImportError:  # in YADE: yade_common.py is copied into the working directory
    sys.path.insert(0, os.getcwd())
    from yade_common import contacts, steps, unbalanced


def _stop_free(O, cell):
    for bid in cell["ids"]:
        O.bodies[bid].state.vel = (0.0, 0.0, 0.0)


def _record(O, cell, origin, contacts, unbalanced, iters):
    pos = []
    for bid in cell["ids"]:
        p = O.bodies[bid].state.pos
        pos.append([p[0] - origin[0], p[1] - origin[1]])
    forces = [[O.forces.f(bid)[0], O.forces.f(bid)[1]] for bid in cell["ids"]]
    return {"pos": pos, "forces": forces, "contacts": contacts, "unbalanced": unbalanced,
            "iterations": iters}


def main(argv):
    from yade import O, utils  # noqa: F401  (YADE's own Python only)
    from yade.wrapper import (FrictMat, ForceResetter, InsertionSortCollider, Bo1_Sphere_Aabb,
                              InteractionLoop, Ig2_Sphere_Sphere_ScGeom,
                              Ip2_FrictMat_FrictMat_FrictPhys, Law2_ScGeom_FrictPhys_CundallStrack,
                              NewtonIntegrator, MatchMaker)

    t0 = time.time()
    with open(argv[0]) as fh:
        spec = json.load(fh)
    kn, kt_kn = spec["kn"], spec["kt_kn"]
    r_ref = spec["r_ref"]
    mat = O.materials.append(FrictMat(young=kn / r_ref, poisson=kt_kn, density=spec["density"],
                                      frictionAngle=spec["phi_g"]))
    cells = spec["cells"]
    owner, owner_cells = {}, []
    x0 = 0.0
    for cell in cells:
        origin = (x0 + cell["half_width"], 0.0, 0.0)
        x0 += 2.0 * cell["half_width"] + spec["gap"]
        cell["_origin"] = origin
        cell["ids"] = []
        for (pn, pt), r, drive in zip(cell["pos"], cell["radii"], cell["drive"]):
            b = utils.sphere((origin[0] + pn, origin[1] + pt, 0.0), r, material=mat)
            # z and every rotation blocked (2D, no spin); driven directions are kinematic.
            b.state.blockedDOFs = "zXYZ" + ("x" if drive == "n" else "y" if drive == "t" else "")
            b.state.mass = spec["mass"]  # mass scaling: one mass for all grains
            cell["ids"].append(O.bodies.append(b))
        for k, bid in enumerate(cell["ids"]):
            owner[bid] = (len(owner_cells), k)
        owner_cells.append(cell)
        cell["f_floor"] = 1e-12 * kn * r_ref
        cell["l"] = [cell["l1"], cell["l2"]]

    enlarge = 1.0 + spec["detect_margin"]
    collider = InsertionSortCollider([Bo1_Sphere_Aabb(aabbEnlargeFactor=enlarge)])
    # avoidGranularRatcheting=False: shear increment = tangential part of (v2 - v1) dt, i.e.
    # d1 dalpha as in eq. 1.8; YADE's default scales it by (r1 + r2) / d1 (McNamara's
    # correction for spinning grains, moot here since rotations are blocked).
    ig2 = Ig2_Sphere_Sphere_ScGeom(interactionDetectionFactor=enlarge, avoidGranularRatcheting=False)
    ip2 = Ip2_FrictMat_FrictMat_FrictPhys(kn=MatchMaker(algo="val", val=kn),
                                          ks=MatchMaker(algo="val", val=kt_kn * kn))
    # neverErase: a contact that opens keeps its interaction with zero force (it is reported
    # as absent); a touching contact created at the detection margin is therefore never lost.
    law = Law2_ScGeom_FrictPhys_CundallStrack(neverErase=True)
    O.engines = [ForceResetter(), collider, InteractionLoop([ig2], [ip2], [law]),
                 NewtonIntegrator(damping=spec["damping"], gravity=(0, 0, 0))]
    O.dt = spec["dt_safety"] * utils.PWaveTimeStep()
    O.step()  # creates the initial contacts at exactly touching distance
    ig2.interactionDetectionFactor = 1.0
    for f in collider.boundDispatcher.functors:
        f.aabbEnlargeFactor = 1.0

    n_steps = max(len(c["increments"]) for c in cells)
    cons = contacts(O, cells, owner)
    records = [[_record(O, c, c["_origin"], cons[k], 0.0, 0)] for k, c in enumerate(cells)]
    substeps, check_every = spec["substeps"], spec["check_every"]
    status, message = "ok", ""
    for step in range(n_steps):
        # 1. kinematic increment of the driven grains (constant velocity over `substeps` steps)
        for cell in cells:
            inc = cell["increments"][step] if step < len(cell["increments"]) else [0.0, 0.0]
            for k, bid in enumerate(cell["ids"]):
                st = O.bodies[bid].state
                axis = {"n": 0, "t": 1}.get(cell["drive"][k])
                if axis is None:
                    continue
                rel = st.pos[axis] - cell["_origin"][axis]
                v = [0.0, 0.0, 0.0]
                v[axis] = rel * inc[axis] / cell["l"][axis] / (substeps * O.dt)
                st.vel = v
            cell["l"] = [cell["l"][0] + inc[0], cell["l"][1] + inc[1]]
        steps(O, substeps)
        for cell in cells:
            for k, bid in enumerate(cell["ids"]):
                if cell["drive"][k] != "free":
                    O.bodies[bid].state.vel = (0.0, 0.0, 0.0)
        # 2. relaxation to the quasi-static state
        iters = 0
        pending = list(range(len(cells)))
        ratios = [0.0] * len(cells)
        while True:
            still = []
            cons = contacts(O, cells, owner)
            for c in pending:
                ratios[c], empty = unbalanced(O, cells[c], cons[c])
                if empty:
                    _stop_free(O, cells[c])
                if ratios[c] > spec["tol"]:
                    still.append(c)
            pending = still
            if not pending or iters >= spec["max_iter"]:
                break
            steps(O, check_every)
            iters += check_every
        if pending:
            status = "no-equilibrium"
            message = (f"equilibrium not reached at step {step + 1} within {spec['max_iter']} "
                       f"iterations (unbalanced force ratio {max(ratios[c] for c in pending):.3g} "
                       f"> {spec['tol']:g} in {len(pending)} cell(s))")
            break
        cons = contacts(O, cells, owner)
        for c, cell in enumerate(cells):
            for bid in cell["ids"]:  # quasi-static: no kinetic energy carried over
                O.bodies[bid].state.vel = (0.0, 0.0, 0.0)
            records[c].append(_record(O, cell, cell["_origin"], cons[c], ratios[c],
                                      iters + substeps))
    result = {"status": status, "message": message, "dt": O.dt, "iterations": O.iter,
              "wall_s": time.time() - t0, "cells": records}
    with open(argv[1] + ".part", "w") as fh:
        json.dump(result, fh)
    os.replace(argv[1] + ".part", argv[1])


if __name__ == "__main__":
    main(sys.argv[1:])
