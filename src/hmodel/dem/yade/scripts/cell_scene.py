"""Many independent H-model cells in one YADE scene (YADE side, see
:mod:`hmodel.dem.yade.scripts`): set-up, driving, relaxation, contact rows; shared by the tasks
``runs`` (:mod:`~hmodel.dem.yade.scripts.cell_runs`) and ``increment``
(:mod:`~hmodel.dem.yade.scripts.cell_increment`).

Scene. The cells lie side by side where the task places them, far enough apart never to touch;
each grain is a sphere whose z translation and three rotations are blocked, so the problem is
2D and grains do not spin. The H-model's tangential displacement kt d1 dalpha (eq. 1.8) is the
relative displacement of the branch vector's ends *without* grain spin; blocking rotations
makes the DEM contact law and eqs. 1.3-1.10 describe the same cell. The cell frame is (n, t) =
(x, y). Contacts: linear springs, Law2_ScGeom_FrictPhys_CundallStrack (Coulomb slider of angle
phi_g), kn and ks = kt_kn kn for every pair (:func:`~hmodel.dem.yade.scripts.common.stiffness`).
The shear increment is the tangential part of the relative velocity of the centres times dt
(``avoidGranularRatcheting=False``), so that dT = kt d1 dalpha exactly as in eq. 1.8. young =
kn / r_ref and poisson = kt_kn are also set so that PWaveTimeStep sees the same stiffness; every
grain has the mass ``mass``, dt = dt_safety PWaveTimeStep.

Driving. In one increment (dl1, dl2) the grains driven along n move along n by x_n dl1 / l1
(affine in l1 about the cell centre), those driven along t by x_t dl2 / l2, at constant velocity
over ``substeps`` time steps; all other degrees of freedom are free. Then the scene relaxes
(Cundall's non-viscous damping) until, in every cell, the unbalanced-force ratio
max|F_free| / mean|f_contact| <= ``tol`` (F_free: resultant force on a free degree of freedom),
checked every ``check_every`` steps, at most ``max_iter`` steps.

A cell is a dict of its request (``pos``, ``radii``, ``drive`` per grain: ``"n"``, ``"t"`` or
``"free"``, ``l`` = (l1, l2)) to which :func:`build` adds ``ids`` (YADE body ids of its grains),
``_origin`` and ``f_floor`` (mean contact force below which the cell counts as unloaded);
``owner`` maps a body id to (cell index, local grain index).
"""

import math

try:  # pytest collecting the package's doctests
    from .common import steps, stiffness
except ImportError:  # in YADE: the scripts lie side by side in the working directory
    from common import steps, stiffness


def build(O, utils, w, spec, origins, blocked):
    """Material, the grains of every cell of ``spec["cells"]`` at its origin (2-tuple, m), engines
    and time step, then one time step that creates the contacts of touching grains.

    ``blocked(drive)`` gives a grain's blockedDOFs during that first step. The contacts are
    detected with a relative margin ``detect_margin`` during that step only, so that grains
    touching to round-off start in contact. Returns ``owner``.
    """
    kn, r_ref = spec["kn"], spec["r_ref"]
    mat = material(O, w, spec)
    owner = {}
    for c, (cell, origin) in enumerate(zip(spec["cells"], origins)):
        cell["_origin"] = origin
        cell["ids"] = []
        for (pn, pt), r, drive in zip(cell["pos"], cell["radii"], cell["drive"]):
            b = utils.sphere((origin[0] + pn, origin[1] + pt, 0.0), r, material=mat)
            b.state.blockedDOFs = blocked(drive)
            b.state.mass = spec["mass"]  # mass scaling: one mass for all grains
            cell["ids"].append(O.bodies.append(b))
        for k, bid in enumerate(cell["ids"]):
            owner[bid] = (c, k)
        cell["f_floor"] = 1e-12 * kn * r_ref
    start(O, utils, w, spec)
    return owner


def material(O, w, spec):
    """The grains' material (its young and poisson only set PWaveTimeStep's stiffness; the
    contacts' kn, ks are :func:`~hmodel.dem.yade.scripts.common.stiffness`); returns its id."""
    return O.materials.append(w.FrictMat(young=spec["kn"] / spec["r_ref"], poisson=spec["kt_kn"],
                                         density=spec["density"], frictionAngle=spec["phi_g"]))


