"""Task ``runs`` (YADE side, see :mod:`hmodel.dem.yade.scripts`): many cells, each under its own
list of increments, in one scene (:mod:`~hmodel.dem.yade.scripts.cell_scene`).

Request: the scene's settings (:func:`hmodel.dem.scene.scene_settings`) and ``cells``, each with
``radii``, ``pos`` (cell frame), ``drive``, ``l`` = (l1, l2), ``half_width`` and
``increments`` (S_c rows (dl1, dl2)). The cells lie along x, ``gap`` apart; every grain starts
free but for its driven direction. After each increment the scene relaxes until every cell is
balanced; a cell without contact force counts as balanced (its free grains are stopped), and
every grain is stopped once all are (no kinetic energy carried over). A cell with fewer
increments than the longest stays still afterwards. If relaxing takes more than ``max_iter``
time steps the answer is ``status = "no-equilibrium"``.

Answer: for every cell and every step (0 = initial) grain positions (cell frame), contact rows
(:func:`~hmodel.dem.yade.scripts.cell_scene.contacts`), the unbalanced-force ratio, the time
steps spent (driving + relaxation) and the resultant contact force on every grain; ``dt`` and
the total ``iterations``.
"""

try:  # pytest collecting the package's doctests
    from .cell_scene import apply, blocked_dofs, build, contacts, relax
except ImportError:  # in YADE: the scripts lie side by side in the working directory
    from cell_scene import apply, blocked_dofs, build, contacts, relax


def _stop(O, cell):
    for bid in cell["ids"]:
        O.bodies[bid].state.vel = (0.0, 0.0, 0.0)


def _record(O, cell, contacts, unbalanced, iters):
    origin = cell["_origin"]
    pos = []
    for bid in cell["ids"]:
        p = O.bodies[bid].state.pos
        pos.append([p[0] - origin[0], p[1] - origin[1]])
    forces = [[O.forces.f(bid)[0], O.forces.f(bid)[1]] for bid in cell["ids"]]
    return {"pos": pos, "forces": forces, "contacts": contacts, "unbalanced": unbalanced,
            "iterations": iters}


def run(spec):
    """The answer to one request (see the module docstring)."""
    from yade import O, utils
    import yade.wrapper as w

    O.reset()
    cells = spec["cells"]
    origins, x0 = [], 0.0
    for cell in cells:
        origins.append((x0 + cell["half_width"], 0.0))
        x0 += 2.0 * cell["half_width"] + spec["gap"]
    owner = build(O, utils, w, spec, origins, blocked_dofs)

    def settle(c, unloaded, it):
        if unloaded:
            _stop(O, cells[c])

    cons = contacts(O, cells, owner)
    records = [[_record(O, c, cons[k], 0.0, 0)] for k, c in enumerate(cells)]
    substeps = spec["substeps"]
    for step in range(max(len(c["increments"]) for c in cells)):
        dls = [c["increments"][step] if step < len(c["increments"]) else [0.0, 0.0] for c in cells]
        apply(O, cells, dls, substeps)
        for cell, dl in zip(cells, dls):
            cell["l"] = [cell["l"][0] + dl[0], cell["l"][1] + dl[1]]
        pending, ratios, iters, cons = relax(O, cells, owner, spec, settle)
        if pending:
            return {"status": "no-equilibrium",
                    "message": (f"equilibrium not reached at step {step + 1} within "
                                f"{spec['max_iter']} iterations (unbalanced force ratio "
                                f"{max(ratios[c] for c in pending):.3g} > {spec['tol']:g} in "
                                f"{len(pending)} cell(s))")}
        for c, cell in enumerate(cells):
            _stop(O, cell)  # quasi-static: no kinetic energy carried over
            records[c].append(_record(O, cell, cons[c], ratios[c], iters + substeps))
    return {"status": "ok", "message": "", "dt": O.dt, "iterations": O.iter, "cells": records}
