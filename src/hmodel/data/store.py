"""Datasets on disk: Parquet shards plus a JSON manifest, written resumably, read with checks.

Layout of a dataset folder::

    manifest.json          what was asked (kind, generator options, material parameters,
                           schema version, hmodel version) and what is done (one entry per
                           finished shard: file, rows, SHA-256)
    part-00000.parquet     shard 0 (paths 0..k-1), ...

A shard is written to a temporary name and renamed into place; the manifest is rewritten
atomically after each shard. A killed run therefore leaves finished shards, an older manifest
and at most temporary files, which the next run removes before computing only what is missing.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from .. import __version__
from ..cell.base import check_mechanisms
from ..errors import HModelError, InputError
from ..io import check_output_folder
from ..limits import check_disk
from ..params import Params
from ..solvers import get_solver
from .generator import DatasetSpec, compute_shard
from .schema import (
    EXTRA_COLUMNS,
    MATERIAL_COLUMNS,
    SCHEMA_VERSION,
    arrow_schema,
    column_array,
    columns_for,
)
from ..workers import run_tasks

#: Disk a dataset row takes, at most [bytes] (Parquet shards; measured about 61 B a row on a
#: small Dataset 2), for the disk check before a run.
BYTES_PER_ROW = 100
MANIFEST = "manifest.json"
FORMAT = "hmodel-cell-dataset"


class DatasetError(HModelError):
    """A dataset folder that is missing, incomplete, altered or of another version."""


def shard_name(i: int) -> str:
    return f"part-{i:05d}.parquet"


def sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 22), b""):
            h.update(block)
    return h.hexdigest()


def _write_json(path: Path, obj: dict) -> None:
    tmp = path.with_name(path.name + ".part")
    tmp.write_text(json.dumps(obj, indent=1) + "\n")
    os.replace(tmp, path)


def _header(spec: DatasetSpec, params: Params) -> dict:
    """The part of a manifest that identifies what the dataset is."""
    rows = spec.dataset_kind
    header = {"format": FORMAT, "schema_version": SCHEMA_VERSION, "kind": spec.kind,
              "options": spec.to_dict(), "params": params.to_dict(), "seed": None,
              "columns": list(rows.columns) + list(MATERIAL_COLUMNS if spec.draws_material else ()),
              "units": rows.units}
    from ..solvers import get_solver

    extra = list(get_solver(spec.solver).field_names()[8:])  # a richer cell's extra state fields
    if extra:
        header["columns"] += list(EXTRA_COLUMNS)
        header["extra_fields"] = extra
    return header


def _parquet_metadata(header: dict) -> dict[bytes, bytes]:
    return {b"hmodel": json.dumps({k: header[k] for k in
                                   ("format", "schema_version", "kind", "options", "params",
                                    "units")}).encode()}


def encode_shard(spec: DatasetSpec, params: Params, i: int) -> bytes:
    """Shard ``i`` computed and encoded as Parquet bytes (runs in a worker)."""
    table = compute_shard(spec, params, i)
    table = table.replace_schema_metadata(_parquet_metadata(_header(spec, params)))
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink, compression="zstd", row_group_size=1 << 16)
    return sink.getvalue().to_pybytes()


def _write_shard(folder: Path, i: int, data: bytes) -> dict:
    final = folder / shard_name(i)
    tmp = folder / (shard_name(i) + ".part")
    tmp.write_bytes(data)
    os.replace(tmp, final)
    rows = pq.ParquetFile(final).metadata.num_rows
    return {"file": final.name, "rows": rows, "sha256": hashlib.sha256(data).hexdigest()}


def generate(spec: DatasetSpec, params: Params, out: "str | os.PathLike", *, workers: int = 1,
             scheduler: str | None = None, progress: Callable[[float], None] | None = None,
             overwrite: bool = False) -> "Dataset":
    """Compute the dataset into ``out``; resume a run that stopped; return the opened dataset.

    ``workers`` local processes (1: in this process), or the Dask cluster at ``scheduler``.
    An existing folder made with other options or parameters is refused unless ``overwrite``.
    """
    # the rows are the cells' own: a DEM cell cannot make Hertz-Mindlin or reborn cells' rows
    check_mechanisms(get_solver(spec.solver), [params])
    folder = Path(out)
    check_disk(spec.n_rows * BYTES_PER_ROW, folder, f"a dataset of {spec.n_rows:.3g} rows")
    header = _header(spec, params)
    manifest = _prepare(folder, header, overwrite)
    done = {int(e["file"][5:10]): e for e in manifest["shards"]}
    # Keep only finished shards whose file is intact; everything else is recomputed.
    done = {i: e for i, e in done.items()
            if (folder / e["file"]).is_file() and sha256(folder / e["file"]) == e["sha256"]}
    todo = [i for i in range(spec.n_shards) if i not in done]
    manifest["shards"] = sorted(done.values(), key=lambda e: e["file"])
    manifest["complete"] = not todo
    _write_json(folder / MANIFEST, manifest)
    if progress is not None:
        progress(len(done) / spec.n_shards)
    for i, data in run_tasks(encode_shard, [(spec, params, i) for i in todo], todo,
                             workers=workers, scheduler=scheduler):
        done[i] = _write_shard(folder, i, data)
        manifest["shards"] = [done[k] for k in sorted(done)]
        manifest["complete"] = len(done) == spec.n_shards
        manifest["rows"] = sum(e["rows"] for e in done.values())
        _write_json(folder / MANIFEST, manifest)
        if progress is not None:
            progress(len(done) / spec.n_shards)
    manifest["rows"] = sum(e["rows"] for e in done.values())
    _write_json(folder / MANIFEST, manifest)
    return Dataset.open(folder, verify=False)


def _prepare(folder: Path, header: dict, overwrite: bool) -> dict:
    """Create the folder or check that it holds the same dataset; drop temporary files."""
    check_output_folder(folder)
    path = folder / MANIFEST
    if path.is_file() and not overwrite:
        old = _read_manifest(path)
        if isinstance(old.get("options"), dict):  # options added since it was written take their defaults
            old = {**old, "options": DatasetSpec.from_dict(old["options"]).to_dict()}
        if isinstance(old.get("params"), dict):
            # parameters added to Params since it was written: their defaults are the physics its
            # rows were computed with (a new parameter defaults to the model it extends)
            old = {**old, "params": {**Params().to_dict(), **old["params"]}}
        for key in ("format", "schema_version", "kind", "options", "params"):
            if old.get(key) != header[key]:
                raise InputError(
                    f"{str(folder)!r} holds a dataset with other {key} "
                    f"({_diff(old.get(key), header[key])}); choose another --out or add --overwrite")
        manifest = {**old, "hmodel": __version__}
    else:
        if folder.exists() and any(p.name.endswith(".parquet") for p in folder.iterdir()) and not overwrite:
            raise InputError(f"{str(folder)!r} holds Parquet files but no manifest; "
                             f"choose another --out or add --overwrite")
        folder.mkdir(parents=True, exist_ok=True)
        if overwrite:
            for p in folder.glob("part-*.parquet"):
                p.unlink()
        manifest = {**header, "hmodel": __version__, "shards": [], "rows": 0, "complete": False}
    for p in folder.glob("*.part"):
        p.unlink()
    return manifest


def _diff(old, new) -> str:
    if isinstance(old, dict) and isinstance(new, dict):
        keys = [k for k in sorted(set(old) | set(new)) if old.get(k) != new.get(k)]
        return ", ".join(f"{k}: {old.get(k)!r} there, {new.get(k)!r} asked" for k in keys[:3])
    return f"{old!r} there, {new!r} asked"


def _read_manifest(path: Path) -> dict:
    try:
        m = json.loads(path.read_text())
    except OSError as e:
        raise DatasetError(f"cannot read {str(path)!r}: {e.strerror}") from None
    except (json.JSONDecodeError, UnicodeDecodeError):
        raise DatasetError(f"{str(path)!r} is not a valid manifest (not JSON)") from None
    if not isinstance(m, dict) or m.get("format") != FORMAT:
        raise DatasetError(f"{str(path)!r} is not an hmodel dataset manifest")
    return m


@dataclass(frozen=True)
class Dataset:
    """An opened, checked dataset folder. Rows are in shard order, then path order."""

    folder: Path
    manifest: dict

    @classmethod
    def open(cls, folder: "str | os.PathLike", verify: bool = True) -> "Dataset":
        """Open ``folder``; refuse an incomplete dataset, another schema version, or (with
        ``verify``) a shard whose size or checksum differs from the manifest."""
        folder = Path(folder)
        if not (folder / MANIFEST).is_file():
            raise DatasetError(f"{str(folder)!r} is not a dataset folder (no {MANIFEST})")
        m = _read_manifest(folder / MANIFEST)
        if m.get("schema_version") != SCHEMA_VERSION:
            raise DatasetError(f"{str(folder)!r} has schema version {m.get('schema_version')}, "
                               f"this hmodel reads version {SCHEMA_VERSION}; regenerate it")
        spec = DatasetSpec.from_dict(m["options"])
        if not m.get("complete") or len(m["shards"]) != spec.n_shards:
            raise DatasetError(f"{str(folder)!r} is incomplete ({len(m['shards'])} of "
                               f"{spec.n_shards} shards); re-run the same generate command to finish it")
        for e in m["shards"]:
            path = folder / e["file"]
            if not path.is_file():
                raise DatasetError(f"shard {e['file']} of {str(folder)!r} is missing")
            if verify and sha256(path) != e["sha256"]:
                raise DatasetError(f"shard {e['file']} of {str(folder)!r} does not match the "
                                   f"checksum in its manifest (altered or truncated); regenerate it")
        return cls(folder, m)

    @property
    def spec(self) -> DatasetSpec:
        return DatasetSpec.from_dict(self.manifest["options"])

    @property
    def params(self) -> Params:
        return Params.from_dict(self.manifest["params"])

    @property
    def n_rows(self) -> int:
        return sum(e["rows"] for e in self.manifest["shards"])

    @property
    def checksum(self) -> str:
        """SHA-256 over the shard checksums: identifies the dataset's rows."""
        h = hashlib.sha256()
        for e in self.manifest["shards"]:
            h.update(e["sha256"].encode())
        return h.hexdigest()

    def shards(self) -> list[Path]:
        return [self.folder / e["file"] for e in self.manifest["shards"]]

    def iter_tables(self, columns: list[str] | None = None) -> Iterator[pa.Table]:
        """Shard by shard (bounded memory)."""
        cols = _check_columns(columns, self.n_extra, self.dim, self.material)
        for path in self.shards():
            yield pq.read_table(path, columns=cols)

    @property
    def dim(self) -> int:
        """2: H-cell rows; 3: bi-hexagon rows (:data:`~hmodel.data.schema.COLUMNS_3D`)."""
        return self.spec.dim

    @property
    def material(self) -> bool:
        """Whether every path drew its own material (rows hold :data:`MATERIAL_COLUMNS`)."""
        return self.spec.draws_material

    @property
    def n_extra(self) -> int:
        """Number of extra state fields of a richer DEM cell (0 otherwise)."""
        return len(self.manifest.get("extra_fields", ()))

    def read(self, columns: list[str] | None = None, rows: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Columns as NumPy arrays, all rows or the sorted global row indices ``rows``; the
        extra state columns of a richer cell (read by default when present) as (rows, n_extra)."""
        cols = (_check_columns(columns, self.n_extra, self.dim, self.material)
                or list(columns_for(self.dim)) + list(EXTRA_COLUMNS if self.n_extra else ())
                + list(MATERIAL_COLUMNS if self.material else ()))
        parts: dict[str, list[np.ndarray]] = {c: [] for c in cols}
        offset = 0
        for e, path in zip(self.manifest["shards"], self.shards()):
            n = e["rows"]
            if rows is not None:
                lo, hi = np.searchsorted(rows, [offset, offset + n])
                local = rows[lo:hi] - offset
                offset += n
                if len(local) == 0:
                    continue
                t = pq.read_table(path, columns=cols).take(pa.array(local))
            else:
                offset += n
                t = pq.read_table(path, columns=cols)
            for c in cols:
                parts[c].append(column_array(t, c))
        return {c: (np.concatenate(v) if v else _empty(c, self.n_extra, self.dim)) for c, v in parts.items()}


def _empty(column: str, n_extra: int, dim: int = 2) -> np.ndarray:
    if column in EXTRA_COLUMNS:
        return np.empty((0, n_extra))
    return np.array([], dtype=arrow_schema(dim=dim, material=True).field(column).type.to_pandas_dtype())


def _check_columns(columns: list[str] | None, n_extra: int = 0, dim: int = 2,
                   material: bool = False) -> list[str] | None:
    if columns is None:
        return None
    known = (list(columns_for(dim)) + list(EXTRA_COLUMNS if n_extra else ())
             + list(MATERIAL_COLUMNS if material else ()))
    unknown = [c for c in columns if c not in known]
    if unknown:
        raise InputError(f"unknown dataset column(s) {', '.join(unknown)} (known: {', '.join(known)})")
    return list(columns)
