"""The DEM backend (hmodel.dem): YADE cells against the closed form, Love-Weber stress, failures."""

from __future__ import annotations

import math
import os
import stat
import tempfile

import numpy as np
import pytest

from hmodel.cell import mesostructure as meso
from hmodel.cell.mesostress import meso_volume, meso_vsigma
from hmodel.cell.state import CellState
from hmodel.cli.app import main
from hmodel.dem.scene import DEMOptions, hcell_state, scene_settings, simulate
from hmodel.dem.yade import DEMError, EquilibriumError, YadeNotFound, YadeServer
from hmodel.params import Params

# The DEM keeps grain 2 in equilibrium; with T1 < 0 on the Coulomb cone that is the closed
# form's `equilibrium` closure (the report's lambda differs from it only when xi = -1).
PARAMS = Params(sliding_rhs="equilibrium")


def _increments(cell, theta_deg, step, n):
    th = math.radians(theta_deg)
    return np.tile([-cell.l1 * step * math.cos(th), -cell.l2 * step * math.sin(th)], (n, 1))


@pytest.mark.yade
def test_standard_cell_follows_closed_form_on_two_paths():
    """θ = 0: elastic, T1 > 0; θ = 90°: contact 1 slides with T1 < 0 (ξ = -1). DEM states and
    single-increment probes within 2 % of each quantity's range of the refined closed form,
    every increment quasi-static (unbalanced force ratio <= tol)."""
    from hmodel.dem.validate import validate

    v = validate(PARAMS, strain=0.02, steps=10, directions_deg=(0.0, 90.0), probe_at=(1.0,),
                 n_probe=4, refine=10)
    for row in v.rows:
        assert row["dev_cf_fine"] <= 0.02, row
        assert row["max_unbalanced"] <= DEMOptions().tol, row
        if row["kind"] == "probe":
            assert row["dev_increment"] <= 0.02, row
    assert v.dem[0, -1, 5] > 0 and v.dem[1, -1, 5] < 0  # T1 sign as in the closed form
    sliding = np.abs(v.dem[1, 1:, 5]) / v.dem[1, 1:, 3]
    assert np.allclose(sliding, math.tan(PARAMS.phi_g), rtol=5e-3)  # on the Coulomb cone


def _love_weber(contacts: np.ndarray) -> np.ndarray:
    """V sigma (2, 2) [N m] = sum f (x) b over the rows of a contact table
    (scene.CONTACT_COLUMNS): f the force on grain j by grain i, b = x_j - x_i the branch vector
    (report eq. 1.11, compression positive)."""
    c = np.asarray(contacts, float).reshape(-1, 8)
    return np.einsum("ca,cb->ab", c[:, 4:6], c[:, 6:8])


def vsigma(run) -> np.ndarray:
    """V sigma of every recorded step of a DEM cell run, full (not symmetrized), (S+1, 2, 2)."""
    return np.array([_love_weber(c) for c in run.contacts])


def _boundary_form(positions: np.ndarray, forces: np.ndarray) -> np.ndarray:
    """sum_p F_p (x) x_p (2, 2) from grain positions (g, 2) and resultant forces (g, 2)."""
    return np.einsum("pa,pb->ab", np.asarray(forces, float), np.asarray(positions, float))


def _skew_ratio(vs: np.ndarray) -> np.ndarray:
    """|skew part| / |V sigma| (Frobenius), 0 for a force-free cell; shape (...)."""
    vs = np.asarray(vs, float)
    skew = 0.5 * (vs - np.swapaxes(vs, -1, -2))
    norm = np.linalg.norm(vs, axis=(-2, -1))
    return np.where(norm > 0, np.linalg.norm(skew, axis=(-2, -1)) / np.where(norm > 0, norm, 1), 0.0)


