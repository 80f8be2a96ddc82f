"""docs/mechanisms.md's tables are the benchmarks' JSON files (benchmarks/model3d/mechanisms_table.py)."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_mechanisms_page_is_generated_from_the_benchmarks():
    r = subprocess.run([sys.executable, "-m", "benchmarks.model3d.mechanisms_table", "--check"], cwd=ROOT,
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr


def test_the_check_fails_on_a_stale_number(tmp_path, monkeypatch):
    from benchmarks.model3d import mechanisms_table as mt

    text = mt.PAGE.read_text()
    fresh = mt.render(text)
    stale = fresh.replace("| published (none) |", "| published (none) | 9.99 |", 1)
    assert stale != fresh and mt.render(stale) == fresh  # rendering restores the generated block
