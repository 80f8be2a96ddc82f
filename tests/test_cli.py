"""The ``hmodel`` command line as a user runs it (DESIGN.md, "Public contract")."""

import csv
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hmodel.loading.result import COLUMNS

CONTRACT = ("eps11", "eps22", "eps12", "sig11", "sig22", "sig12", "p", "q", "eps_v")
FAST = ["--param", "n_theta=36"]


def read_table(path: Path) -> dict[str, np.ndarray]:
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    return {k: np.array([r[k] for r in rows], dtype=object if k == "stage" else float)
            for k in rows[0]}


def check_identities(t):
    np.testing.assert_allclose(t["p"], 0.5 * (t["sig11"] + t["sig22"]), rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(t["q"], t["sig11"] - t["sig22"], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(t["eps_v"], t["eps11"] + t["eps22"], rtol=1e-12, atol=1e-15)


def test_biaxial_writes_table_and_figure(tmp_path, cli):
    out = tmp_path / "fig"
    code, stdout, err = cli("run", "biaxial", "--p0", "200kPa", "--axial-strain", "0.02",
                            *FAST, "--out", out)
    assert code == 0, err
    assert "result.csv" in stdout
    t = read_table(out / "result.csv")
    assert tuple(t) == COLUMNS and set(CONTRACT) <= set(t)
    check_identities(t)
    shear = t["stage"] == "shear"
    np.testing.assert_allclose(t["sig22"][shear], 2e5, rtol=1e-8)
    assert t["eps11"][shear][-1] - t["eps11"][~shear][-1] == pytest.approx(0.02)
    assert (out / "result.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in out.iterdir()) == ["result.csv", "result.png"]
    assert [p.name for p in tmp_path.iterdir()] == ["fig"]  # no temporary folder left


def test_several_confining_pressures_in_one_run(tmp_path, cli):
    code, _, err = cli("run", "biaxial", "--p0", "100kPa,0.2MPa,400000", "--axial-strain",
                       "0.01", "--undrained", *FAST, "--out", tmp_path)
    assert code == 0, err
    t = read_table(tmp_path / "result.csv")
    assert sorted(set(t["point"].astype(int))) == [0, 1, 2]
    for b, p0 in enumerate((1e5, 2e5, 4e5)):
        cons = (t["point"] == b) & (t["stage"] == "consolidation")
        assert t["p"][cons][-1] == pytest.approx(p0, rel=1e-9)
        shear = (t["point"] == b) & (t["stage"] == "shear")
        np.testing.assert_allclose(t["eps_v"][shear], t["eps_v"][cons][-1], atol=1e-13)  # isochoric


def test_iso_reaches_p0(tmp_path, cli):
    code, _, err = cli("run", "iso", "--p0", "150kPa", *FAST, "--out", tmp_path)
    assert code == 0, err
    t = read_table(tmp_path / "result.csv")
    check_identities(t)
    assert t["p"][-1] == pytest.approx(1.5e5, rel=1e-9)
    np.testing.assert_allclose(t["sig12"], 0.0, atol=1e-6 * 1.5e5)


def test_strain_path_one_row_per_input_row_in_order(tmp_path, cli):
    path = tmp_path / "path.csv"
    eps = [[1e-4, 1e-4, 0.0], [4e-4, 2e-4, 1e-4], [4e-4, 2e-4, -1e-4], [2e-4, 1e-4, 0.0]]
    path.write_text("eps11,eps22,eps12\n" + "\n".join(",".join(map(str, r)) for r in eps) + "\n")
    code, _, err = cli("run", "strain-path", path, *FAST, "--param", "alpha0=50",
                       "--out", tmp_path / "o")
    assert code == 0, err
    t = read_table(tmp_path / "o" / "result.csv")
    np.testing.assert_array_equal(np.column_stack([t["eps11"], t["eps22"], t["eps12"]]), eps)
    check_identities(t)


def test_strain_path_without_shear_column(tmp_path, cli):
    path = tmp_path / "path.csv"
    path.write_text("eps11,eps22\n0.0002,0.0001\n0.0004,0.0001\n")
    code, _, err = cli("run", "strain-path", path, *FAST, "--out", tmp_path / "o")
    assert code == 0, err
    assert len(read_table(tmp_path / "o" / "result.csv")["eps12"]) == 2


BAD_PARAMS = [
    (["--param", "foo=1"], "foo"),
    (["--param", "kn=-2e8"], "kn"),
    (["--param", "phi_g=0"], "phi_g"),
    (["--param", "phi_g=90"], "phi_g"),
    (["--param", "alpha0=30"], "alpha0"),
    (["--param", "alpha0=95"], "alpha0"),
    (["--param", "kn=inf"], "kn"),
    (["--param", "kn"], "NAME=VALUE"),
    (["--p0", "abc"], "pressure"),
    (["--p0", "-100kPa"], "pressure"),
    (["--p0", "0"], "pressure"),
    (["--p0", "100kPa,,200kPa"], "pressure"),
    (["--axial-strain", "-0.1"], "axial-strain"),
    (["--axial-strain", "nan"], "axial-strain"),
    (["--axial-strain", "abc"], "axial-strain"),
    (["--step", "0"], "step"),
    (["--bogus"], "bogus"),
    (["--solver", "magic"], "solver"),
]


@pytest.mark.parametrize("extra, word", BAD_PARAMS)
def test_bad_biaxial_input_is_one_line_and_writes_nothing(tmp_path, cli, extra, word):
    out = tmp_path / "o"
    code, stdout, err = cli("run", "biaxial", "--axial-strain", "0.01", *FAST, *extra,
                            "--out", out)
    assert code != 0
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hmodel: error:"), err
    assert word in lines[0]
    assert "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


#: Malformed command lines (README: exit status 2), each with a word the message must name.
MALFORMED = [
    (["run", "biaxial", "--bogus"], "--bogus"),  # unknown option
    (["run", "spiral"], "spiral"),  # unknown command
    (["run", "strain-path"], "path"),  # missing argument
    (["run", "biaxial", "--axial-strain"], "--axial-strain"),  # option without its value
    (["run", "biaxial", "--axial-strain", "abc"], "--axial-strain"),  # not a number
    (["run", "biaxial", "--step", "1e-4x"], "--step"),
    (["data", "generate", "2", "--workers", "two"], "--workers"),  # not an integer
    (["run", "iso", "--p0", "100kPa", "extra"], "extra"),  # an argument too many
    (["run", "biaxial", "--undrained=yes"], "--undrained"),  # a flag given a value
]


@pytest.mark.parametrize("args, word", MALFORMED)
def test_malformed_command_line_exits_2_with_one_line(tmp_path, cli, monkeypatch, args, word):
    monkeypatch.chdir(tmp_path)  # where the default output folders would go
    code, stdout, err = cli(*args)
    assert code == 2, (code, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hmodel: error:") and word in lines[0], err
    assert stdout == ""
    assert list(tmp_path.iterdir()) == []

BAD_CSV = {
    "bad-header": ("e11,e22\n0.001,0.001\n", "header"),
    "non-finite": ("eps11,eps22\n0.001,nan\n", "non-finite"),
    "infinite": ("eps11,eps22,eps12\n0.001,0.001,inf\n", "non-finite"),
    "text": ("eps11,eps22\n0.001,abc\n", "not a number"),
    "short-row": ("eps11,eps22,eps12\n0.001,0.001\n", "expected 3 values"),
    "empty": ("", "empty"),
    "header-only": ("eps11,eps22\n", "no rows"),
}


@pytest.mark.parametrize("name", sorted(BAD_CSV))
def test_malformed_strain_path_is_one_line_and_writes_nothing(tmp_path, cli, name):
    text, word = BAD_CSV[name]
    src = tmp_path / "in"
    src.mkdir()
    (src / "path.csv").write_text(text)
    out = tmp_path / "o"
    code, _, err = cli("run", "strain-path", src / "path.csv", *FAST, "--out", out)
    assert code != 0
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hmodel: error:") and word in lines[0], err
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in"]


def test_missing_and_binary_strain_path_files(tmp_path, cli):
    code, _, err = cli("run", "strain-path", tmp_path / "nope.csv", "--out", tmp_path / "o")
    assert code != 0 and "nope.csv" in err and len(err.strip().splitlines()) == 1
    (tmp_path / "bin.csv").write_bytes(b"\xff\xfe\x00\x81" * 10)
    code, _, err = cli("run", "strain-path", tmp_path / "bin.csv", "--out", tmp_path / "o")
    assert code != 0 and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()


def test_existing_results_survive_a_failed_run(tmp_path, cli):
    out = tmp_path / "o"
    assert cli("run", "iso", "--p0", "100kPa", *FAST, "--out", out)[0] == 0
    before = (out / "result.csv").read_bytes()
    code, _, _ = cli("run", "iso", "--p0", "-1", *FAST, "--out", out)
    assert code != 0
    assert (out / "result.csv").read_bytes() == before


def test_output_path_that_is_a_file_is_refused(tmp_path, cli):
    (tmp_path / "o").write_text("mine")
    code, _, err = cli("run", "iso", "--p0", "100kPa", *FAST, "--out", tmp_path / "o")
    assert code != 0 and "not a folder" in err
    assert (tmp_path / "o").read_text() == "mine"


@pytest.mark.slow
def test_console_script_as_installed(tmp_path):
    exe = shutil.which("hmodel") or str(Path(sys.executable).with_name("hmodel"))
    if not Path(exe).exists():
        pytest.skip("hmodel console script not installed")
    ok = subprocess.run([exe, "run", "iso", "--p0", "0.1MPa", *FAST, "--out", str(tmp_path / "o")],
                        capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    bad = subprocess.run([exe, "run", "iso", "--param", "phi_g=120", "--out", str(tmp_path / "x")],
                         capture_output=True, text=True)
    assert bad.returncode == 1
    assert bad.stderr.count("\n") == 1 and "phi_g" in bad.stderr
    assert not (tmp_path / "x").exists()
    malformed = subprocess.run([exe, "run", "iso", "--p0", "0.1MPa", "--bogus", "--out", str(tmp_path / "y")],
                               capture_output=True, text=True)
    assert malformed.returncode == 2
    assert malformed.stderr.count("\n") == 1 and malformed.stderr.startswith("hmodel: error:")
    assert "--bogus" in malformed.stderr and "Traceback" not in malformed.stderr
    assert not (tmp_path / "y").exists()


def test_version_and_help(cli):
    code, out, _ = cli("--version")
    assert code == 0 and out.startswith("hmodel ")
    code, out, _ = cli("run", "biaxial", "--help")
    assert code == 0 and all(o in out for o in ("--undrained", "--p0", "--axial-strain", "--param"))
