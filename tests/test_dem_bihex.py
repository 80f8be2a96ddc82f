"""The bi-hexagon as a DEM cell (hmodel.dem.bihex, hmodel.dem.validate3d): against the closed
form, against the 2D DEM hexagon, through the 3D REV, and its bad input."""

from __future__ import annotations

import numpy as np
import pytest

from hmodel.cell.bihex import BIHEX_FIELDS, BIHEX_FLAGS, BiHexSolver, initial_bihex
from hmodel.cell.state import CellState
from hmodel.cli.app import main
from hmodel.errors import InputError
from hmodel.params import Params
from hmodel.solvers import get_solver, get_solver_3d

# The DEM keeps the grains in equilibrium: the closed form's `equilibrium` sliding closure.
PARAMS = Params(sliding_rhs="equilibrium")
FORCES = [BIHEX_FIELDS.index(f) for f in ("N1", "N2", "T1", "N1_b", "N2_b", "T1_b")]


@pytest.mark.yade
def test_dem_bihexagon_follows_the_closed_form_and_its_contacts_give_its_stress():
    """Three paths from the unloaded cell (both hexagons sliding; B sliding, A not; A sliding, B
    opening), 5 increments of 0.1 % cell strain, each driven over 1000 time steps: the DEM cell and the closed form (another
    solution of the same cell, refined 10x) within 1e-3 of the largest force, with the same
    sliding and opening flags; the Love-Weber sum over the DEM's own contacts equals the closed
    form's meso-stress of the DEM's fields (eq. 1.12 per hexagon)."""
    from hmodel.dem.bihex import simulate
    from hmodel.dem.validate3d import closed_form_path, love_weber
    from hmodel.dem.validate3d import VALIDATION_OPTIONS as OPTIONS

    dirs = np.array([[1.0, -0.5, -0.5], [1.0, 1.0, -1.0], [0.0, 1.0, -1.0]])
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    v0 = initial_bihex(PARAMS, np.full(3, PARAMS.alpha0)).values
    dl = -v0[:, [6, 7, 15]] * 1e-3 * dirs
    runs = simulate(PARAMS, v0, np.repeat(dl[:, None], 5, axis=1), OPTIONS)
    cf = closed_form_path(PARAMS, dl, 5, 10)
    for p in range(3):
        scale = np.abs(cf[p][:, FORCES]).max()
        assert np.abs(runs.values[p][:, FORCES] - cf[p][:, FORCES]).max() <= 1e-3 * scale
    _, flags = BiHexSolver().step(PARAMS, CellState(cf[:, -2]), *dl.T)
    sliding_open = [BIHEX_FLAGS.index(f) for f in ("sliding", "open1", "sliding_b", "open1_b")]
    assert np.array_equal(runs.flags[:, -1, sliding_open], flags.flags[:, sliding_open])
    assert flags.flags[:, sliding_open].tolist() == [[1, 0, 1, 0], [0, 0, 1, 0], [1, 0, 0, 1]]
    n, S = runs.positions.shape[:2]
    contacts = love_weber(runs.positions.reshape(n * S, 10, 3), [c for rec in runs.contacts for c in rec])
    fields = BiHexSolver().meso(PARAMS, CellState(runs.values[:, 1:].reshape(n * S, -1)))[0][:, :3]
    assert np.allclose(contacts, fields, rtol=0, atol=1e-9 * np.abs(fields).max())
    assert runs.unbalanced.max() <= OPTIONS.tol


