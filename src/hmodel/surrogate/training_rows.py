"""Rows for training and evaluation: a sample folder (``hmodel data sample``) or a dataset."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from ..data import Dataset
from ..data.filters import DEFAULT_RULES
from ..data.sampling import sample_split
from ..data.schema import column_array
from ..data.store import sha256
from ..errors import InputError
from ..params import Params


def read_sample(folder: "str | Path", part: str) -> tuple[dict[str, np.ndarray], dict]:
    """Columns of ``train`` or ``test`` of a sample folder, and its provenance (checked)."""
    folder = Path(folder)
    mpath = folder / "manifest.json"
    if not mpath.is_file():
        raise InputError(f"{str(folder)!r} is not a sample folder (no manifest.json); "
                         f"make one with hmodel data sample")
    try:
        meta = json.loads(mpath.read_text())
    except json.JSONDecodeError:
        raise InputError(f"{str(mpath)!r} is not valid JSON") from None
    if meta.get("format") != "hmodel-cell-sample":
        raise InputError(f"{str(folder)!r} is not a sample folder (manifest format {meta.get('format')!r})")
    entry = meta["files"].get(part)
    path = folder / f"{part}.parquet"
    if entry is None or not path.is_file():
        raise InputError(f"{str(folder)!r} has no {part} rows")
    if sha256(path) != entry["sha256"]:
        raise InputError(f"{str(path)!r} does not match the checksum in its manifest")
    t = pq.read_table(path)
    cols = {c: column_array(t, c) for c in t.column_names}
    prov = {"sample": str(folder), "part": part, "file_sha256": entry["sha256"],
            "source_checksum": meta["source_checksum"], "kind": meta["kind"],
            "method": meta["method"], "seed": meta["seed"], "rules": meta["rules"],
            "options": meta["options"], "extra_fields": meta.get("extra_fields", [])}
    return cols, {"provenance": prov, "params": meta["params"]}


def read_rows(path: "str | Path", part: str = "test", n: int | None = None,
              seed: int = 0) -> tuple[dict[str, np.ndarray], dict]:
    """Rows from a sample folder (its ``part``) or from a dataset folder (``n`` random rows
    kept by the default cleaning rules, or all of them)."""
    if n is not None and not (isinstance(n, (int, np.integer)) and n >= 1):
        raise InputError(f"the number of rows must be a positive integer, got {n!r}")
    path = Path(path)
    if (path / "manifest.json").is_file():
        try:
            m = json.loads((path / "manifest.json").read_text())
        except json.JSONDecodeError:
            m = {}
        if m.get("format") == "hmodel-cell-dataset":
            ds = Dataset.open(path)
            if n is None or n >= ds.n_rows:
                from ..data.filters import kept_rows
                rows = kept_rows(ds, DEFAULT_RULES)
            else:
                rows, _ = sample_split(ds, n, 0, "random", seed)
            prov = {"dataset": str(path), "source_checksum": ds.checksum, "kind": ds.manifest["kind"],
                    "rows": int(len(rows)), "seed": seed, "rules": list(DEFAULT_RULES)}
            return ds.read(rows=rows), {"provenance": prov, "params": ds.manifest["params"]}
    cols, info = read_sample(path, part)
    if n is not None and n < len(cols["deps1"]):
        keep = np.sort(np.random.default_rng(seed).choice(len(cols["deps1"]), n, replace=False))
        cols = {k: v[keep] for k, v in cols.items()}
    return cols, info


def params_of(info: dict) -> Params:
    return Params.from_dict(info["params"])
