"""The surrogate shipped inside the package, so that the ANN-based H-model works after install.

It is produced by the command in ``models/README.md`` (a fixed dataset, sample and seed) and
loaded like any other model file (checked, never unpickled).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from ..errors import InputError

SHIPPED = "h-cell-default.safetensors"


def shipped_path() -> Path:
    path = Path(str(resources.files("hmodel.surrogate") / "models" / SHIPPED))
    if not path.is_file():
        raise InputError(f"the shipped surrogate {SHIPPED} is missing from this installation")
    return path


def load_shipped():
    from .modelfile import load
    return load(shipped_path())
