"""The accuracy–cost curve of an ensemble's gate: gate level against error and exact-solver work.

An ensemble of ``compliance`` networks whose trust is its disagreement (made by
``python -m benchmarks.surrogates.refine --members 4``: four networks of the default recipe on 6,000 rows),
on every comparison path (nθ = 360, to 10 %, increments 10⁻³), ungated and gated at several
levels with the closed form as the exact solver: the largest |Δq| / peak q over the paths, the
share of cell increments (Newton trials included) sent to the closed form, and the wall time.

Usage: ``python -m benchmarks.surrogates.gate_ensemble --ensemble A+B+C+D``; prints a table, writes
``gate_ensemble.json``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from benchmarks.surrogates.gate import gate_curve
from benchmarks.timing import record, write_table
from hmodel.surrogate import modelfile


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ensemble", required=True, help="the members, first the one with the trust: A+B+...")
    ap.add_argument("--gates", type=float, nargs="+", default=[0.5, 0.9, 0.99, 0.999])
    ap.add_argument("--step", type=float, default=1e-3)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("gate_ensemble.json"))
    args = ap.parse_args()
    members = [modelfile.load(p) for p in args.ensemble.split("+")]
    rows = gate_curve(members, args.gates, args.step, what="cell increments")
    write_table(rows, args.out, record(__file__, args, 1, rows, step=args.step, members=len(members)))


if __name__ == "__main__":
    main()
