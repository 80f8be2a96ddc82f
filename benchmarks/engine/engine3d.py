"""Engine speed of the 3D H-model (issue 34): the compiled 3D path, printed as a table and written
to ``engine3d.json``.

(a) drained triaxial test at p0 = 200 kPa to 10 % axial strain in 1000 increments (σ22 and σ33
    held by Newton; consolidation + shear + recording) at the default rule (``Sphere()``),
    compiled kernel and generic Python driver;
(b) 32 parameter sets (kn, kt/kn, φg, α0 from a Sobol design) × 3 drained triaxial tests
    (100, 200, 400 kPa), 96 material points in one batched call (consolidation + shear +
    recording, all cores), in the calibration benchmark's setting (5 % axial strain in
    increments of 10⁻³, consolidation in steps of 10⁻⁴: ``benchmarks/calibration/calibrate.py``)
    at the default rule and at order 17 with two azimuths, and once to 10 % in 1000 increments;
(c) bi-hexagon updates per second on one core, ``BiHexSolver.step`` on a large batch and inside
    the fused 3D REV trial, beside the 2D engine's cell updates per second measured in the same
    run (``benchmarks.engine.engine``);
(d) test (a) compiled at several (order, azimuths) pairs, to choose the defaults;
(e) test (a) compiled with Hertz-Mindlin contacts (``contact="hertz-mindlin"``, grains of the
    default G = 29 GPa, ν = 0.2, docs/mechanisms.md), beside (a) in the same run; and with every
    mechanism of the sand variant on (Hertz-Mindlin, ``lateral="axisymmetric"``,
    ``renewal="mix"``: the REV then holds one bi-hexagon per direction, ``Rev3D.cell_sphere``),
    its sides held equal (``run_triaxial(..., radial="equal")``, as its benchmarks run);
(f) the batch (b) in the calibration setting with one radial strain (ε22 = ε33, (σ22 + σ33)/2
    held): the points that free sides lose where the REV leaves axisymmetry;
(g) the cost of a bi-hexagon update in the fused 3D trial with Hertz-Mindlin contacts, with
    the sand variant's mechanisms, and with Hertz-Mindlin contacts and contacts between the
    hexagons, over the published bi-hexagon's (the trials timed in turn, a consolidated REV:
    issue 54's 1.5x lifted to 3D);
(h) the same costs over the published bi-hexagon's trial as the compiled Newton makes it
    (``benchmarks.engine.engine.prepared_trials``: the linear hexagons' state-only part prepared
    once per increment, the mechanisms having none; the trials called from a compiled loop).

All tests use ``sliding_rhs="equilibrium"``, the 3D commands' default (docs/model3d.md). Points
whose increment Newton cannot solve are dropped (``failures``) and counted.

Usage: ``python -m benchmarks.engine.engine3d [--repeat N] [--out PATH]``. The first call of each
kernel compiles it (or loads Numba's cache); it is excluded, and the best of N runs is reported
(of one run for the grid (d) and the batch to 10 %).
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
from scipy.stats import qmc

from benchmarks.engine.engine import cell_updates, costs_prepared, fused_trials
from benchmarks.timing import best_in_turn, best_of, record, write_table
from hmodel import Params
from hmodel.cell.bihex import BiHexSolver
from hmodel.loading import Recorder, Segment, consolidate, run_segment
from hmodel.loading.compiled import any_trial
from hmodel.loading.compiled3d import kernel_inputs3d
from hmodel.loading.stages import ROWS_3D
from hmodel.rev import Rev3D, Sphere

BASE = Params(sliding_rhs="equilibrium")
#: every mechanism of the sand variant (``--model sand``), its α0 the published default
SAND = BASE.with_(contact="hertz-mindlin", lateral="axisymmetric", renewal="mix")
#: Ranges of the drawn materials (angles in degrees).
RANGES = {"kn": (1e8, 4e8), "kt_kn": (0.3, 1.0), "phi_g": (20.0, 40.0), "alpha0": (40.0, 60.0)}
PRESSURES = (1e5, 2e5, 4e5)
GRID_ORDERS = (17, 23, 35, 59, 89)
GRID_AZIMUTHS = (2, 4, 6, 8)
#: the calibration benchmark's setting: shear strain and step, consolidation step
CALIBRATION = (0.05, 1e-3, 1e-4)


def drawn_sets(n: int, seed: int = 0) -> list[Params]:
    u = qmc.Sobol(len(RANGES), seed=seed).random(n)
    sets = []
    for row in u:
        v = {k: lo + x * (hi - lo) for (k, (lo, hi)), x in zip(RANGES.items(), row)}
        v["phi_g"], v["alpha0"] = math.radians(v["phi_g"]), math.radians(v["alpha0"])
        sets.append(BASE.with_(**v))
    return sets


def triaxial(rev: Rev3D, p0, axial: float = 0.1, n_steps: int = 1000, compiled: bool | None = None,
             failures: dict | None = None, iso_step: float = 1e-5, radial: str = "free"):
    """A drained triaxial test of every point: consolidation to p0 (B,), then ``axial`` in
    ``n_steps`` with σ22 = σ33 = p0 (``radial="equal"``: ε22 = ε33 and (σ22 + σ33)/2 = p0), all
    recorded; returns the result table."""
    p0 = np.asarray(p0, float)
    rec = Recorder()
    state = consolidate(rev, p0, step=iso_step, recorder=rec, compiled=compiled, failures=failures)
    values = np.zeros((state.n_points, 6))
    matrix, stress = np.eye(6), (False, True, True, False, False, False)
    if radial == "equal":
        matrix[1], matrix[2] = ROWS_3D["sig_r"][1], ROWS_3D["eps22-eps33"][1]
        stress = (False, True, False, False, False, False)
        values[:, 0], values[:, 1] = axial, 0.5 * (state.sig[:, 1] + state.sig[:, 2])
    else:
        values[:, 0], values[:, 1], values[:, 2] = axial, state.sig[:, 1], state.sig[:, 2]
    seg = Segment(stress, matrix, values, n_steps, "shear")
    run_segment(rev, state, seg, rec, compiled=compiled, failures=failures)
    return rec.result()


def single(repeat: int, compiled: bool, sphere: Sphere = Sphere(), params: Params = BASE,
           radial: str = "free") -> float:
    rev = Rev3D(params, sphere)
    return best_of(lambda: triaxial(rev, [2e5], compiled=compiled, radial=radial), repeat)


def batched(repeat: int, sphere: Sphere = Sphere(), calibration: bool = True,
            n_sets: int = 32, radial: str = "free") -> tuple[float, int]:
    """(seconds, points dropped) of n_sets x 3 tests in one call: in the calibration setting, or
    to 10 % in 1000 increments; ``repeat`` 0: one run, no warm-up."""
    sets = drawn_sets(n_sets)
    rev = Rev3D([s for s in sets for _ in PRESSURES], sphere)
    p0 = np.tile(PRESSURES, n_sets)
    failures: dict = {}
    axial, step, iso = CALIBRATION if calibration else (0.1, 1e-4, 1e-5)
    run = lambda: (failures.clear(), triaxial(rev, p0, axial, round(axial / step),  # noqa: E731
                                              failures=failures, iso_step=iso, radial=radial))
    if repeat:
        return best_of(run, repeat), len(failures)
    t = time.perf_counter()  # one run, the kernels compiled by the calls before
    run()
    return time.perf_counter() - t, len(failures)


def bihex_updates(repeat: int, n_cells: int = 1_000_000) -> float:
    """BiHexSolver.step increments per second, compressive increments on loaded cells."""
    params, solver = BASE, BiHexSolver()
    rng = np.random.default_rng(0)
    l1, l2 = solver.initial(params, ()).values[[6, 7]]
    state = solver.step(params, solver.initial(params, (n_cells,)), -1e-4 * l1, -0.5e-4 * l2, -0.5e-4 * l2)[0]
    dl1 = -l1 * rng.uniform(0, 1e-4, n_cells)
    dl2 = -l2 * rng.uniform(-1e-4, 1e-4, n_cells)
    dl3 = -l2 * rng.uniform(-1e-4, 1e-4, n_cells)
    return n_cells / best_of(lambda: solver.step(params, state, dl1, dl2, dl3), repeat)


def _bihex_trial_args(params: Params) -> tuple:
    """The arguments of the compiled 3D REV trial (:func:`hmodel.rev.trial.point_trial`) of one
    material point consolidated to 200 kPa (default rule) and a strain increment of 1e-4."""
    rev = Rev3D(params)
    s0 = consolidate(rev, [2e5])
    geo, p = kernel_inputs3d(rev)
    values = np.ascontiguousarray(s0.cells.values[0])
    C = rev.n_cells
    out, flags, sig, resp = np.empty_like(values), np.empty((C, 11), bool), np.empty(6), np.empty((C, 0))
    x = np.array([1e-4, -5e-5, -5e-5, 0.0, 0.0, 0.0])
    return (values, s0.eps[0], x, geo[0], p[0], rev.mode, rev.volume0, out, flags, sig, resp)


def _fused_bihex_trial(params: Params, n_calls: int):
    """n_calls compiled 3D REV trials of one material point consolidated to 200 kPa (default
    rule), a strain increment of 1e-4 each: ``(run, cells)``, a function of no argument and the
    REV's bi-hexagons."""
    args = _bihex_trial_args(params)

    def run():
        for _ in range(n_calls):
            any_trial(*args)
    return run, len(args[0])


