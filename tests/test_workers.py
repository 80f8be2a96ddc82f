"""Local worker processes are capped at the CPUs: more would only share the same cores."""

import os

from hmodel.cli.app import main
from hmodel.workers import local_workers, run_tasks


def _square(x: int) -> int:
    return x * x


def test_workers_are_capped_at_the_cpus(monkeypatch):
    monkeypatch.setattr(os, "cpu_count", lambda: 3)
    assert [local_workers(n) for n in (1, 2, 3, 4, 100_000)] == [1, 2, 3, 3, 3]
    monkeypatch.setattr(os, "cpu_count", lambda: None)  # unknown: one
    assert local_workers(8) == 1


def test_run_tasks_past_the_cpus_runs_here_with_the_same_results(monkeypatch):
    monkeypatch.setattr(os, "cpu_count", lambda: 1)  # one CPU: no worker process is started
    assert sorted(run_tasks(_square, [(i,) for i in range(4)], range(4), workers=100_000)) == \
        [(0, 0), (1, 1), (2, 4), (3, 9)]


def test_the_command_line_warns_in_one_line_and_runs(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(os, "cpu_count", lambda: 1)
    code = main(["data", "generate", "2", "--workers", "100000", "--directions", "2", "--alpha0", "40:40:10",
                 "--max-strain", "0.01", "--increments", "2", "--substeps", "1", "--out", str(tmp_path / "d")])
    err = capsys.readouterr().err
    assert code == 0, err
    assert err == "hmodel: warning: --workers 100000 is more than the CPUs (1): using 1\n"