@pytest.mark.yade
def test_a_bihexagon_loaded_in_one_plane_is_the_2d_dem_hexagon():
    """dl3 = 0: hexagon A follows (dl1, dl2) and hexagon B (dl1, 0) exactly as 2D DEM hexagons
    (dem:standard) do, two increments through the cell solvers (each rebuilds from the state)."""
    bihex, hexagon = get_solver("dem:bihexagon"), get_solver("dem:standard")
    dl1, dl2 = np.array([-6e-3, -4e-3]), np.array([8e-3, -5e-3])
    s3, s2 = bihex.initial(PARAMS, (2,)), hexagon.initial(PARAMS, (4,))
    for _ in range(2):
        s3, f3 = bihex.step(PARAMS, s3, dl1, dl2, 0.0)
        s2, f2 = hexagon.step(PARAMS, s2, np.concatenate([dl1, dl1]), np.concatenate([dl2, 0 * dl2]))
    both = np.concatenate([s3.values[:, :8], s3.values[:, 8:]])
    scale = np.abs(s2.values[:, [3, 4, 5]]).max()
    assert np.allclose(both[:, [3, 4, 5]], s2.values[:, [3, 4, 5]], rtol=0, atol=1e-7 * scale)
    assert np.allclose(both[:, [0, 1, 2, 6, 7]], s2.values[:, [0, 1, 2, 6, 7]], rtol=0, atol=1e-10)
    assert np.array_equal(np.concatenate([f3.flags[:, :5], f3.flags[:, 5:10]]), f2.flags)
    assert f2.flags[0, 1] and not f2.flags[1:, 1].any()  # hexagon A of the first opens
    assert np.all(np.abs(s2.values[1:, 5]) > 0.1 * scale)  # the others carry T1


@pytest.mark.yade
def test_rev3d_takes_the_dem_bihexagon():
    """One strain increment of a 3D REV of DEM bi-hexagons (Lebedev order 3, the increment driven
    over 1000 time steps): the stress of the closed-form REV (the increment in 10 steps) within
    1e-3 of its largest component."""
    from hmodel.rev import Rev3D
    from hmodel.rev.sphere import Sphere

    sphere = Sphere(order=3, n_azimuth=1)
    deps = np.array([[1e-3, -2e-4, -3e-4, 0.0, 2e-4, 0.0]])
    dem = Rev3D(PARAMS, sphere, solver=get_solver("dem:bihexagon:substeps=1000"))
    cf = Rev3D(PARAMS, sphere)
    a, b = dem.step(dem.initial(1), deps), cf.initial(1)
    for _ in range(10):
        b = cf.step(b, deps / 10)
    assert np.abs(a.sig - b.sig).max() <= 1e-3 * np.abs(b.sig).max()
    assert a.flags.flags[..., 0].any()  # hexagons sliding


def test_bad_input_is_one_line(tmp_path, capsys):
    """Unknown options, a 2D state, a meaningless volume, unknown paths and 2D-only options
    are refused in one line (no YADE is started), nothing written."""
    from hmodel.dem.validate3d import validate_bihex

    with pytest.raises(InputError, match="unknown option 'ratio'.*numerics"):
        get_solver("dem:bihexagon:ratio=0.5")
    solver = get_solver("dem:bihexagon")
    assert solver.n_lengths == 3 and solver.field_names() == BIHEX_FIELDS
    # hmodel run triaxial --solver dem:bihexagon takes it as is
    assert get_solver_3d("dem:bihexagon:substeps=500").options.substeps == 500
    with pytest.raises(InputError, match="16"):
        solver.step(PARAMS, get_solver("closed-form").initial(PARAMS, (2,)), 0.0, 0.0, 0.0)
    with pytest.raises(InputError, match="volume"):
        solver.step(Params(volume="hexagon-consistent"), solver.initial(PARAMS, (1,)), 0.0, 0.0, 0.0)
    from hmodel.data import DatasetSpec
    from hmodel.rev import Rev

    with pytest.raises(InputError, match="2D REV's cells take two lengths"):
        Rev(PARAMS, solver)
    with pytest.raises(InputError, match="3D model's cell"):
        DatasetSpec(kind=2, solver="dem:bihexagon")
    with pytest.raises(InputError, match="unknown bi-hexagon path 'shear'"):
        validate_bihex(PARAMS, paths=("shear",))
    with pytest.raises(InputError, match="3 finite numbers"):
        validate_bihex(PARAMS, paths=(("zero", (0, 0, 0)),))
    for args, message in ((["--probes", "2"], "--probes are the 2D cell's"),
                          (["--paths", "1:2"], "3 components"), (["--steps", "0"], "--steps")):
        assert main(["dem", "validate", "--dim", "3", *args, "--out", str(tmp_path / "v")]) == 1
        err = capsys.readouterr().err.strip()
        assert message in err and len(err.splitlines()) == 1
    assert not (tmp_path / "v").exists()