@pytest.mark.yade
def test_love_weber_stress_of_standard_and_richer_cells():
    """Σ f⊗b over contacts equals Σ F_p⊗x_p over grains (boundary form), is symmetric for the
    mirror-symmetric cells, and equals eq. 1.12 with V of eq. 1.20 for the standard cell."""
    std = meso.standard(PARAMS.radius, PARAMS.alpha0)
    centre = meso.hexagon_center(PARAMS.radius, PARAMS.alpha0)
    unequal = meso.hexagon_unequal(PARAMS.radius, PARAMS.alpha0, ratio=0.7)
    cells = [(std, _increments(std, 30, 2e-3, 5)), (centre, _increments(centre, 90, 2e-3, 5)),
             (unequal, _increments(unequal, 20, 2e-3, 5))]
    runs, _ = simulate(cells, PARAMS)
    for run in runs:
        vs = vsigma(run)
        scale = np.abs(vs).max()
        assert scale > 0
        for k in range(run.n_steps + 1):
            assert np.allclose(vs[k], _boundary_form(run.positions[k], run.forces[k]),
                               atol=1e-6 * scale)
        assert _skew_ratio(vs).max() < 1e-6
    assert any(6 in c[:2] for c in runs[1].contacts[-1])  # the centre grain carries load
    state = CellState(hcell_state(runs[0]))
    ref = meso_vsigma(PARAMS, state)
    vs = vsigma(runs[0])
    assert np.allclose(vs[:, 0, 0], ref[:, 0], rtol=1e-9, atol=1e-9 * np.abs(ref).max())
    assert np.allclose(vs[:, 1, 1], ref[:, 1], rtol=1e-9, atol=1e-9 * np.abs(ref).max())
    assert np.allclose(std.volume(runs[0].positions), meso_volume(PARAMS, state), rtol=1e-12)


