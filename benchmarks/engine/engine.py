"""Engine speed: the figures of issue 2, printed as a table and written to ``engine.json``.

(a) drained biaxial test at p0 = 200 kPa to 10 % axial strain, nθ = 360, default steps
    (consolidation + shear + recording, i.e. everything ``run_biaxial`` computes), compiled
    kernel and generic Python driver;
(b) cell updates per second on one core: the closed-form cell kernel (``ClosedFormSolver.step``)
    on a large batch, and the fused REV trial of the compiled path (localize + cell + average);
(c) the same fused trial with Hertz-Mindlin contacts (``contact="hertz-mindlin"``,
    docs/mechanisms.md), and its cost per cell over the linear law's, the trials timed in turn;
    likewise with Hertz-Mindlin and rebirth, and with the sand variant's mechanisms
    (Hertz-Mindlin, ``renewal="mix"``, ``lateral="axisymmetric"``, which a 2D cell takes as its
    own lateral length);
(d) the same costs over the published cell's trial as the compiled Newton makes it: the part
    the committed cells fix prepared once per increment (the linear cell's rows; the mechanisms
    have none), the trials called from a compiled loop. The Newton's trials of one increment
    lie between (c), which prepares at every trial, and (d), which prepares once for all.

Usage: ``python -m benchmarks.engine.engine [--repeat N] [--out PATH]``. The first call of each kernel
compiles it (or loads Numba's cache); it is excluded, and the best of N runs is reported.
"""

from __future__ import annotations

import argparse
from functools import partial
from pathlib import Path

import numpy as np
from numba import njit

from benchmarks.timing import best_in_turn, best_of, record, write_table
from hmodel import Params
from hmodel.cell import CellState
from hmodel.cell.closed_form import ClosedFormSolver
from hmodel.loading import consolidate, run_biaxial
from hmodel.loading.compiled import CompiledSegment
from hmodel.loading.control import Tangent
from hmodel.rev import Rev
from hmodel.rev.trial import point_prepared, point_trial_prepared


