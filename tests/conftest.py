"""Markers and fixtures shared by the test modules.

- ``@pytest.mark.yade``: the test drives the YADE executable; skipped, with the reason, where
  YADE is not installed (``.ci/run`` installs it, so CI runs every one).
- ``@pytest.mark.slow``: one of the slowest tests (4 s or more on the project's 2-core machine).
  CI still runs it; ``python -m pytest -m "not slow"`` leaves it out while editing.
"""

import pytest

from hmodel import Params
from hmodel.data import DatasetSpec, generate
from hmodel.data.sampling import write_split
from hmodel.dem.yade import available
from hmodel.surrogate.modelfile import load, save
from hmodel.surrogate.training import TrainConfig, train_on_sample


def pytest_collection_modifyitems(config, items):
    if available():
        return
    skip = pytest.mark.skip(reason="YADE is not installed (apt-get install -y yade)")
    for item in items:
        if "yade" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(scope="session")
def tiny_model(tmp_path_factory):
    """A small meso network of the closed-form H-cell, trained once for the session on a
    Dataset 2 sample (also returned: the folder of its data and sample)."""
    tmp = tmp_path_factory.mktemp("meso")
    spec = DatasetSpec(kind=2, n_directions=8, theta_min=-60.0, theta_max=150.0, alpha0_min=45.0,
                       alpha0_max=45.0, max_strain=0.02, step=0.001, start_every=0.002,
                       magnitude=0.002, magnitude_min=0.0, n_increments=12, substeps=1)
    ds = generate(spec, Params(sliding_rhs="equilibrium"), tmp / "data")
    write_split(ds, tmp / "sample", 700, 150)
    cfg = TrainConfig(formulation="meso", width=32, depth=2, activation="silu", epochs=80,
                      patience=80, device="cpu")
    model, _ = train_on_sample(tmp / "sample", cfg)
    return load(save(model, tmp / "meso.safetensors")), tmp
