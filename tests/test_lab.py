"""Laboratory files in: the Sand Triaxial Test Database's sectioned CSV (the shipped Karlsruhe
fine sand), plain CSVs whose headers carry units, and hmodel's own result.csv as a test file.
Expected values are read off the file's own rows by hand (its units: %, kPa)."""

from pathlib import Path

import numpy as np
import pytest

from hmodel.calibrate import Kind, Test, parse_data_spec
from hmodel.calibrate.data import read_lab_tests
from hmodel.calibrate.lab import read_database
from hmodel.cli.app import main
from hmodel.errors import InputError
from hmodel.examples import example_path
from hmodel.units import unit_factor

KFS = example_path("example:kfs")


def test_the_shipped_sand_is_read_with_its_programme_and_attribution():
    db = read_database(KFS)
    assert db.material == "Karlsruhe fine sand" and len(db.programme) == 25
    assert db.void_ratio_range == (0.677, 1.054)
    assert "CC-BY-4.0" in db.attribution and "Wichtmann" in db.attribution
    t = db.test("TMD12")  # sigma_r0 100.6 kPa, sigma_v0 102 kPa, e0 0.8168
    assert t.kind is Kind.TRIAXIAL_DRAINED and t.e0 == 0.8168
    assert t.p0 == pytest.approx((102 + 2 * 100.6) / 3 * 1e3, rel=1e-12)
    assert len(t.eps_a) == 201 and t.eps_a[-1] == pytest.approx(0.20)
    # TMD1's second row: 0.1 %, 0.0586 %, sigma_r 50.6 kPa, sigma_v 66.56 kPa
    t1 = db.test("TMD1")
    assert t1.eps_a[1] == pytest.approx(1e-3) and t1.eps_v[1] == pytest.approx(5.86e-4)
    assert t1.q[1] == pytest.approx((66.56 - 50.6) * 1e3)


def test_a_database_test_on_the_command_line_and_in_python_agree():
    t = parse_data_spec("example:kfs#TMD12")
    assert isinstance(t, Test) and t.e0 == 0.8168 and t.kind is Kind.TRIAXIAL_DRAINED
    tests, attribution = read_lab_tests("example:kfs", ["TMD12"])
    assert np.array_equal(tests[0].q, t.q) and attribution


def test_unit_headers_convert_once_at_the_door(tmp_path):
    rows = [(0.0, 0.0, 0.0), (0.5, 40.0, 0.1), (1.0, 60.0, 0.15)]
    (tmp_path / "si.csv").write_text("eps_a,q,eps_v\n" + "".join(f"{a / 100},{q * 1e3},{v / 100}\n" for a, q, v in rows))
    (tmp_path / "lab.csv").write_text("eps_a[%],q[kPa],eps_v[%]\n" + "".join(f"{a},{q},{v}\n" for a, q, v in rows))
    (tmp_path / "sig.csv").write_text("eps_a[%],sigma_r[kPa],sigma_v[MPa],eps_v[%]\n"
                                      + "".join(f"{a},100,{(100 + q) / 1e3},{v}\n" for a, q, v in rows))
    si, lab, sig = (parse_data_spec(f"triaxial-drained:100kPa:{tmp_path / f}") for f in ("si.csv", "lab.csv", "sig.csv"))
    for t in (lab, sig):
        assert np.allclose(t.eps11, si.eps11, rtol=1e-12) and np.allclose(t.q, si.q, rtol=1e-12)
        assert np.allclose(t.eps_v, si.eps_v, rtol=1e-12)
    assert unit_factor("sigma_r[MPa]") == ("sigma_r", 1e6)


def test_e0_given_with_a_plain_file(tmp_path):
    (tmp_path / "t.csv").write_text("eps_a,q\n0,0\n0.01,1e5\n")
    assert parse_data_spec(f"triaxial-drained:100kPa:{tmp_path / 't.csv'}:e0=0.81").e0 == 0.81
    assert parse_data_spec(f"triaxial-drained:100kPa:{tmp_path / 't.csv'}").e0 is None


def test_hmodels_own_result_csv_is_a_test_file(tmp_path):
    """The text column ``stage`` is read, the rows after consolidation kept and their strains
    measured from its end."""
    out = tmp_path / "run"
    assert main(["run", "biaxial", "--p0", "100kPa", "--axial-strain", "0.002", "-p", "n_theta=12",
                 "--out", str(out)]) == 0
    t = parse_data_spec(f"drained:100kPa:{out / 'result.csv'}")
    assert t.eps11[0] == 0 and t.eps11[-1] == pytest.approx(0.002) and t.q[0] == pytest.approx(0, abs=1e-6)
    assert len(t.eps11) == 21  # the end of consolidation and 20 increments of 1e-4


@pytest.mark.parametrize("edit, phrase", [
    (lambda s: s.replace("format_version,1.1", "format_version,2.0"), "format version 2.0"),
    (lambda s: s.replace("eps_a[%]", "eps_a"), "carries no unit"),
    (lambda s: s.replace("eps_a[%]", "eps_a[in]"), "unit must be % or -"),
    (lambda s: s.replace("1,1,100.6,102,0.8168", "1,1,100.6,102,1.2"), "outside the sand's e_min"),
    (lambda s: s.replace("# ===== [6] TEST_DATA =====", "# ===== [6] OTHER ====="), "no section TEST_DATA"),
])
def test_bad_database_files_are_one_line(tmp_path, edit, phrase):
    (tmp_path / "db.csv").write_text(edit(KFS.read_text()))
    with pytest.raises(InputError, match=phrase):
        parse_data_spec(f"{tmp_path / 'db.csv'}#TMD12")


def test_unknown_test_and_a_2d_kind_on_a_triaxial_file(tmp_path):
    with pytest.raises(InputError, match="no test 'TMD99'"):
        parse_data_spec("example:kfs#TMD99")
    with pytest.raises(InputError, match="no example 'sand'"):
        parse_data_spec("example:sand#TMD1")
    (tmp_path / "t.csv").write_text("eps_a[%],q[kPa]\n0,0\n1,100\n")
    with pytest.raises(InputError, match="2D model's biaxial test"):
        parse_data_spec(f"drained:100kPa:{tmp_path / 't.csv'}")
    with pytest.raises(InputError, match="e0 must be a number"):
        parse_data_spec(f"triaxial-drained:100kPa:{tmp_path / 't.csv'}:e0=dense")


def test_data_lab_writes_test_files_that_read_back(tmp_path, capsys):
    out = tmp_path / "kfs"
    assert main(["data", "lab", "example:kfs", "--test", "TMD1", "--test", "TMD25", "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["ATTRIBUTION.txt", "TMD1.csv", "TMD25.csv", "tests.csv"]
    back = parse_data_spec(f"triaxial-drained:100kPa:{out / 'TMD25.csv'}")
    assert np.allclose(back.q, parse_data_spec("example:kfs#TMD25").q, rtol=1e-11)
    assert "CC-BY-4.0" in (out / "ATTRIBUTION.txt").read_text()
    code = main(["data", "lab", "example:kfs", "--test", "TMD0", "--out", str(tmp_path / "no")])
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1 and "no test 'TMD0'" in err and not (tmp_path / "no").exists()
