"""hmodel fem --scheduler: the material updates on a Dask cluster give the local results."""

from __future__ import annotations

import numpy as np
import pytest

from hmodel import Params
from hmodel.fem import biaxial
from hmodel.fem.material import HModelMaterial

FAST = Params(n_theta=36)


@pytest.mark.slow
def test_dask_scheduler_gives_the_local_results(monkeypatch):
    distributed = pytest.importorskip("distributed")
    run = dict(params=FAST, p0=2e5, axial_strain=0.003, mesh=(1, 2), n_steps=3, reference=False,
               imperfection="alpha0=50@0,0,0.02")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        remote = biaxial(**run, scheduler=cluster.scheduler_address)
    fused = biaxial(**run)  # the compiled trials and the closed form's exact tangent
    # the scheduler sends batched Rev.step calls (forward-difference tangents): the same calls
    # made here give the same results bit for bit
    monkeypatch.setattr(HModelMaterial, "trial", HModelMaterial.trial_calls)
    calls = biaxial(**run)
    for c in calls.columns:
        np.testing.assert_array_equal(remote.column(c), calls.column(c))
    np.testing.assert_array_equal(remote.snapshots[-1].sig, calls.snapshots[-1].sig)
    # and the local default's to Newton's tolerance (its tangent is exact, not a difference)
    for c in ("eps11", "sig11", "sig22", "q", "eps_v"):
        np.testing.assert_allclose(remote.column(c), fused.column(c), rtol=1e-9, atol=1e-12)
    sig = fused.snapshots[-1].sig
    np.testing.assert_allclose(remote.snapshots[-1].sig, sig, rtol=0, atol=1e-8 * np.abs(sig).max())


@pytest.mark.slow
def test_unreachable_scheduler_is_an_input_error():
    pytest.importorskip("distributed")
    from hmodel.errors import InputError
    with pytest.raises(InputError, match="cannot reach the Dask scheduler"):
        biaxial(FAST, 2e5, 0.003, mesh=(1, 1), n_steps=1, reference=False, scheduler="tcp://127.0.0.1:9")