@pytest.mark.yade
def test_validate_dim3_writes_its_table_paths_and_figure(tmp_path, capsys):
    """``hmodel dem validate --dim 3``: one path, two increments, without cross contacts."""
    import csv

    assert main(["dem", "validate", "--dim", "3", "--paths", "mixed,1:0:0", "--steps", "2",
                 "--strain", "0.002", "--no-cross", "--out", str(tmp_path / "v")]) == 0
    assert sorted(p.name for p in (tmp_path / "v").iterdir()) == ["deviations.csv", "paths.csv",
                                                                   "validation.png"]
    rows = list(csv.DictReader(open(tmp_path / "v" / "deviations.csv")))
    assert [r["path"] for r in rows] == ["mixed", "1:0:0"]
    assert all(float(r["dev_force"]) <= 1e-3 for r in rows)
    assert len(list(csv.DictReader(open(tmp_path / "v" / "paths.csv")))) == 2 * 3
    assert "max |ΔF| / max |F|" in capsys.readouterr().out


@pytest.mark.yade
def test_validate_dim3_with_frictionless_cross_contacts_from_the_command_line(tmp_path):
    """``--frictionless-cross`` with ``-p cross_contacts=frictionless``: the closed form's cross
    contacts against their DEM twin on the path that couples the hexagons (D != 0)."""
    import csv

    assert main(["dem", "validate", "--dim", "3", "--paths", "unequal", "--steps", "6", "--strain", "0.03",
                 "-p", "cross_contacts=frictionless", "-p", "sliding_rhs=equilibrium",
                 "--frictionless-cross", "--out", str(tmp_path / "v")]) == 0
    rows = {r["cross"]: r for r in csv.DictReader(open(tmp_path / "v" / "deviations.csv"))}
    touching = rows["True"]
    assert int(touching["cross_steps"]) > 0
    assert float(touching["dev_force"]) < 2e-3 and float(touching["dev_stress"]) < 2e-3


def test_validation_counts_paths_runs_and_increments_before_building(monkeypatch):
    """The bi-hexagon validation's estimate is one cell per path and run (twice with cross
    contacts) over its increments (:func:`hmodel.dem.scene.scene_bytes`): at the budget YADE is
    asked (and found missing); a path, a run or an increment more is refused."""
    from hmodel.dem.scene import scene_bytes
    from hmodel.dem.validate3d import validate_bihex
    from hmodel.dem.yade import YadeNotFound
    from hmodel.limits import WorkTooLarge

    monkeypatch.setenv("HMODEL_YADE", "/no/such/yade")
    monkeypatch.setenv("HMODEL_MEMORY_LIMIT", str(int(scene_bytes(4, 3))))
    two, four = ("axial", "plane"), ("axial", "plane", "mixed", "opening")
    for paths, cross in ((two, True), (four, False)):
        with pytest.raises(YadeNotFound):
            validate_bihex(PARAMS, steps=3, paths=paths, cross=cross)
    with pytest.raises(WorkTooLarge, match="3 DEM bi-hexagon paths of 3 increments"):
        validate_bihex(PARAMS, steps=3, paths=(*two, "mixed"))
    with pytest.raises(WorkTooLarge, match="with and without cross contacts"):
        validate_bihex(PARAMS, steps=3, paths=four)
    with pytest.raises(WorkTooLarge, match="paths of 4 increments"):
        validate_bihex(PARAMS, steps=4, paths=two)
