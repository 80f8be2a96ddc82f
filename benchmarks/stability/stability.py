"""Stability speed: one 360-probe envelope at nθ = 360, and the d²W map of a drained path.

(a) ``strain_envelope`` with 360 strain probes from the consolidated state at 200 kPa,
    nθ = 360 (the state is reused; best of N);
(b) ``along_biaxial``: drained biaxial at 200 kPa to 10 % (1000 increments) with 72 strain
    probes at every 10th state and at every state from the approach of the bifurcation domain
    to its entry (153 states in all), probes tied to the increment, nθ = 360 — the path and the
    probes together.

Usage: ``python -m benchmarks.stability.stability [--repeat N]``; prints a table, writes ``stability.json``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from benchmarks.timing import best_of, record, write_table
from hmodel import Params
from hmodel.loading import consolidate
from hmodel.rev import Rev
from hmodel.stability import along_biaxial, strain_envelope


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("stability.json"))
    args = ap.parse_args()
    params = Params(n_theta=360)
    rev = Rev(params)
    state = consolidate(rev, [2e5])
    rows = [("one envelope, 360 strain probes, ntheta=360 [s]",
             best_of(lambda: strain_envelope(rev, state, 360, 1e-5), args.repeat), "<= 0.01"),
            ("d2W map, drained 200 kPa to 10 %, 153 states x 72 probes, ntheta=360 [s]",
             best_of(lambda: along_biaxial(params, 2e5, 0.1, every=10, n_probes=72), args.repeat), "<= 1")]
    write_table(rows, args.out, record(__file__, args, args.repeat, rows))


if __name__ == "__main__":
    main()
