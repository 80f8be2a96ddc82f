"""The measures of benchmarks/calibration/kfs_rows.py on curves with known answers."""

import math

import numpy as np

from benchmarks.calibration.kfs_rows import best, row_scores
from hmodel.calibrate import Test


def _test(name, q_peak, ev_end):
    e11 = np.linspace(0.0, 0.2, 21)
    return Test("drained", 100e3, e11, q_peak * np.minimum(e11 / 0.05, 1.0), ev_end * e11 / 0.2, name=name, e0=0.8)


def test_row_scores_of_curves_off_by_known_amounts():
    a, b = _test("A", 300e3, -0.04), _test("B", 500e3, 0.01)
    # A's model 10 % of peak q too high everywhere, its volume right; B's q right, its volume 0.5 % off
    # everywhere; B's model ends half way (NaN beyond)
    qa, eva = a.q + 0.1 * a.q_scale, a.eps_v.copy()
    qb, evb = b.q.copy(), b.eps_v + 0.005
    qb[11:] = np.nan
    s = row_scores([a, b], [(qa, eva), (qb, evb)])
    assert math.isclose(s["mean_rms_dq"], 0.05) and math.isclose(s["max_rms_dq"], 0.1)
    assert math.isclose(s["mean_rms_dev"], 0.0025)
    assert math.isclose(s["reached_min"], 0.1) and s["none"] == 0


def test_a_test_the_model_never_reached_counts_as_failed():
    a = _test("A", 300e3, -0.04)
    nan = np.full(len(a.eps11), np.nan)
    s = row_scores([a, a], [(a.q.copy(), a.eps_v.copy()), (nan, nan)])
    assert s["none"] == 1 and math.isinf(s["mean_rms_dq"]) and s["reached_min"] == 0.0
    assert best([{"k": 2.0}, {"k": 0.5}, {"k": math.inf}], "k") == {"k": 0.5}