def fused_bihex_trials(repeat: int, n_calls: int = 2000) -> float:
    """Bi-hexagon updates per second inside the compiled 3D REV trial (default rule, one
    material point after consolidation to 200 kPa)."""
    run, cells = _fused_bihex_trial(BASE, n_calls)
    return n_calls * cells / best_of(run, repeat)


#: The bi-hexagons timed against the published one in the fused 3D trial.
BIHEX_MECHANISMS = {"linear": BASE, "hertz-mindlin": BASE.with_(contact="hertz-mindlin"),
                    "sand": SAND, "cross": BASE.with_(contact="hertz-mindlin", cross_contacts="frictionless")}


BIHEX_LABELS = {"hertz-mindlin": "Hertz-Mindlin contacts",
                "sand": "the sand variant's mechanisms (Hertz-Mindlin, lateral=axisymmetric, renewal=mix)",
                "cross": "Hertz-Mindlin contacts and contacts between the hexagons"}


def bihex_costs(repeat: int, n_calls: int = 500) -> dict[str, float]:
    """Cost per bi-hexagon of the fused 3D trial with each of :data:`BIHEX_MECHANISMS` over the
    published one's (the trials timed in turn; a consolidated REV, so every hexagon carries and,
    with contacts between the hexagons, every bi-hexagon whose hexagons touch takes the coupled
    update)."""
    runs = {name: _fused_bihex_trial(params, n_calls) for name, params in BIHEX_MECHANISMS.items()}
    best = best_in_turn({name: run for name, (run, _) in runs.items()}, repeat)
    per_cell = {name: best[name] / runs[name][1] for name in runs}
    return {name: per_cell[name] / per_cell["linear"] for name in runs if name != "linear"}


