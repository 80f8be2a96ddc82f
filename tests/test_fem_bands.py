"""Shear bands told apart (hmodel.fem.bands.band_lines) on synthetic fields of Gauss points: one
band at its angle, a conjugate pair (a cross, a wedge from an edge imperfection), none; and
the biaxial run's band report of a pair (each band, not one line through both)."""

import math

import numpy as np
import pytest

from hmodel.fem.bands import band_inclination, band_lines, shear_band
from hmodel.fem.result import FemResult, Snapshot


def _grid(nx=60, ny=60, width=1.0, height=1.0):
    """Cell centres of an nx × ny grid over width × height and their areas."""
    gx = (np.arange(nx) + 0.5) * width / nx
    gy = (np.arange(ny) + 0.5) * height / ny
    X, Y = np.meshgrid(gx, gy)
    return np.stack([X.ravel(), Y.ravel()]), np.full(nx * ny, width * height / (nx * ny))


def _strip(x, angle, through, half_width):
    """Points within half_width of the line at ``angle`` [deg] from the horizontal through
    ``through``."""
    a = math.radians(angle)
    return np.abs(-(x[0] - through[0]) * math.sin(a) + (x[1] - through[1]) * math.cos(a)) < half_width


def _noisy(x, bands):
    """A background of 0.01 with 20 % noise, 1 in the bands."""
    rng = np.random.default_rng(7)
    values = 0.01 * (1 + 0.2 * rng.random(x.shape[1]))
    values[np.any(bands, axis=0)] = 1.0
    return values


@pytest.mark.parametrize("angle", [40.0, -35.0, 62.0, 10.0])
def test_one_band_is_one_line_at_its_angle(angle):
    x, dx = _grid()
    values = _noisy(x, [_strip(x, angle, (0.5, 0.5), 0.03)])
    lines = band_lines(x, values, dx)
    assert len(lines) == 1
    assert lines[0].angle_deg == pytest.approx(angle, abs=1.5)


@pytest.mark.parametrize("angles", [(45.0, -45.0), (30.0, -30.0), (60.0, -20.0)])
def test_two_crossing_bands_are_both_reported(angles):
    x, dx = _grid()
    values = _noisy(x, [_strip(x, a, (0.5, 0.5), 0.03) for a in angles])
    lines = band_lines(x, values, dx)
    assert len(lines) == 2
    assert [b.angle_deg for b in lines] == pytest.approx(sorted(angles, reverse=True), abs=1.5)
    if angles == (30.0, -30.0):  # one line through the cross is neither band: the horizontal
        assert band_inclination(x, values, dx, top=0.1) < 5


def test_a_wedge_from_an_edge_imperfection_is_a_pair():
    """The biaxial specimen's pattern: two branches from the middle of the left side to the
    right corners (±45° on 0.05 × 0.1 m), the imperfection's disc left out."""
    x, dx = _grid(24, 48, 0.05, 0.1)
    branches = [_strip(x, a, (0.0, 0.05), 0.004) for a in (45.0, -45.0)]
    values = _noisy(x, branches)
    far = x[0] ** 2 + (x[1] - 0.05) ** 2 > 0.02 ** 2
    lines = band_lines(x, values, dx, mask=far)
    assert [b.angle_deg for b in lines] == pytest.approx([45.0, -45.0], abs=1.5)


def test_no_band_in_a_uniform_or_diffuse_field():
    x, dx = _grid()
    assert band_lines(x, np.full(dx.size, 0.3), dx) == []
    assert band_lines(x, 1.0 + 0.5 * x[0], dx) == []  # a gradient, nowhere twice the mean


def _result(x, dx, increment):
    """A biaxial run's result whose deviatoric strain increment after its peak is
    ``increment`` (a pure shear e12 = increment / 2)."""
    def snap(step, eps12):
        eps = np.zeros((dx.size, 3))
        eps[:, 2] = eps12
        zeros = np.zeros(dx.size)
        return Snapshot(step, step / 2, np.zeros(0), eps, np.zeros((dx.size, 3)), zeros, zeros, zeros)
    return FemResult("biaxial", None, ("q",), {"q": np.array([0.0, 2.0, 1.0])},
                     [snap(0, 0.0), snap(1, 0.0), snap(2, increment / 2)], [], x, dx, {})


def test_the_band_report_of_a_cross_lists_each_band():
    x, dx = _grid(50, 100, 0.05, 0.1)
    cross = _noisy(x, [_strip(x, a, (0.025, 0.05), 0.003) for a in (50.0, -50.0)])
    band = shear_band(_result(x, dx, cross))
    assert band["bands"] == 2
    assert [b["angle_deg"] for b in band["conjugate"]] == pytest.approx([50.0, -50.0], abs=1.5)
    assert band["angle_deg"] == pytest.approx(50.0, abs=1.5)
    assert all(b["width_m"] == pytest.approx(0.006, rel=0.3) for b in band["conjugate"])
    one = _noisy(x, [_strip(x, 50.0, (0.025, 0.05), 0.003)])
    band = shear_band(_result(x, dx, one))
    # one band: its second moment, as before
    assert band["bands"] == 1 and band["conjugate"] is None
    assert band["angle_deg"] == band_inclination(x, one, dx, top=0.2)
    assert shear_band(_result(x, dx, np.full(dx.size, 0.1)))["bands"] == 0


def test_the_cli_prints_each_band_of_a_pair(tmp_path, capsys, monkeypatch):
    import hmodel.fem
    from hmodel.cli.fem import _finish

    x, dx = _grid(50, 100, 0.05, 0.1)
    cross = _noisy(x, [_strip(x, a, (0.025, 0.05), 0.003) for a in (50.0, -50.0)])
    res = _result(x, dx, cross)
    res.meta = {"gauss_points": dx.size, "seconds": 1.0, "band": shear_band(res)}
    monkeypatch.setattr(hmodel.fem, "write_result", lambda res, out: None)
    _finish(res, tmp_path)
    line = capsys.readouterr().out.splitlines()[1]
    a, b = (band["angle_deg"] for band in res.meta["band"]["conjugate"])
    assert line.startswith(f"shear band at {a:+.1f}° from the horizontal and its conjugate at {b:+.1f}°, ")
    assert round(a) == 50 and round(b) == -50 and line.endswith("mm wide each, after the peak at step 1")
