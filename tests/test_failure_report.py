"""The failure surface's files and summary from Python (hmodel.failure_report), as the
``hmodel failure-surface`` command writes and prints them."""

import csv
import json
import math

import numpy as np
import pytest

from hmodel import Params
from hmodel.failure_report import FILES, report_lines, summary, warnings, write_failure_surface
from hmodel.failure_surface import FailureSurface, failure_surface
from hmodel.rev import Sphere


def _surface(ended, ratio):
    """A surface at 0° and 60° (the numbers only: no paths)."""
    lode = np.array([0.0, 60.0])
    ratio = np.asarray(ratio, float)
    sig = np.full((2, 3), 100e3)
    return FailureSurface(p=100e3, lode=lode, q_peak=100e3 * ratio, ratio=ratio, phi=np.array([30.0, math.nan]),
                          principal=sig, strain=np.zeros((2, 6)), lode_reached=lode, b_reached=np.zeros(2),
                          ended=tuple(ended), paths=None, meta={"order": 5})


def test_a_path_on_the_tension_cut_off_is_named_and_null_in_the_summary():
    fs = _surface(("past peak", "tension cut-off"), [1.2, math.nan])
    (line,) = warnings(fs)
    assert line.startswith("Lode 60°: the path reached the tension cut-off")
    info = summary(fs)
    assert info["q_p"] == [1.2, None] and info["strength_ratio"] is None and info["warnings"] == [line]
    assert json.loads(json.dumps(info)) == info  # JSON without NaN
    lines = report_lines(fs)
    assert lines[1] == "Lode  60.0°: no peak, σ3 fell to 0 (tension cut-off)"
    assert lines[-1] == "extension/compression strength ratio: none (no peak at 60°: the tension cut-off)"
    assert warnings(_surface(("past peak", "newton"), [1.2, 0.8])) == []


def test_written_from_python_as_the_command_writes_it(tmp_path):
    params = Params(sliding_rhs="equilibrium")
    sphere = Sphere(order=5)
    fs = failure_surface(params, 200e3, [60.0], sphere=sphere, max_strain=0.05)
    info = write_failure_surface(fs, tmp_path / "fs", params, sphere)
    assert sorted(p.name for p in (tmp_path / "fs").iterdir()) == sorted(FILES)
    assert json.loads((tmp_path / "fs" / "failure_surface.json").read_text()) == info
    assert info == {**summary(fs), "params": params.to_dict()}
    with open(tmp_path / "fs" / "failure_surface.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [float(r["q_p"]) for r in rows] == pytest.approx(fs.ratio.tolist(), rel=1e-15)
    lines = report_lines(fs)
    assert len(lines) == len(fs.lode) + 1 and lines[-1].startswith("extension/compression strength ratio: ")
