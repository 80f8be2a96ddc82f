"""The critical-state and π-plane figures of the 3D H-model with each cell mechanism on and off,
as one table in docs/mechanisms.md, generated from the JSON files of
``benchmarks.model3d.critical_state`` and ``benchmarks.model3d.pi_plane`` run with
``--mechanisms ... --tag TAG`` (no tag: the published model).

Usage: ``python -m benchmarks.model3d.mechanisms_table`` rewrites the block between the markers
``<!-- mechanisms-table -->`` and ``<!-- /mechanisms-table -->`` of docs/mechanisms.md;
``--check`` exits 1 when the page's block differs from what the JSON files give (the test
suite runs it, so the page cannot keep a stale number).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

HERE = Path(__file__).parent
PAGE = HERE.parents[1] / "docs" / "mechanisms.md"
BEGIN, END = "<!-- mechanisms-table -->", "<!-- /mechanisms-table -->"
#: (tag, what is on), in the table's order.
VARIANTS = (("", "published (none)"), ("hertz", "Hertz–Mindlin contacts"), ("rebirth", "rebirth"),
            ("hertz_rebirth", "Hertz–Mindlin + rebirth"))
#: The issue's measure of a critical state: q/p within ±3 % of one M, |dε_v/dε₁| ≤ 0.05.
QP_BAND, RATE_MAX = 0.03, 0.05


def _load(name: str, tag: str) -> dict | None:
    path = HERE / (f"{name}_{tag}.json" if tag else f"{name}.json")
    return json.loads(path.read_text()) if path.exists() else None


def _result(rec: dict, start: str) -> float:
    for r in rec["results"]:
        if r["measure"].startswith(start):
            return float(r["value"])
    return math.nan


def row(tag: str, label: str) -> str | None:
    cs, pi = _load("critical_state", tag), _load("pi_plane", tag)
    if cs is None:
        return None
    table = cs["table"]
    reached = [r for r in table if not r["newton_failed"]]
    qp = [r["q_p_end"] for r in reached]
    m = sum(qp) / len(qp) if qp else math.nan
    within = sum(abs(q / m - 1) <= QP_BAND for q in qp) if qp else 0
    drained = [r for r in table if r["test"] == "drained"]
    steady = sum(abs(r["deps_v_deps11_end"]) <= RATE_MAX for r in drained if not r["newton_failed"])
    loose_u = [r for r in table if r["test"] == "undrained" and r["state"] == "loose"]
    liq = min((r["p_end"] / r["p0"] for r in loose_u), default=math.nan)
    ratio = _result(pi, "strength ratio") if pi else math.nan
    mc = _result(pi, "M_c") if pi else math.nan
    return (f"| {label} | {len(reached)} of {len(table)} | {min(qp):.3f}–{max(qp):.3f} | {within} of {len(reached)} "
            f"| {max(abs(r['deps_v_deps11_end']) for r in drained):.3f} | {steady} of {len(drained)} "
            f"| {liq:.2f} | {mc:.3f} | {ratio:.3f} |")


def block() -> str:
    head = ("| mechanisms on | tests to 30 % | q/p at the end | within ±3 % of their mean | "
            "largest drained \\|dε_v/dε₁\\| at the end | drained with \\|dε_v/dε₁\\| ≤ 0.05 | "
            "loose undrained p_end/p₀ (lowest) | M_c (π-plane) | M_e/M_c |\n"
            "|---|---|---|---|---|---|---|---|---|")
    rows = [r for r in (row(tag, label) for tag, label in VARIANTS) if r is not None]
    return "\n".join([BEGIN, head, *rows, END])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="compare the page with the JSON files")
    args = ap.parse_args()
    text = PAGE.read_text()
    i, j = text.index(BEGIN), text.index(END) + len(END)
    new = text[:i] + block() + text[j:]
    if args.check:
        if new != text:
            print("docs/mechanisms.md: the mechanisms table differs from the benchmarks' JSON files; "
                  "run python -m benchmarks.model3d.mechanisms_table")
            return 1
        return 0
    PAGE.write_text(new)
    print(block())
    return 0


if __name__ == "__main__":
    sys.exit(main())
