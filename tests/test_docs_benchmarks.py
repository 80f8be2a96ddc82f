"""The benchmarks page marks a missed target as missed (docs/hooks/benchmarks.py): the verdict
is computed from the JSON's value and target, in each file's table and in the page's count."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

HOOK = Path(__file__).resolve().parents[1] / "docs" / "hooks" / "benchmarks.py"


@pytest.fixture(scope="module")
def hook():
    spec = importlib.util.spec_from_file_location("docs_benchmarks_hook", HOOK)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("value, target, expected", [
    (2.4023, "<= 2", "missed"),            # engine3d: the batched calibration setting
    (1.9, "<= 2", "met"),
    (2.0, "<= 2", "met"),
    (6, "0", "missed"),                    # points dropped against none
    (0, "0", "met"),
    (0.09, "<= 10 %", "met"),
    (4.93, "<= 2 %", "missed"),
    (2.7e7, ">= 1e7", "met"),
    (40.3, ">= 50", "missed"),
    (18000.0, "< 594,000", "met"),
    (float("nan"), "< 594,000", "missed"),  # not reached
    (None, "<= 1", "missed"),
    (4.0, "= 4", "met"),
    (0.5, "≤ 0.5", "met"),
    (1.2, "-", None),
    (1.2, "", None),
    (0.5, "<= target", None),
    (0.99, "report 0.998", None),
    (3.0, "small", None),
    (3.0, None, None),
])
def test_verdict(hook, value, target, expected):
    assert hook.verdict(value, target) == expected


def _write(folder: Path, name: str, results: list[dict]) -> None:
    (folder / name).parent.mkdir(parents=True, exist_ok=True)
    (folder / name).write_text(json.dumps({"command": "python -m x", "results": results}))


def test_tables_and_count_mark_missed_targets(hook, tmp_path):
    _write(tmp_path, "engine/fast.json", [
        {"measure": "batched call [s]", "value": 2.4, "target": "<= 2"},
        {"measure": "  points dropped (Newton failed)", "value": 6, "target": "0"},
        {"measure": "single test [s]", "value": 0.27, "target": "<= 0.5"},
        {"measure": "generic driver [s]", "value": 1.8, "target": "-"}])
    _write(tmp_path, "engine/other.json", [{"measure": "ratio", "value": 1.2, "target": "<= 1.5"}])
    found = {f"{p.parent.name}/{p.stem}": p for p in sorted(tmp_path.glob("*/*.json"))}

    page = hook.render("engine/fast", found["engine/fast"], set())
    rows = {line.split("|")[1].strip(): line for line in page.splitlines() if line.startswith("| ")}
    assert "✗ **missed**" in rows["batched call [s]"]
    assert "✗ **missed**" in rows["points dropped (Newton failed)"]
    assert "✓ met" in rows["single test [s]"]
    assert "met" not in rows["generic driver [s]"]
    assert f'<a id="{hook.anchor("engine/fast")}"></a>' in page

    summary = hook.targets(found)
    assert "**2 meet it and 2 miss it**" in summary
    assert "The 2 missed targets" in summary
    assert summary.count("(#bench-engine-fast)") == 2 and "bench-engine-other" not in summary


def test_count_without_a_miss_has_no_list(hook, tmp_path):
    _write(tmp_path, "engine/other.json", [{"measure": "ratio", "value": 1.2, "target": "<= 1.5"}])
    summary = hook.targets({"engine/other": tmp_path / "engine" / "other.json"})
    assert "**1 meet it and 0 miss it**" in summary and "missed targets" not in summary