def start(O, utils, w, spec):
    """Engines and time step of a scene whose grains are placed, then the first time step, which
    creates the contacts of touching grains (detection margin ``detect_margin``, that step only).
    ``spec["frictionless"]``, where present: pairs of material ids whose contacts have no
    friction (:func:`~hmodel.dem.yade.scripts.common.stiffness`)."""
    enlarge = 1.0 + spec["detect_margin"]
    collider = w.InsertionSortCollider([w.Bo1_Sphere_Aabb(aabbEnlargeFactor=enlarge)])
    # avoidGranularRatcheting=False: shear increment = tangential part of (v2 - v1) dt, i.e.
    # d1 dalpha as in eq. 1.8; YADE's default scales it by (r1 + r2) / d1 (McNamara's
    # correction for spinning grains, moot here since rotations are blocked).
    ig2 = w.Ig2_Sphere_Sphere_ScGeom(interactionDetectionFactor=enlarge, avoidGranularRatcheting=False)
    # neverErase: a contact that opens keeps its interaction with zero force (it is reported
    # as absent); a touching contact created at the detection margin is therefore never lost.
    law = w.Law2_ScGeom_FrictPhys_CundallStrack(neverErase=True)
    O.engines = [w.ForceResetter(), collider,
                 w.InteractionLoop([ig2], [stiffness(w, spec["kn"], spec["kt_kn"],
                                                     spec.get("frictionless", ()))], [law]),
                 w.NewtonIntegrator(damping=spec["damping"], gravity=(0, 0, 0))]
    O.dt = spec["dt_safety"] * utils.PWaveTimeStep()
    O.step()
    ig2.interactionDetectionFactor = 1.0
    for f in collider.boundDispatcher.functors:
        f.aabbEnlargeFactor = 1.0


def blocked_dofs(drive):
    """z and every rotation blocked (2D, no spin); a driven direction is kinematic."""
    return "zXYZ" + ("x" if drive == "n" else "y" if drive == "t" else "")


def apply(O, cells, increments, substeps):
    """Drive every cell by its increment (dl1, dl2) [m] at constant velocity over ``substeps``
    time steps, then stop the driven grains."""
    for cell, dl in zip(cells, increments):
        for k, bid in enumerate(cell["ids"]):
            st = O.bodies[bid].state
            axis = {"n": 0, "t": 1}.get(cell["drive"][k])
            if axis is None:
                continue
            rel = st.pos[axis] - cell["_origin"][axis]
            v = [0.0, 0.0, 0.0]
            v[axis] = rel * dl[axis] / cell["l"][axis] / (substeps * O.dt)
            st.vel = v
    steps(O, substeps)
    for cell in cells:
        for k, bid in enumerate(cell["ids"]):
            if cell["drive"][k] != "free":
                O.bodies[bid].state.vel = (0.0, 0.0, 0.0)


def relax(O, cells, owner, spec, settle, rows=None, ratio=None):
    """Time steps until every cell is balanced (ratio <= ``tol``) or ``max_iter`` steps are spent.

    ``settle(c, unloaded, it)`` is called once for each cell c as it is found balanced, after
    ``it`` relaxation steps. ``rows`` and ``ratio`` are the scene's :func:`contacts` and
    :func:`unbalanced` (the 2D cells' by default; the bi-hexagons bring their own). Returns
    (pending cells, ratios, steps spent, contact rows of the last check).
    """
    rows = rows or contacts
    ratio = ratio or unbalanced
    pending = list(range(len(cells)))
    ratios = [0.0] * len(cells)
    it = 0
    while True:
        cons = rows(O, cells, owner)
        still = []
        for c in pending:
            ratios[c], unloaded = ratio(O, cells[c], cons[c], cells[c].get("f_abs", 0.0))
            if ratios[c] > spec["tol"]:
                still.append(c)
            else:
                settle(c, unloaded, it)
        pending = still
        if not pending or it >= spec["max_iter"]:
            return pending, ratios, it, cons
        steps(O, spec["check_every"])
        it += spec["check_every"]


def contacts(O, cells, owner):
    """Closed contacts of every cell, one row [i, j, fn, ft, fx, fy, bx, by] per contact.

    i < j local grain indices; f = force on j by i (N), fn = f.e (compression positive),
    ft = f.(e_y, -e_x) with e = b/|b|, b = x_j - x_i (m). Rows sorted by (i, j).
    """
    out = [[] for _ in cells]
    for c, i, j, (fx, fy, _), (bx, by, _) in contact_pairs(O, cells, owner):
        norm = math.hypot(bx, by)
        ex, ey = bx / norm, by / norm
        out[c].append([i, j, fx * ex + fy * ey, fx * ey - fy * ex, fx, fy, bx, by])
    return [sorted(o) for o in out]


def contact_pairs(O, cells, owner):
    """(cell, i, j, f, b) of every closed contact between two grains of one cell: i < j local
    grain indices, f the force on j by i and b = x_j - x_i (3-lists, N and m)."""
    for I in O.interactions:
        if not I.isReal or I.geom.penetrationDepth < 0:  # kept by neverErase but open
            continue
        c, i = owner[I.id1]
        c2, j = owner[I.id2]
        if c != c2:
            continue
        f = I.phys.normalForce + I.phys.shearForce  # force on id2 by id1
        f = [f[0], f[1], f[2]]
        if i > j:
            i, j, f = j, i, [-x for x in f]
        pi = O.bodies[cells[c]["ids"][i]].state.pos
        pj = O.bodies[cells[c]["ids"][j]].state.pos
        yield c, i, j, f, [pj[k] - pi[k] for k in range(3)]


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

