"""Training databases of H-cell increments (report §2.3): generation, storage, cleaning, sampling."""

from .generator import DatasetSpec, compute_shard
from .schema import COLUMNS, SCHEMA_VERSION
from .store import Dataset, DatasetError, generate

__all__ = ["COLUMNS", "SCHEMA_VERSION", "Dataset", "DatasetError", "DatasetSpec", "compute_shard",
           "generate"]