def _cli_fails(tmp_path, monkeypatch, capsys, extra_env=None):
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    for k, val in (extra_env or {}).items():
        monkeypatch.setenv(k, val)
    out = tmp_path / "out"
    code = main(["dem", "validate", "--steps", "2", "--directions", "0", "--probes", "0",
                 "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 1
    assert len(err.splitlines()) == 1 and err.startswith("hmodel: error: ")
    assert not out.exists()
    assert os.listdir(tmp_path / "tmp") == []  # YADE's work folder removed
    return err


def test_missing_yade_is_a_one_line_error(tmp_path, monkeypatch, capsys):
    err = _cli_fails(tmp_path, monkeypatch, capsys, {"HMODEL_YADE": str(tmp_path / "no-such-yade")})
    assert "YADE is not installed" in err and "apt-get install -y yade" in err
    with pytest.raises(YadeNotFound):
        simulate([(meso.standard(), np.zeros((1, 2)))], PARAMS)


def test_crashing_yade_is_a_one_line_error(tmp_path, monkeypatch, capsys):
    fake = tmp_path / "fake-yade"
    fake.write_text("#!/bin/sh\necho 'starting' >&2\necho 'Segmentation fault in the engine' >&2\nexit 1\n")
    fake.chmod(fake.stat().st_mode | stat.S_IEXEC)
    err = _cli_fails(tmp_path, monkeypatch, capsys, {"HMODEL_YADE": str(fake)})
    assert "YADE crashed (exit status 1): Segmentation fault in the engine" in err


@pytest.mark.yade
def test_no_equilibrium_is_a_one_line_error(tmp_path, monkeypatch, capsys):
    import hmodel.dem.validate as val

    capped = DEMOptions(max_iter=5, substeps=1, check_every=1)
    real = val.simulate
    monkeypatch.setattr(val, "simulate", lambda cells, params, options=None: real(cells, params, capped))
    err = _cli_fails(tmp_path, monkeypatch, capsys)
    assert "equilibrium not reached at step" in err and "within 5 iterations" in err
    with pytest.raises(EquilibriumError) as e:
        real([(meso.standard(), np.full((2, 2), -1e-3))], PARAMS, capped)
    assert isinstance(e.value, DEMError) and "\n" not in str(e.value)


@pytest.mark.yade
def test_a_failing_request_is_a_one_line_error_and_the_process_goes_on(tmp_path, monkeypatch):
    """The one transport: an unknown task, or a request the YADE side cannot read, is answered
    with a one-line DEMError; the same process then answers a good request, and its folder goes
    with it."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    with YadeServer() as yade:
        with pytest.raises(DEMError, match=r"^DEM: unknown task 'draw' \(known: runs, increment, biaxial, triaxial, bihex\)$"):
            yade.request("draw", {})
        with pytest.raises(DEMError, match=r"^DEM: KeyError: 'cells'$"):
            yade.request("runs", {})
        pid = yade.pid
        std = meso.standard()
        ok = yade.request("runs", {**scene_settings(PARAMS, std.radii.max(), DEMOptions()),
                                   "cells": [{"radii": std.radii.tolist(), "pos": std.positions.tolist(),
                                              "drive": list(std.drive), "l": [std.l1, std.l2],
                                              "half_width": std.half_width, "increments": [[-1e-3, 0.0]]}]})
        assert pid is not None and yade.pid == pid and ok["status"] == "ok"  # the process went on
        assert yade.calls == 3
        assert len(ok["cells"][0]) == 2 and ok["cells"][0][1]["unbalanced"] <= DEMOptions().tol
        assert len(os.listdir(tmp_path)) == 1
    assert os.listdir(tmp_path) == []


@pytest.mark.yade
@pytest.mark.parametrize("mesostructure", ["standard", "hexagon-center"])
def test_draw_writes_the_loaded_cell_as_png(tmp_path, capsys, mesostructure):
    import struct

    from matplotlib.image import imread

    out = tmp_path / "d"
    code = main(["dem", "draw", "--mesostructure", mesostructure, "--steps", "2", "--strain", "0.002",
                 "--out", str(out)])
    stdout, err = capsys.readouterr()
    assert code == 0, err
    assert "cell.png" in stdout and sorted(p.name for p in out.iterdir()) == ["cell.png"]
    png = (out / "cell.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and png[12:16] == b"IHDR"
    width, height = struct.unpack(">II", png[16:24])
    image = imread(out / "cell.png")  # decodes the whole file
    assert image.shape[:2] == (height, width) and min(width, height) >= 200
    assert np.ptp(image[..., :3]) > 0.5  # something drawn, not a blank canvas


def test_draw_refuses_an_unknown_mesostructure_before_starting_yade(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("HMODEL_YADE", str(tmp_path / "no-such-yade"))  # never reached
    code = main(["dem", "draw", "--mesostructure", "pentagon", "--out", str(tmp_path / "d")])
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1 and err.startswith("hmodel: error: "), err
    assert "unknown mesostructure 'pentagon'" in err and "standard" in err
    assert not (tmp_path / "d").exists()


def test_validation_counts_its_cells_and_increments_before_building_the_scene(monkeypatch):
    """The scene's estimate is cells x (the longest cell's increments + 1) x RECORD_BYTES, the
    cells a path each and a probe cell per probe and start state: at the budget the scene is
    built and YADE asked (and found missing); one probe or one increment more is refused."""
    from hmodel.dem.scene import RECORD_BYTES, scene_bytes
    from hmodel.dem.validate import validate
    from hmodel.limits import WorkTooLarge

    monkeypatch.setenv("HMODEL_YADE", "/no/such/yade")
    # one path of 4 increments, 3 probes from its steps 2 and 4: 7 cells over 5 increments
    assert scene_bytes(7, 5) == 7 * 6 * RECORD_BYTES
    monkeypatch.setenv("HMODEL_MEMORY_LIMIT", str(7 * 6 * RECORD_BYTES))
    kw = {"strain": 0.01, "directions_deg": (0.0,), "probe_at": (0.5, 1.0)}
    with pytest.raises(YadeNotFound):
        validate(PARAMS, steps=4, n_probe=3, **kw)
    with pytest.raises(WorkTooLarge, match=r"4 probes from 2 states of each \(9 cells"):
        validate(PARAMS, steps=4, n_probe=4, **kw)
    with pytest.raises(WorkTooLarge, match="paths of 5 increments"):
        validate(PARAMS, steps=5, n_probe=3, **kw)
    with pytest.raises(WorkTooLarge, match="HMODEL_MAX_INCREMENTS"):
        validate(PARAMS, steps=10**8, n_probe=3, **kw)
