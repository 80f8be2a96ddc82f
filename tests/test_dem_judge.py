"""The DEM judge's sample folders (benchmarks/calibration/calibrate3d_dem.py): the tests of one
model's dimension, each with the void ratio its CSV starts at."""

from benchmarks.calibration.calibrate3d_dem import read_tests
from hmodel.calibrate import Kind

ROWS = "eps11,q,eps_v,p,e\n0.0,0.0,0.0,1e5,{e0}\n0.01,5e4,0.001,1.2e5,0.24\n0.02,8e4,0.0,1.3e5,0.25\n"


def test_a_disk_folder_gives_the_2d_models_tests_and_a_sphere_folder_the_3d_ones(tmp_path):
    for stem, e0 in (("drained_100kPa", 0.25), ("undrained_200kPa", 0.26), ("triaxial-drained_100kPa", 0.61),
                     ("sample", 0.0)):
        (tmp_path / f"{stem}.csv").write_text(ROWS.format(e0=e0))
    two = read_tests(tmp_path, "disks/", dim=2)
    three = read_tests(tmp_path, dim=3)
    assert sorted(two) == ["disks/drained_100kPa", "disks/undrained_200kPa"]
    assert two["disks/drained_100kPa"].kind is Kind.DRAINED and two["disks/drained_100kPa"].p0 == 1e5
    assert two["disks/undrained_200kPa"].e0 == 0.26 and two["disks/drained_100kPa"].e0 == 0.25
    assert list(three) == ["triaxial-drained_100kPa"] and three["triaxial-drained_100kPa"].e0 == 0.61
    assert sorted(read_tests(tmp_path, dim=None)) == ["drained_100kPa", "triaxial-drained_100kPa", "undrained_200kPa"]
