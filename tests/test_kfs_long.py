"""The measures of benchmarks/calibration/kfs_long.py on paths with known answers."""

import numpy as np
from types import SimpleNamespace

from benchmarks.calibration.kfs_long import long_ends, summary


def test_end_rate_and_void_ratio_of_a_path_with_a_known_slope():
    e11 = np.linspace(0.0, 0.5, 501)
    ev = np.where(e11 < 0.1, 0.1 * e11, 0.01 - 0.4 * (e11 - 0.1))  # contracts, then dilates at 0.4
    res = {"point": np.zeros(501, int), "eps11": e11, "eps_v": ev, "q_p": np.full(501, 1.2)}
    test = SimpleNamespace(name="T", e0=0.8, p0=100e3, q=np.array([0.0, 150e3]), eps_v=np.array([0.0, -0.05]))
    (row,) = long_ends([test], res, {}, window=0.03)
    assert np.isclose(row["deps_v_deps11_end"], -0.4)
    assert np.isclose(row["e_end"], 0.8 - (0.01 - 0.4 * 0.4) * 1.8)
    assert np.isclose(row["e_20"], 0.8 - (0.01 - 0.4 * 0.1) * 1.8)
    assert np.isclose(row["sand_e_end"], 0.8 + 0.05 * 1.8) and np.isclose(row["sand_q_p_end"], 150 / 150)
    assert row["reached"] == 0.5 and row["failed"] == ""


def test_summary_counts_tests_ending_early_apart():
    rows = [{"rms_dq": 0.05, "rms_dev": 0.01, "reached": 0.2}, {"rms_dq": 0.08, "rms_dev": 0.02, "reached": 0.1},
            {"rms_dq": 0.30, "rms_dev": 0.03, "reached": 0.2}, {"rms_dq": None, "rms_dev": None, "reached": 0.0}]
    s = summary(rows)
    assert s["within_10"] == 1 and s["ended_early"] == 2
    assert np.isclose(s["median_rms_dq"], 0.08) and np.isclose(s["median_rms_dev"], 0.02)
