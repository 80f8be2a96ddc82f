"""Markers shared by the test modules.

- ``@pytest.mark.yade``: the test drives the YADE executable; skipped, with the reason, where
  YADE is not installed (``.ci/run`` installs it, so CI runs every one).
- ``@pytest.mark.slow``: one of the slowest tests (4 s or more on the project's 2-core machine).
  CI still runs it; ``python -m pytest -m "not slow"`` leaves it out while editing.
"""

import pytest

from hmodel.dem.yade import available


def pytest_collection_modifyitems(config, items):
    if available():
        return
    skip = pytest.mark.skip(reason="YADE is not installed (apt-get install -y yade)")
    for item in items:
        if "yade" in item.keywords:
            item.add_marker(skip)
