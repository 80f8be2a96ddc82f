"""Loading-program speed: a cyclic undrained program of 100 cycles at nθ = 360, closed form.

Consolidation to 200 kPa, then 100 cycles of undrained (isochoric) q-controlled loading between
+0.3 p0 and -0.3 p0: 200 stages of 100 increments (2·10⁴ mixed-control increments), every
state recorded, with the block's criterion ``until = "p <= 0.05 * p0"`` evaluated on every
state (it is not met: the default material shakes down at this amplitude). And one cycle of it.

Usage: ``python -m benchmarks.engine.program [--repeat N]``; prints a table, writes ``program.json``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from benchmarks.timing import best_of, record, write_table
from hmodel.loading import Program


def cyclic(amplitude: float, cycles: int = 100, n_theta: int = 360) -> Program:
    return Program.from_dict({
        "name": "cyclic undrained", "params": {"n_theta": n_theta},
        "stage": [{"preset": "iso", "p": "200kPa"},
                  {"name": "cycles", "repeat": cycles, "until": "p <= 0.05 * p0", "stages": [
                      {"name": "load", "preset": "undrained", "q": f"{amplitude} * p0", "steps": 100},
                      {"name": "unload", "preset": "undrained", "q": f"-{amplitude} * p0", "steps": 100}]}]})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("program.json"))
    args = ap.parse_args()
    prog = cyclic(0.3)
    params = prog.with_params([])
    res = prog.run(params)
    n_rows = int((res["stage"] != "consolidation").sum())
    rows = [(f"cyclic undrained, 100 cycles = 200 stages, {n_rows} increments, ntheta=360 [s]",
             best_of(lambda: prog.run(params), args.repeat), "<= 5"),
            ("the same, one cycle (2 stages, 200 increments) [s]",
             best_of(lambda: cyclic(0.3, 1).run(params), args.repeat), "")]
    write_table(rows, args.out, record(__file__, args, args.repeat, rows, increments=n_rows,
                                       cycles=res.meta["cycles"]["cycles"]))


if __name__ == "__main__":
    main()
