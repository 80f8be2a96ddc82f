"""3D laboratory tests of the H-model: the triaxial test drained and undrained, in compression
and extension, the true triaxial test at constant p and b, the oedometer and its K0, as stages
on six components, from Python, programs and the command line.

Physics, not copied numbers: what each test holds (its rows) must hold along the path, the
Lode angle follows from b, batches equal separate runs (a batch of pressures and bad input are
tested for the 2D and the 3D model alike in test_loading.py). A cheap rule (Lebedev order 9, 38
bi-hexagons) and ``sliding_rhs=equilibrium`` (the 3D command line's default).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from hmodel import Params
from hmodel.cli.app import main
from hmodel.errors import InputError
from hmodel.loading import Program, run_oedometer, run_triaxial, run_true_triaxial
from hmodel.loading.stages import PRESETS_3D, ROWS_3D, Stage, component_order
from hmodel.rev import Rev
from hmodel.rev.rev3d import Rev3D
from hmodel.rev.sphere import Sphere

P = Params(sliding_rhs="equilibrium")
S = Sphere(order=9)
P0 = 2e5
EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "triaxial-unload-reload.toml"


def _end_of_consolidation(res, b=0):
    return res.point(b).stage("consolidation")


@pytest.fixture(scope="module")
def drained():
    return run_triaxial(P, P0, 0.03, sphere=S)


def test_drained_triaxial_holds_the_radial_stress_and_no_shear(drained):
    sh = drained.stage("shear")
    assert len(sh) == 300
    np.testing.assert_allclose(sh["sig22"], P0, rtol=1e-8)
    np.testing.assert_allclose(sh["sig33"], P0, rtol=1e-8)
    for c in ("eps12", "eps13", "eps23"):
        assert np.all(sh[c] == 0.0)
    for c in ("sig12", "sig13", "sig23"):
        assert np.abs(sh[c]).max() < 1e-6 * P0
    # axial compression: q = sig11 - (sig22 + sig33)/2 > 0 at Lode angle 0 (b = 0), q = q_eq
    assert np.all(sh["q"] > 0) and sh["q"].max() > 0.5 * P0
    np.testing.assert_allclose(sh["lode"], 0.0, atol=1e-4)
    np.testing.assert_allclose(sh["q_eq"], sh["q"], rtol=1e-6)
    np.testing.assert_allclose(sh["p"], (sh["sig11"] + sh["sig22"] + sh["sig33"]) / 3, rtol=1e-14)
    np.testing.assert_allclose(sh["eps_v"], sh["eps11"] + sh["eps22"] + sh["eps33"], rtol=1e-12)
    # the axial strain moves by its increments from the end of consolidation
    e0 = _end_of_consolidation(drained)["eps11"][-1]
    assert sh["eps11"][-1] - e0 == pytest.approx(0.03, rel=1e-12)
    assert drained.meta["test"] == "drained triaxial compression"
    assert drained.meta["sphere"]["order"] == 9


def test_undrained_triaxial_keeps_the_volume_and_axisymmetric_strain():
    res = run_triaxial(P, P0, 0.02, undrained=True, sphere=S)
    sh, c = res.stage("shear"), _end_of_consolidation(res)
    np.testing.assert_allclose(sh["eps_v"], c["eps_v"][-1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(sh["eps22"], sh["eps33"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(sh["eps22"] - c["eps22"][-1], -0.5 * (sh["eps11"] - c["eps11"][-1]),
                               rtol=1e-9)
    assert np.all(sh["q"] > 0)
    assert res.meta["test"] == "undrained triaxial compression"


def test_extension_unloads_the_axis_at_constant_radial_stress():
    res = run_triaxial(P, P0, 0.02, extension=True, sphere=S)
    sh, c = res.stage("shear"), _end_of_consolidation(res)
    assert sh["eps11"][-1] - c["eps11"][-1] == pytest.approx(-0.02, rel=1e-12)
    np.testing.assert_allclose(sh["sig22"], P0, rtol=1e-8)
    np.testing.assert_allclose(sh["sig33"], P0, rtol=1e-8)
    assert np.all(sh["q"] < 0) and np.all(sh["sig11"] < sh["sig22"])
    # sig11 < sig22 = sig33: two equal major principal stresses, b = 1, Lode angle 60 degrees
    np.testing.assert_allclose(sh["lode"], 60.0, atol=1e-4)
    np.testing.assert_allclose(sh["b"], 1.0, atol=1e-6)
    np.testing.assert_allclose(sh["q_eq"], -sh["q"], rtol=1e-6)


@pytest.mark.parametrize("b", [0.0, 0.25, 0.5])
def test_true_triaxial_keeps_p_and_b_and_gives_their_lode_angle(b):
    res = run_true_triaxial(P, P0, b, 0.02, sphere=S)
    sh = res.stage("shear")
    np.testing.assert_allclose(sh["p"], P0, rtol=1e-8)
    s1, s2, s3 = sh["sig11"], sh["sig22"], sh["sig33"]
    assert np.all(s1 >= s2) and np.all(s2 >= s3 - 1e-6 * P0)  # principal axes stay 1, 2, 3
    np.testing.assert_allclose((s2 - s3) - b * (s1 - s3), 0.0, atol=1e-9 * P0)  # Newton's tolerance
    np.testing.assert_allclose(sh["b"], b, atol=1e-6)
    lode = math.degrees(math.atan2(math.sqrt(3) * b, 2 - b))
    np.testing.assert_allclose(sh["lode"], lode, atol=1e-3)
    assert np.all(sh["q_eq"] > 0) and res.meta["b"] == b


def test_true_triaxial_at_b_0_is_the_constant_p_triaxial_test():
    tt = run_true_triaxial(P, P0, 0.0, 0.01, sphere=S).stage("shear")
    rows = {"eps11": 0.01, "p": "hold", "sig22-sig33": 0.0, "eps23": 0.0, "eps13": 0.0, "eps12": 0.0}
    assert set(rows) == set(PRESETS_3D["constant_p"][0]) | {"eps11"}
    from hmodel.loading import Recorder, consolidate, run_segment

    rev = Rev3D(P, S)
    s = consolidate(rev, P0)
    rec = Recorder()
    run_segment(rev, s, Stage("shear", rows, steps=100).segment(s), rec)
    np.testing.assert_allclose(rec.result()["sig11"], tt["sig11"], rtol=1e-8)


def test_oedometer_keeps_the_lateral_strains_and_reports_k0():
    res = run_oedometer(P, [1e5, 2e5], 0.01, sphere=S)
    assert len(res.meta["K0"]) == 2
    for b in range(2):
        sh, c = res.point(b).stage("shear"), _end_of_consolidation(res, b)
        for comp in ("eps22", "eps33"):
            np.testing.assert_array_equal(sh[comp], c[comp][-1])
        k0 = 0.5 * (sh["sig22"] + sh["sig33"]) / sh["sig11"]
        np.testing.assert_allclose(sh["K0"], k0, rtol=1e-14)
        assert 0 < res.meta["K0"][b] < 1 and res.meta["K0"][b] == sh["K0"][-1]
        assert np.all(sh["sig11"] > sh["sig22"])  # loaded axially, the radial stress lags
        np.testing.assert_allclose(c["K0"], 1.0, rtol=1e-9)  # isotropic consolidation


def test_a_batch_of_parameter_sets_equals_separate_runs():
    # (a batch of pressures, and bad input: test_loading.py, for both models)
    sets = [Params(sliding_rhs="equilibrium", phi_g=math.radians(a)) for a in (25, 35)]
    batch = run_true_triaxial(sets, P0, 0.5, 0.01, sphere=S)
    assert batch.meta["point_params"][1]["phi_g"] == pytest.approx(35)
    for b, s in enumerate(sets):
        one = run_true_triaxial(s, P0, 0.5, 0.01, sphere=S)
        for c in ("eps11", "eps22", "eps33", "sig11", "sig22", "sig33"):
            np.testing.assert_allclose(batch.point(b)[c], one[c], rtol=1e-9, atol=1e-14)
    assert batch.point(1)["q"].max() > batch.point(0)["q"].max()  # more friction, more strength


# ---------------------------------------------------------------------- stages on 6 components

def test_3d_rows_and_the_dimension_of_a_stage():
    assert component_order(["eps12", "sig33", "eps_v", "eps11", "eps13", "eps23"]) == \
        ["eps11", "eps_v", "sig33", "eps23", "eps13", "eps12"]
    rev2, rev3 = Rev(Params(n_theta=12)), Rev3D(P, Sphere(order=5))
    s2, s3 = rev2.initial(1), rev3.initial(1)
    with pytest.raises(InputError, match="unknown component 'eps33' of a 2D stage.*3D row"):
        Stage("x", {"eps11": 0.01, "eps33": 0.0, "eps12": 0.0}).segment(s2)
    with pytest.raises(InputError, match="3 rows for a 3D stage, which needs 6"):
        Stage("x", {"eps11": 0.01, "sig22": "hold", "eps12": 0.0}).segment(s3)
    seg = Stage("x", {"eps11": 0.01, "p": 1e5, "b": 0.5, "eps23": 0, "eps13": 0, "eps12": 0}).segment(s3)
    assert seg.stress_rows == (False, True, True, False, False, False)
    np.testing.assert_allclose(seg.matrix[2], [-0.5, 1, -0.5, 0, 0, 0])
    np.testing.assert_allclose(seg.values, [0.01, 1e5, 0.0, 0, 0, 0])
    for fixed, drivers in PRESETS_3D.values():
        assert set(fixed) | set(drivers) <= set(ROWS_3D)
        assert len(fixed) == 5


def _program(text: str) -> Program:
    return Program.from_dict(__import__("tomllib").loads(text))


ISO = '[[stage]]\npreset = "iso"\np = "200kPa"\n'


def test_3d_programs_check_their_rows_against_their_dimension():
    prog = _program('dim = 3\n[sphere]\norder = 9\n' + ISO +
                    '[[stage]]\npreset = "true_triaxial"\nb = 0.5\neps11 = 0.005\n')
    assert prog.dim == 3 and prog.sphere.order == 9
    res = prog.run(Params(sliding_rhs="equilibrium"))
    sh = res.stage("true_triaxial")
    np.testing.assert_allclose(sh["b"], 0.5, atol=1e-7)
    assert res.meta["dim"] == 3 and "eps33" in res.columns
    bad = [
        (ISO + '[[stage]]\ncontrol = {eps11 = 0.01, eps33 = 0, eps12 = 0}\n', "a 3D row: a 3D program says dim = 3"),
        ('dim = 3\n' + ISO + '[[stage]]\ncontrol = {eps11 = 0.01, sig22 = "hold", eps12 = 0}\n',
         "component 23 is not controlled"),
        ('dim = 3\n' + ISO + '[[stage]]\npreset = "true_triaxial"\nb = 2\neps11 = 0.01\n', r"b must be a number in \[0, 1\]"),
        (ISO + '[[stage]]\npreset = "true_triaxial"\neps11 = 0.01\n', "'true_triaxial' is a 3D preset"),
        ('dim = 3\n' + ISO + '[[stage]]\npreset = "proportional"\ndirection = [1, 0, 0]\nmagnitude = 0.01\n',
         "direction must be 6 numbers"),
        ('dim = 4\n' + ISO, "dim must be 2"),
        ('[sphere]\norder = 13\n' + ISO, "Lebedev rule order"),
        ('dim = 3\n[params]\nn_theta = 72\n' + ISO, r"\[sphere\] order"),
        ('dim = 3\n' + ISO + '[[stage]]\npreset = "drained"\nq = "p0"\nuntil = "lode >= 1"\nsteps = 5\n'
         '[[stage]]\npreset = "drained"\neps11 = 0.01\nuntil = "bogus > 1"\n', "bogus"),
    ]
    for text, phrase in bad:
        with pytest.raises(InputError, match=phrase):
            _program(text)


def test_the_3d_example_program_runs():
    prog = Program.from_toml(EXAMPLE)
    assert prog.dim == 3
    res = prog.run(prog.with_params([]))
    p0 = res.meta["p0"][0]
    load = res.stage("load")
    np.testing.assert_allclose(load["sig22"], p0, rtol=1e-8)
    np.testing.assert_allclose(load["sig33"], p0, rtol=1e-8)
    assert res.stage("unload")["q"][-1] == pytest.approx(0.1 * p0, rel=1e-6)
    reload = res.stage("reload")
    assert reload["q_p"][-1] >= 1.0 and reload["q_p"][-2] < 1.0  # ended by its criterion
    tt = res.stage("true triaxial")
    # from b = 0 at the end of the reload, the row (s22 - s33) - b (s11 - s33) = 0 is reached
    # linearly over the stage's increments (a stress row's target): b rises to 0.5
    assert tt["b"][-1] == pytest.approx(0.5, abs=1e-6) and np.all(np.diff(tt["b"]) > 0)
    np.testing.assert_allclose(tt["p"], reload["p"][-1], rtol=1e-8)


# ---------------------------------------------------------------------- the command line

CONTRACT = ["eps11", "eps22", "eps33", "eps12", "eps13", "eps23", "sig11", "sig22", "sig33", "sig12",
            "sig13", "sig23", "p", "q", "eps_v", "q_p", "lode", "b"]


def _read(path: Path) -> dict[str, np.ndarray]:
    with open(path) as fh:
        rows = list(csv.reader(fh))
    return {h: np.array([r[j] for r in rows[1:]]) for j, h in enumerate(rows[0])}


def test_cli_triaxial_writes_the_3d_contract_columns(tmp_path, capsys):
    out = tmp_path / "tx"
    assert main(["run", "triaxial", "--p0", "100kPa,200kPa", "--axial-strain", "0.01", "--order", "9",
                 "--out", str(out)]) == 0
    cols = _read(out / "result.csv")
    assert list(cols)[3:3 + len(CONTRACT) - 2] == CONTRACT[:-2] and {"lode", "b", "q_eq"} <= set(cols)
    assert set(cols["point"]) == {"0", "1"} and (out / "result.png").stat().st_size > 0
    sh = cols["stage"] == "shear"
    np.testing.assert_allclose(cols["sig22"][sh].astype(float)[cols["point"][sh] == "1"], 2e5, rtol=1e-8)
    assert main(["run", "triaxial", "--extension", "--undrained", "--axial-strain", "0.005", "--order", "9",
                 "-p", "phi_g=25,35", "--out", str(tmp_path / "ext")]) == 0
    ext = _read(tmp_path / "ext" / "result.csv")
    assert set(ext["point"]) == {"0", "1"} and np.all(ext["q"][ext["stage"] == "shear"].astype(float) < 0)


def test_cli_true_triaxial_and_oedometer(tmp_path, capsys):
    assert main(["run", "true-triaxial", "--b", "0.5", "--axial-strain", "0.005", "--order", "9",
                 "--azimuths", "1", "--out", str(tmp_path / "tt")]) == 0
    tt = _read(tmp_path / "tt" / "result.csv")
    sh = tt["stage"] == "shear"
    np.testing.assert_allclose(tt["lode"][sh].astype(float), 30.0, atol=1e-4)
    capsys.readouterr()
    assert main(["run", "oedometer", "--axial-strain", "0.005", "--order", "9",
                 "--out", str(tmp_path / "oed")]) == 0
    text = capsys.readouterr().out
    oed = _read(tmp_path / "oed" / "result.csv")
    k0 = float(oed["K0"][-1])
    assert 0 < k0 < 1 and f"K0 = sig_r/sig_a after 0.005 axial strain (p0 = 200 kPa): {k0:.4f}" in text


def test_cli_3d_program(tmp_path):
    assert main(["run", "program", str(EXAMPLE), "--out", str(tmp_path / "p")]) == 0
    cols = _read(tmp_path / "p" / "result.csv")
    assert set(CONTRACT) <= set(cols) and "cycle" in cols


def test_cli_failure_surface_writes_its_tables_and_figure(tmp_path, capsys):
    out = tmp_path / "fs"
    assert main(["failure-surface", "--p", "200kPa", "--lode", "60", "--order", "5", "--max-strain", "0.05",
                 "--out", str(out)]) == 0
    assert {p.name for p in out.iterdir()} == {"failure_surface.csv", "failure_surface.json",
                                                "failure_surface.png", "paths.csv"}
    table = _read(out / "failure_surface.csv")
    np.testing.assert_array_equal(table["lode"].astype(float), [0.0, 60.0])  # 0 added for the fits
    info = __import__("json").loads((out / "failure_surface.json").read_text())
    q_p = table["q_p"].astype(float)
    assert info["strength_ratio"] == pytest.approx(q_p[1] / q_p[0], rel=1e-12)
    assert info["params"]["sliding_rhs"] == "equilibrium" and info["order"] == 5
    # the fits agree with the model at compression, where they are fitted
    for fit in ("mohr_coulomb", "matsuoka_nakai", "lade_duncan"):
        assert float(table[fit][0]) == pytest.approx(q_p[0], rel=1e-9)
    paths = _read(out / "paths.csv")
    assert set(CONTRACT) <= set(paths) and set(paths["point"]) == {"0", "1"}
    assert "extension/compression strength ratio" in capsys.readouterr().out
