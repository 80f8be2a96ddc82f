"""A calibration of the density variant on specimens of two void ratios made by hmodel at a known
α0 (so the truth is known), the calibrated model read back from calibration.json and run at
another density, and the least-squares starts on a Dask cluster."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from hmodel import InputError, Params
from hmodel.calibrate import CalibratedModel, Test, fit
from hmodel.calibrate.report import write
from hmodel.cli.app import main
from hmodel.loading import run_biaxial
from hmodel.rev.density import alpha0_for_void_ratio
from hmodel.variants import get_variant

BASE = Params(n_theta=36, sliding_rhs="equilibrium", phi_g=math.radians(28.0), kt_kn=0.5)
TRUE = BASE.with_(alpha0=math.radians(50.0))  # at e_ref = 0.8, the mean of the two specimens
KW = dict(step=1e-3, iso_step=1e-4)


def _specimen(e0: float, p0: float) -> Test:
    """A drained test of a specimen at void ratio e0: hmodel at the α0 the map gives it."""
    params = TRUE.with_(alpha0=alpha0_for_void_ratio(TRUE, 2, e0, 0.8))
    r = run_biaxial(params, [p0], 0.02, **KW)
    c, s = r.stage("consolidation"), r.stage("shear")
    e = np.asarray(s["eps11"]) - c["eps11"][-1]
    ev = np.asarray(s["eps_v"]) - c["eps_v"][-1]
    return Test("drained", p0, e[1::2], np.asarray(s["q"])[1::2], ev[1::2], name=f"e0 {e0}", e0=e0)


@pytest.fixture(scope="module")
def specimens():
    return [_specimen(0.75, 1e5), _specimen(0.85, 3e5)]


@pytest.fixture(scope="module")
def calibrated(specimens):
    return fit(specimens, ("alpha0",), base=BASE, starts=2, model="density", **KW)


def test_the_density_variant_finds_alpha0_at_the_mean_void_ratio(calibrated):
    assert calibrated.e_ref == pytest.approx(0.8)
    assert calibrated.fitted["alpha0"] == pytest.approx(50.0, abs=1e-3)
    assert calibrated.cost < 1e-8
    # the published model (one alpha0 for both specimens) cannot fit them as well
    published = fit(calibrated.tests, ("alpha0",), base=BASE, starts=2, **KW)
    assert published.cost > 100 * calibrated.cost + 1e-6


def test_the_calibrated_model_reads_back_and_runs_at_another_density(calibrated, tmp_path):
    write(calibrated, tmp_path / "cal")
    record = json.loads((tmp_path / "cal" / "calibration.json").read_text())
    assert record["model"]["variant"] == "density" and record["model"]["e_ref"] == pytest.approx(0.8)
    model = CalibratedModel.load(tmp_path / "cal")
    assert model.params == calibrated.params  # bit for bit, radians recorded
    assert model.params_at(None) == calibrated.params
    assert model.params_at(0.8).alpha0 == pytest.approx(calibrated.params.alpha0, rel=1e-12)
    assert model.params_at(0.7).alpha0 == alpha0_for_void_ratio(calibrated.params, 2, 0.7, calibrated.e_ref)
    with pytest.raises(InputError, match="positive void ratio"):
        model.params_at(-1.0)
    published = replace(model, variant=get_variant("published"))
    with pytest.raises(InputError, match="--e0 sets the initial state"):
        published.params_at(0.7)


def test_a_folder_without_a_model_record_is_one_line(tmp_path):
    (tmp_path / "calibration.json").write_text('{"method": "least-squares"}')
    with pytest.raises(InputError, match="records no model"):
        CalibratedModel.load(tmp_path)
    with pytest.raises(InputError, match="cannot read calibration"):
        CalibratedModel.load(tmp_path / "nowhere")


@pytest.mark.slow
def test_the_cli_calibrates_the_sand_variant_and_refuses_a_test_without_e0(specimens, tmp_path, capsys):
    files = []
    for t in specimens:
        f = tmp_path / f"{t.e0}.csv"
        f.write_text("eps11,q,eps_v\n" + "".join(f"{float(a)!r},{float(b)!r},{float(c)!r}\n" for a, b, c in zip(t.eps11, t.q, t.eps_v)))
        files.append(f"drained:{t.p0:g}:{f}:e0={t.e0}")
    common = ["calibrate", "--fit", "alpha0", "--starts", "1", "-p", "n_theta=36", "-p", "sliding_rhs=equilibrium",
              "-p", "phi_g=28", "-p", "kt_kn=0.5"]
    assert main([*common, "--data", files[0], "--data", files[1], "--model", "density", "--out", str(tmp_path / "o")]) == 0
    fitted = json.loads((tmp_path / "o" / "calibration.json").read_text())["fitted"]["alpha0"]
    assert fitted == pytest.approx(50.0, abs=1e-3)
    bare = files[0].rpartition(":e0=")[0]
    assert main([*common, "--data", bare, "--model", "density", "--out", str(tmp_path / "n")]) == 1
    err = capsys.readouterr().err
    assert "has no e0" in err and err.count("\n") == 1 and not (tmp_path / "n").exists()
    assert main([*common, "--data", files[0], "--model", "clay", "--out", str(tmp_path / "m")]) == 1
    assert "no model 'clay'" in capsys.readouterr().err


@pytest.mark.slow
def test_starts_on_a_dask_cluster_give_the_local_calibration(specimens):
    distributed = pytest.importorskip("distributed")
    kw = dict(base=BASE, starts=2, model="density", **KW)
    local = fit(specimens, ("alpha0", "phi_g"), **kw)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        remote = fit(specimens, ("alpha0", "phi_g"), scheduler=cluster.scheduler_address, **kw)
    assert [s["end"] for s in remote.starts] == [s["end"] for s in local.starts]
    np.testing.assert_array_equal(remote.z, local.z)
    assert remote.cost == local.cost


@pytest.mark.slow
def test_run_commands_take_the_calibrated_model_at_a_void_ratio(calibrated, tmp_path):
    """run biaxial --calibration DIR --e0 E gives the run of -p with the fitted parameters and
    the alpha0 the map gives at E, bit for bit; a program and fem take it too."""
    write(calibrated, tmp_path / "cal")
    p = calibrated.params
    a0 = math.degrees(alpha0_for_void_ratio(p, 2, 0.78, calibrated.e_ref))
    common = ["--p0", "100kPa", "--axial-strain", "0.003", "--step", "1e-3"]
    assert main(["run", "biaxial", *common, "--calibration", str(tmp_path / "cal"), "--e0", "0.78",
                 "--out", str(tmp_path / "a")]) == 0
    explicit = [f"{k}={v if isinstance(v, str) else repr(v)}" for k, v in p.to_dict().items() if k != "alpha0"] + [f"alpha0={a0!r}"]
    assert main(["run", "biaxial", *common, *sum((["-p", e] for e in explicit), []), "--out", str(tmp_path / "b")]) == 0
    a, b = ((tmp_path / d / "result.csv").read_text().splitlines() for d in "ab")
    assert len(a) == len(b) > 3
    np.testing.assert_allclose(np.loadtxt(a[1:], delimiter=",", usecols=range(3, 12)),
                               np.loadtxt(b[1:], delimiter=",", usecols=range(3, 12)), rtol=1e-12, atol=1e-9)
    program = tmp_path / "p.toml"
    program.write_text('[[stage]]\npreset = "iso"\np = "100kPa"\n[[stage]]\npreset = "drained"\neps11 = 0.002\nsteps = 2\n')
    assert main(["run", "program", str(program), "--calibration", str(tmp_path / "cal"), "--e0", "0.78",
                 "--out", str(tmp_path / "c")]) == 0
    assert main(["fem", "biaxial", "--mesh", "1x2", "--steps", "2", "--axial-strain", "0.002",
                 "--calibration", str(tmp_path / "cal"), "--e0", "0.78", "--out", str(tmp_path / "f")]) == 0


def test_a_calibration_records_the_variant_an_alias_named(tmp_path):
    """A calibration keeps the variant it fitted, not the alias it was asked by: ``sand`` is
    recorded as ``axisym-mix`` (what it names now), and a record of ``hertz`` (what ``sand``
    named before) still loads as hertz, with the contacts its parameters recorded."""
    from hmodel import Params

    assert get_variant("sand").name == "axisym-mix"
    params = Params(contact="hertz-mindlin", alpha0=0.9)
    record = {"model": {"variant": "hertz", "e_ref": 0.8, "dim": 3,
                        "params_rad": params.to_dict(degrees=False)}}
    (tmp_path / "calibration.json").write_text(json.dumps(record))
    model = CalibratedModel.load(tmp_path)
    assert model.variant is get_variant("hertz")
    assert model.params_at(0.8).renewal == "none" and model.params_at(0.8).contact == "hertz-mindlin"