def bihex_costs_prepared(repeat: int, n_calls: int = 500) -> dict[str, float]:
    """:func:`bihex_costs` over the published bi-hexagon's trial as the compiled Newton makes it
    (:func:`benchmarks.engine.engine.prepared_trials`: the linear hexagons' state-only part
    prepared once, the trials called from a compiled loop)."""
    return costs_prepared(_bihex_trial_args, BIHEX_MECHANISMS, repeat, n_calls)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("engine3d.json"))
    args = ap.parse_args()
    r = args.repeat
    d = Sphere()
    rule = f"order {d.order}, m = {d.n_azimuth} ({d.n_cells} bi-hexagons)"
    t_cal, drop_cal = batched(r)
    t_cal17, drop_cal17 = batched(r, Sphere(order=17, n_azimuth=2))
    t_equal, drop_equal = batched(r, radial="equal")
    sand = Rev3D(SAND, d).n_cells
    t_long, drop_long = batched(0, calibration=False)
    rows = [
        (f"drained triaxial 200 kPa to 10 %, default rule: {rule}, compiled [s]", single(r, True), "<= 0.5"),
        (f"drained triaxial 200 kPa to 10 %, default rule: {rule}, generic driver [s]",
         single(max(1, r // 3), False), "-"),
        (f"drained triaxial 200 kPa to 10 %, default rule: {rule}, Hertz-Mindlin contacts, compiled [s]",
         single(r, True, params=BASE.with_(contact="hertz-mindlin")), "<= 0.5"),
        (f"drained triaxial 200 kPa to 10 %, default rule, every mechanism of the sand variant (Hertz-Mindlin, "
         f"lateral=axisymmetric, renewal=mix: {sand} bi-hexagons), one radial strain, compiled [s]",
         single(r, True, params=SAND, radial="equal"), "<= 0.5"),
        ("32 parameter sets x 3 triaxial tests, calibration setting (5 %, steps 1e-3), "
         "default rule, one batched call [s]", t_cal, "<= 2"),
        ("  points dropped (Newton failed)", drop_cal, "0"),
        ("32 parameter sets x 3 triaxial tests, calibration setting, order 17, m = 2 [s]", t_cal17, "-"),
        ("  points dropped (Newton failed)", drop_cal17, "0"),
        ("32 parameter sets x 3 triaxial tests, calibration setting, default rule, one radial strain [s]",
         t_equal, "<= 2"),
        ("  points dropped (Newton failed)", drop_equal, "0"),
        ("32 parameter sets x 3 triaxial tests to 10 % in 1000 increments, default rule (one run) [s]",
         t_long, "-"),
        ("  points dropped (Newton failed)", drop_long, "0"),
        ("bi-hexagon updates per second, BiHexSolver.step (one core)", bihex_updates(r), "-"),
        ("bi-hexagon updates per second, fused 3D REV trial (one core)", fused_bihex_trials(r), "-"),
        *((f"cost of a bi-hexagon update, {BIHEX_LABELS[name]} over the published one, fused 3D REV trial",
           ratio, "<= 1.5") for name, ratio in bihex_costs(r).items()),
        *((f"prepared trials' cost of a bi-hexagon update, {BIHEX_LABELS[name]} over the published one (the "
           "linear hexagons' state-only part once per increment, as the compiled Newton makes its trials)", ratio, "-")
          for name, ratio in bihex_costs_prepared(r).items()),
        ("2D cell updates per second, ClosedFormSolver.step (one core)", cell_updates(r), "-"),
        ("2D cell updates per second, fused REV trial (one core)", fused_trials(r), "-"),
    ]
    for order in GRID_ORDERS:
        for m in GRID_AZIMUTHS:
            sphere = Sphere(order=order, n_azimuth=m)
            rows.append((f"drained triaxial to 10 %, order {order}, m = {m} ({sphere.n_cells} "
                         "bi-hexagons), compiled [s]", single(1, True, sphere), "-"))
    write_table(rows, args.out, record(__file__, args, r, rows, pressures=list(PRESSURES),
                                       ranges=RANGES, sliding_rhs=BASE.sliding_rhs,
                                       default_order=d.order, default_azimuths=d.n_azimuth))


if __name__ == "__main__":
    main()
