"""The uncertainty gate of the shipped model: does its trust score rank the errors, and what
does gating cost and buy on the comparison paths?

(a) the trust score's ranking, measured by ``hmodel surrogate trust`` on the held-out rows of
    the model's training sample and stored in the model file: the share of the error held by
    the least trusted 0.1 / 1 / 5 / 10 % of the rows, and the rank correlation;
(b) every comparison path (nθ = 360, to 10 %, increments 1e-3) with the shipped model gated at
    levels 0.5, 0.9, 0.99 and 0.999 (fallback: the closed form) and ungated: the largest
    |Δq| / peak q over the paths, the fraction of cell states sent to the closed form, and the
    wall time of all paths.

Usage: ``python -m benchmarks.surrogates.gate``; prints a table, writes ``gate.json``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from benchmarks.timing import record, write_table
from hmodel import Params
from hmodel.cell import ClosedFormSolver
from hmodel.compare import compare_path, warm_up
from hmodel.loading import standard_paths
from hmodel.surrogate.shipped import load_shipped
from hmodel.surrogate.solver import SurrogateSolver


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--step", type=float, default=1e-3)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("gate.json"))
    args = ap.parse_args()
    model = load_shipped()
    rows = []
    for r in model.meta["trust"]["ranking"]:
        f = 100 * r["top_fraction"]
        rows.append((f"(a) least trusted {f:g} % of held-out rows: share of the error [%]",
                     100 * r["share_of_error"], f"random: {f:g}"))
        rows.append((f"(a) least trusted {f:g} % of held-out rows: share of the squared error [%]",
                     100 * r["share_of_squared_error"], "most"))
    rows.append(("(a) Spearman correlation of score and error", model.meta["trust"]["ranking"][0]["spearman"], "-"))
    rows += gate_curve(model, (0.5, 0.9, 0.99, 0.999), args.step, "(b) ", "cell states")
    write_table(rows, args.out, record(__file__, args, 1, rows, step=args.step))


def gate_curve(model, gates, step: float, prefix: str = "", what: str = "cell states") -> list[tuple]:
    """Every comparison path, ungated and gated at ``gates`` with the closed form as fallback:
    (measure, value, target) rows of the largest |dq| / peak q over the paths, the share of
    ``what`` the gate sent to the closed form, and the wall time."""
    params, rows = Params(), []
    warm_up(params, ["closed-form", SurrogateSolver(model)], step, 1e-4)
    for gate in (None, *gates):
        solver = (SurrogateSolver(model) if gate is None
                  else SurrogateSolver(model, gate=gate, fallback=ClosedFormSolver()))
        worst, t = 0.0, time.perf_counter()
        for spec in standard_paths(0.1):
            _, _, devs, st = compare_path(params, spec, solver, step, 1e-4)
            assert st["status"] == "ok", st
            worst = max([worst] + [d["q_max_dev_rel"] for d in devs])
        t = time.perf_counter() - t
        label = "ungated" if gate is None else f"gate {gate:g}"
        rows.append((f"{prefix}{label}: max |dq| / peak q over the paths [%]", 100 * worst, "<= 1"))
        if gate is not None:
            c = solver.counts
            rows.append((f"{prefix}{label}: {what} sent to the closed form [%]",
                         100 * c["gated"] / max(c["gate_checked"], 1), "small"))
        rows.append((f"{prefix}{label}: wall time of the six paths (both solvers) [s]", t, "-"))
    return rows


if __name__ == "__main__":
    main()
