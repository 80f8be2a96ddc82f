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


def test_fabric_ends_average_the_last_five_percent(tmp_path):
    from benchmarks.model3d.mechanisms_table import _fabric_ends

    eps = [0.0, 0.1, 0.2, 0.21, 0.25]  # the last 5 %: the rows at 0.2, 0.21 and 0.25
    z = [6.0, 4.0, 3.0, 3.5, 4.0]
    sliding = [0.0, 0.1, 0.1, 0.2, 0.3]
    path = tmp_path / "t.csv"
    path.write_text("eps_a,coordination,sliding\n" + "".join(f"{e},{a},{b}\n" for e, a, b in zip(eps, z, sliding)))
    z0, z_end, s_end = _fabric_ends(path)
    assert (z0, z_end) == (6.0, 3.5) and abs(s_end - 0.2) < 1e-12
