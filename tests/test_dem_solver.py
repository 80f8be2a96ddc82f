"""The DEM cell solver (hmodel.dem.solver) through the REV, the loading drivers and the datasets."""

from __future__ import annotations

import json
import stat

import numpy as np
import pytest

from hmodel.solvers import get_solver
from hmodel.cli.app import main
from hmodel.dem.yade import DEMError
from hmodel.loading import run_biaxial
from hmodel.params import Params
from hmodel.rev import Rev


# The DEM keeps the grains in equilibrium: the closed form's `equilibrium` sliding closure.
PARAMS = Params(sliding_rhs="equilibrium", n_theta=6)


def test_spec_options_are_the_mesostructures_or_numerics():
    """``dem:NAME:K=V,...``: the mesostructure's options go to its geometry
    (:class:`hmodel.cell.geometry.CellGeometry`), DEM numerics to the options; any other is
    refused with one line (no YADE is started)."""
    from hmodel.errors import InputError
    s = get_solver("dem:hexagon-unequal:ratio=0.6,tol=1e-7")
    assert s.name == "dem:hexagon-unequal:ratio=0.6,tol=1e-07"
    assert s.geometry.options == {"ratio": 0.6} and s.options.tol == 1e-7 and s.n_fields == 8 + 12 + 15
    assert get_solver("dem:standard").field_names() == ("d1", "d2", "alpha", "N1", "N2", "T1", "l1", "l2")
    with pytest.raises(InputError, match="unknown option 'foo'.*ratio"):
        get_solver("dem:hexagon-center:foo=1")


@pytest.mark.yade
def test_drained_biaxial_through_the_rev_matches_closed_form():
    """Consolidation to 200 kPa then 0.4 % drained axial strain: the DEM-REV stress-strain
    curve lies within 0.5 % of the closed form's range (per-step difference of the two)."""
    kw = dict(axial_strain=0.004, step=1e-3, iso_step=2e-4)
    dem = run_biaxial(PARAMS, [2e5], solver=get_solver("dem:standard"), **kw)
    cf = run_biaxial(PARAMS, [2e5], **kw)
    assert dem.meta["solver"] == "dem:standard"
    assert len(dem) == len(cf)
    for col in ("sig11", "eps22", "q"):
        a, b = np.asarray(dem[col]), np.asarray(cf[col])
        assert np.max(np.abs(a - b)) <= 5e-3 * np.ptp(b), col
    assert abs(np.asarray(dem["sig22"])[-1] - 2e5) <= 1e-5 * 2e5  # the drained condition holds


@pytest.mark.yade
def test_step_is_pure_and_batch_independent():
    solver = get_solver("dem:standard")
    s0 = solver.initial(PARAMS, (3,))
    dl1, dl2 = np.array([-5e-3, -5e-3, 2e-3]), np.array([-3e-3, 1e-3, -3e-3])
    s1, _ = solver.step(PARAMS, s0, dl1, dl2)
    a, fa = solver.step(PARAMS, s1, dl1, dl2)
    b, fb = get_solver("dem:standard").step(PARAMS, s1, dl1, dl2)  # another YADE process
    assert np.array_equal(a.values, b.values) and np.array_equal(fa.flags, fb.flags)
    # the rows of the previous request (a Newton iteration's converged points) are not sent again
    calls = solver.yade().calls
    again, _ = solver.step(PARAMS, s1, dl1, dl2)
    assert solver.yade().calls == calls and np.array_equal(again.values, a.values)
    other = dl1.copy()
    other[0] = -4e-3
    mixed, fm = solver.step(PARAMS, s1, other, dl2)
    assert solver.yade().calls == calls + 1 and np.array_equal(mixed.values[1:], a.values[1:])
    assert not np.allclose(mixed.values[0], a.values[0]) and np.array_equal(fm.flags[1:], fa.flags[1:])
    assert np.array_equal(s1.values, solver.step(PARAMS, s0, dl1, dl2)[0].values)  # input untouched
    # a cell alone gives what it gives in a batch (each cell is frozen once balanced)
    alone, _ = get_solver("dem:standard").step(PARAMS, type(s1)(s1.values[1:2]), dl1[1:2], dl2[1:2])
    assert np.allclose(alone.values[0], a.values[1], rtol=1e-9, atol=1e-9)
    # so a batch sent in requests of at most two cells gives the same
    split, fs = get_solver("dem:standard:max_cells=2").step(PARAMS, s1, dl1, dl2)
    assert np.allclose(split.values, a.values, rtol=1e-9, atol=1e-9) and np.array_equal(fs.flags, fa.flags)


