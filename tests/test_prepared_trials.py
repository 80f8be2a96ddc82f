"""The compiled Newton's trials read the part of a trial that the committed cells fix, prepared
once per increment (:func:`hmodel.rev.trial.point_prepared`, docs/notes/
2026-12-07-per-state-preparation.md): every trial made from one preparation is the unprepared
trial's (:func:`hmodel.rev.trial.point_trial`) to the last bit, in 2D and 3D, with linear
contacts (which prepare) and with the mechanisms (which prepare nothing). The engine
benchmarks time both kinds of trial (docs/notes/2026-12-08-prepared-trials-and-the-hand-back.md)."""

import math

import numpy as np
import pytest

from hmodel import Params
from hmodel.cell import CellFlags
from hmodel.loading import consolidate
from hmodel.loading.compiled3d import kernel_inputs3d
from hmodel.rev import Rev, Rev3D, Sphere
from hmodel.rev.trial import point_prepared, point_trial, point_trial_prepared

BASE = Params(sliding_rhs="equilibrium", alpha0=math.radians(50))
CASES = {"linear": BASE, "hertz-mindlin": BASE.with_(contact="hertz-mindlin"),
         "sand": BASE.with_(contact="hertz-mindlin", renewal="mix", lateral="axisymmetric")}


def _point(params, dim):
    """A REV consolidated to 200 kPa and sheared by 1 %, its trial inputs."""
    rev = Rev(params.with_(n_theta=72)) if dim == 2 else Rev3D(params, Sphere(order=9, n_azimuth=2))
    state = consolidate(rev, [2e5])
    n = state.eps.shape[1]
    shear = np.zeros((1, n))
    shear[0, :2] = [1e-3, -1e-3] if dim == 2 else [1e-3, -5e-4]
    if dim == 3:
        shear[0, 2] = -5e-4
    for _ in range(10):
        state = rev.step(state, shear)
    geo, p = rev.kernel_inputs() if dim == 2 else kernel_inputs3d(rev)
    values = np.ascontiguousarray(state.cells.values[0])
    return rev, state, values, geo[0], p[0], n


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("name", list(CASES))
def test_trials_from_one_preparation_are_the_unprepared_trials(name, dim):
    rev, state, values, geo, p, n = _point(CASES[name], dim)
    C, F = values.shape
    n_flags = 5 if dim == 2 else 11
    resp = np.empty((C, 0))
    pre = point_prepared(values, geo, p, resp)
    rng = np.random.default_rng(3)
    outs = []
    events = np.zeros(3, bool)  # sliding, open1, open2 in some trial
    for _ in range(5):
        x = rng.normal(0.0, 1e-3, n)
        res = []
        for prepared in (False, True):
            out, flags, sig = np.empty_like(values), np.empty((C, n_flags), bool), np.empty(n)
            args = (values, state.eps[0].copy(), x, geo, p, rev.mode, rev.volume0, out, flags, sig, resp)
            ok = point_trial_prepared(*args, pre) if prepared else point_trial(*args)
            res.append((ok, out, flags, sig))
        (ok0, out0, fl0, sig0), (ok1, out1, fl1, sig1) = res
        assert ok0 == ok1
        np.testing.assert_array_equal(out1, out0)
        np.testing.assert_array_equal(fl1, fl0)
        np.testing.assert_array_equal(sig1, sig0)
        outs.append(sig0)
        events |= CellFlags(fl0).hexagons[..., :3].any(axis=(0, 1))
    # the five trials differ (the comparison is not of one trial with itself), and between them
    # hexagons slide and open (the trials' regimes are exercised, not only sticking)
    assert len({tuple(s) for s in outs}) == 5
    assert events[0] and (events[1] or events[2])