def drained_biaxial(repeat: int, compiled: bool) -> float:
    params = Params(n_theta=360)
    if compiled:
        return best_of(lambda: run_biaxial(params, [2e5], 0.1), repeat)
    return best_of(lambda: run_biaxial(params, [2e5], 0.1, compiled=False), max(1, repeat // 3))


def cell_updates(repeat: int, n_cells: int = 2_000_000) -> float:
    """Closed-form cell increments per second, compressive increments on loaded cells."""
    params = Params()
    rng = np.random.default_rng(0)
    state = ClosedFormSolver().step(params, CellState.initial(params, (n_cells,)),
                                    -1e-4 * params.l10, -0.5e-4 * params.l20)[0]
    dl1 = -params.l10 * rng.uniform(0, 1e-4, n_cells)
    dl2 = -params.l20 * rng.uniform(-1e-4, 1e-4, n_cells)
    solver = ClosedFormSolver()
    return n_cells / best_of(lambda: solver.step(params, state, dl1, dl2), repeat)


def _trial_args(params: Params) -> tuple:
    """The arguments of :func:`hmodel.rev.trial.point_trial` for one material point consolidated
    to 200 kPa (nθ = 360) and a strain increment of 1e-4."""
    rev = Rev(params.with_(n_theta=360))
    s0 = consolidate(rev, [2e5])
    seg = CompiledSegment(rev, s0, (False, True, False), np.eye(3), s0.sig,
                          np.array([[0.1, 2e5, 0.0]]), 1000, Tangent())
    out, flags, sig = np.empty((360, 8)), np.empty((360, 5), bool), np.empty(3)
    x = np.array([1e-4, -5e-5, 0.0])
    resp = np.empty((360, 0))  # the closed form: no learned responses
    return (seg.values[0], seg.eps[0], x, seg.geo[0], seg.p[0], rev.mode, rev.volume0, out, flags, sig, resp)


def _fused_trial(params: Params, n_calls: int):
    """n_calls compiled REV trials of one material point consolidated to 200 kPa (nθ = 360), a
    strain increment of 1e-4 each: a function of no argument."""
    from hmodel.loading.compiled import trial

    args = _trial_args(params)

    def run():
        for _ in range(n_calls):
            trial(*args)
    return run


@njit(cache=False)
def prepared_trials(n, values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp):
    """n trials of one point as the compiled Newton makes them (``_newton_point``): the part of
    the trial that the committed cells fix prepared once (:func:`hmodel.rev.trial.point_prepared`:
    the linear cells' rows, nothing for Hertz-Mindlin ones), then
    :func:`~hmodel.rev.trial.point_trial_prepared`, the loop compiled (no Python call per trial)."""
    pre = point_prepared(values, geo, p, resp)
    for _ in range(n):
        point_trial_prepared(values, eps, deps, geo, p, mode, volume0, out, flags, sig, resp, pre)


def costs_prepared(trial_args, mechanisms: dict, repeat: int, n_calls: int) -> dict[str, float]:
    """Cost per cell of :func:`prepared_trials` with each of ``mechanisms`` (name -> Params,
    ``"linear"`` the published cell) over the published one's, timed in turn; ``trial_args``
    makes a point's trial arguments (its cells first)."""
    runs, cells = {}, {}
    for name, params in mechanisms.items():
        args = trial_args(params)
        prepared_trials(1, *args)  # compiles the loop once per signature, outside the timing
        runs[name], cells[name] = partial(prepared_trials, n_calls, *args), len(args[0])
    best = best_in_turn(runs, repeat)
    per_cell = {name: best[name] / cells[name] for name in runs}
    return {name: per_cell[name] / per_cell["linear"] for name in runs if name != "linear"}


def fused_trials(repeat: int, n_calls: int = 2000, params: Params = Params()) -> float:
    """Cell updates per second inside the compiled REV trial (nθ = 360, one material point)."""
    return n_calls * 360 / best_of(_fused_trial(params, n_calls), repeat)


#: The cells timed against the published one: Hertz-Mindlin contacts, and every mechanism on.
MECHANISMS = {"linear": Params(), "hertz-mindlin": Params(contact="hertz-mindlin"),
              "all": Params(contact="hertz-mindlin", renewal="rebirth"),
              "sand": Params(contact="hertz-mindlin", renewal="mix", lateral="axisymmetric")}


PREPARED_LABELS = {"hertz-mindlin": "Hertz-Mindlin contacts", "all": "every mechanism on (Hertz-Mindlin, rebirth)",
                   "sand": "the sand variant's mechanisms (Hertz-Mindlin, rebirth at the mean box)"}


def hertz_cost(repeat: int, n_calls: int = 500) -> tuple[float, float, float, float]:
    """(Hertz-Mindlin cell updates per second in the fused REV trial, their cost per cell over
    the linear law's, the cost with Hertz-Mindlin and rebirth over the linear law's, the cost
    with the sand variant's mechanisms (Hertz-Mindlin, rebirth at the mean box; its lateral
    strain about the axis is the 2D cell's own) over the linear law's): the trials timed
    in turn, ``4 * repeat`` times each, the best of each kept, so that a load beside the run
    weighs on all alike."""
    best = best_in_turn({name: _fused_trial(p, n_calls) for name, p in MECHANISMS.items()}, repeat)
    return (n_calls * 360 / best["hertz-mindlin"], best["hertz-mindlin"] / best["linear"],
            best["all"] / best["linear"], best["sand"] / best["linear"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("engine.json"))
    args = ap.parse_args()
    rows = [
        ("drained biaxial 200 kPa to 10 %, ntheta=360, compiled [s]",
         drained_biaxial(args.repeat, True), "<= 0.1"),
        ("drained biaxial 200 kPa to 10 %, ntheta=360, generic driver [s]",
         drained_biaxial(args.repeat, False), "-"),
        ("cell updates per second, ClosedFormSolver.step (one core)",
         cell_updates(args.repeat), ">= 1e7"),
        ("cell updates per second, fused REV trial (one core)", fused_trials(args.repeat), ">= 1e7"),
    ]
    hertz_rate, hertz_ratio, all_ratio, sand_ratio = hertz_cost(args.repeat)
    rows += [
        ("cell updates per second, fused REV trial, Hertz-Mindlin contacts (one core)", hertz_rate, "-"),
        ("cost of a cell update, Hertz-Mindlin over linear contacts, fused REV trial", hertz_ratio, "<= 1.5"),
        ("cost of a cell update, every mechanism on (Hertz-Mindlin, rebirth) over linear, fused REV trial",
         all_ratio, "<= 1.5"),
        ("cost of a cell update, the sand variant's mechanisms (Hertz-Mindlin, rebirth at the mean box) over "
         "linear, fused REV trial", sand_ratio, "<= 1.5"),
    ]
    prepared = costs_prepared(_trial_args, MECHANISMS, args.repeat, 500)
    rows += [(f"prepared trials' cost of a cell update, {PREPARED_LABELS[name]} over linear (the linear cells' "
              "state-only part once per increment, as the compiled Newton makes its trials)", ratio, "-")
             for name, ratio in prepared.items()]
    write_table(rows, args.out, record(__file__, args, args.repeat, rows), value_width=12)


if __name__ == "__main__":
    main()