@pytest.mark.yade
def test_richer_cell_through_the_rev_gives_symmetric_stress():
    """A hexagon with a centre grain: 21 extra fields, the REV takes its Love-Weber stress
    from the solver. Under equal strains the stress is isotropic, under axial strain sig12 = 0
    (mirror symmetry); the centre grain stiffens the material against the standard cell."""
    rev = Rev(PARAMS, get_solver("dem:hexagon-center"))
    std = Rev(PARAMS, get_solver("dem:standard"))
    assert rev.solver.n_fields == 8 + 14 + 21
    s, t = rev.initial(2), std.initial(2)
    deps = np.array([[5e-4, 5e-4, 0.0], [1e-3, 0.0, 0.0]])
    for _ in range(3):
        s, t = rev.step(s, deps), std.step(t, deps)
    iso, axial = s.sig
    assert iso[0] > 0 and abs(iso[0] - iso[1]) <= 1e-6 * iso[0] and abs(iso[2]) <= 1e-9 * iso[0]
    assert axial[0] > axial[1] > 0 and abs(axial[2]) <= 1e-9 * axial[0]
    assert iso[0] > t.sig[0, 0]
    assert s.cells.values.shape == (2, PARAMS.n_theta, rev.solver.n_fields)


def _generate(tmp_path, name, *extra):
    return main(["data", "generate", "1", "-o", str(tmp_path / name), "--directions", "2",
                 "--alpha0", "45:45:2", "--max-strain", "0.003", "--step", "0.001",
                 "--workers", "1", "--solver", "dem", *extra])


@pytest.mark.yade
def test_data_generate_with_dem(tmp_path):
    import pyarrow.parquet as pq

    from hmodel.data import Dataset
    from hmodel.data.generator import DatasetSpec, compute_shard

    assert _generate(tmp_path, "std") == 0
    ds = Dataset.open(tmp_path / "std")
    assert ds.n_rows == 6 and ds.spec.solver == "dem:standard"
    rows = ds.read()
    cf = compute_shard(DatasetSpec(n_directions=2, alpha0_min=45, alpha0_max=45, max_strain=0.003,
                                   step=0.001, theta_min=0, theta_max=90),
                       Params(sliding_rhs="equilibrium"), 0)
    # the DEM standard cell follows the closed form (default params: report closure, no slip here)
    n1 = cf.column("N1_next").to_numpy()
    assert np.max(np.abs(rows["N1_next"] - n1)) <= 0.01 * np.ptp(n1)
    assert _generate(tmp_path, "centre", "--mesostructure", "hexagon-center") == 0
    table = pq.read_table(tmp_path / "centre" / "part-00000.parquet")
    manifest = json.loads((tmp_path / "centre" / "manifest.json").read_text())
    assert len(manifest["extra_fields"]) == 35 and table.column("state_extra").type.list_size == 35
    # Dataset 3 from a DEM-REV of richer cells: the consolidated cells of an isotropic REV are alike
    assert main(["data", "generate", "3", "-o", str(tmp_path / "rev"), "--directions", "4", "--rev-paths",
                 "undrained:1e5", "--max-strain", "0.001", "--start-every", "0.001", "--from-unloaded",
                 "--increments", "2", "--magnitude", "0.001", "--substeps", "1", "--workers", "1",
                 "--solver", "dem", "--mesostructure", "hexagon-center:tol=1e-7"]) == 0
    rev = Dataset.open(tmp_path / "rev").read()
    assert len(rev["N1"]) == 4 * 2 * 2 and rev["state_extra"].shape == (16, 35)
    rest = rev["start_strain"] == 0
    assert rev["N1"][rest].min() > 0 and np.ptp(rev["N1"][rest]) <= 1e-3 * rev["N1"][rest].max()


def test_failing_yade_leaves_no_shard(tmp_path, monkeypatch, capsys):
    fake = tmp_path / "yade"
    fake.write_text("#!/bin/sh\necho 'Segmentation fault (core dumped)' >&2\nexit 1\n")
    fake.chmod(fake.stat().st_mode | stat.S_IEXEC)
    monkeypatch.setenv("HMODEL_YADE", str(fake))
    with pytest.raises(DEMError, match=r"YADE crashed \(exit status 1\): Segmentation fault"):
        get_solver("dem:standard").step(PARAMS, get_solver("dem").initial(PARAMS, (1,)), -1e-3, 0.0)
    assert _generate(tmp_path, "bad") != 0
    err = capsys.readouterr().err
    assert "YADE crashed (exit status 1)" in err
    out = tmp_path / "bad"
    assert not list(out.glob("*.parquet")) and not list(out.glob("*.part"))
    assert json.loads((out / "manifest.json").read_text())["complete"] is False
