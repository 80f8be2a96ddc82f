"""hmodel fem --scheduler: the material updates on a Dask cluster give the local results."""

from __future__ import annotations

import numpy as np
import pytest

from hmodel import Params
from hmodel.fem import biaxial

FAST = Params(n_theta=36)


@pytest.mark.slow
def test_dask_scheduler_gives_the_local_results():
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        remote = biaxial(FAST, 2e5, 0.003, mesh=(1, 2), n_steps=3, reference=False,
                         imperfection="alpha0=50@0,0,0.02", scheduler=cluster.scheduler_address)
    local = biaxial(FAST, 2e5, 0.003, mesh=(1, 2), n_steps=3, reference=False,
                    imperfection="alpha0=50@0,0,0.02")
    for c in local.columns:
        np.testing.assert_array_equal(remote.column(c), local.column(c))
    np.testing.assert_array_equal(remote.snapshots[-1].sig, local.snapshots[-1].sig)


@pytest.mark.slow
def test_unreachable_scheduler_is_an_input_error():
    pytest.importorskip("distributed")
    from hmodel.errors import InputError
    with pytest.raises(InputError, match="cannot reach the Dask scheduler"):
        biaxial(FAST, 2e5, 0.003, mesh=(1, 1), n_steps=1, reference=False, scheduler="tcp://127.0.0.1:9")
