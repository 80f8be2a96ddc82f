"""Train/test subsets of a requested size (report §2.3): random, grid and Latin-hypercube sampling.

Grid and LHS work in *rank space*: each chosen column is replaced by its empirical CDF over a
candidate pool, so that heavy-tailed forces and clustered angles are spread evenly.

- grid: [0, 1]^d is cut into k^d equal cells (k = ceil(n^(1/d))); one random row is taken from
  each occupied cell, the cells evenly spaced along their row-major order when there are more
  than n of them.
- lhs: a ``scipy.stats.qmc.LatinHypercube`` design of n points; each point takes a row of its
  own stratum in one column (the columns in turn); then rows are swapped in and out as long as
  no column's stratum occupancy gets worse (conditioned LHS, Minasny & McBratney 2006). Rows
  are far apart in d dimensions compared with a stratum, so no finite pool gives a perfect
  Latin hypercube; on 8 columns about 85 % of each column's n strata end up holding a row,
  against 1 - 1/e = 63 % for random sampling.

The candidate pool is a seeded random subset of the kept rows (``pool`` rows at most), which
bounds the cost on the full Dataset 2. Everything is reproducible from ``seed``.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pyarrow as pa
from numba import njit
import pyarrow.parquet as pq
from scipy.stats import qmc, rankdata

from .. import __version__
from ..errors import InputError
from ..io import write_outputs
from .filters import DEFAULT_RULES, kept_rows
from .schema import arrow_schema, to_arrow
from .store import Dataset, sha256

METHODS = ("random", "grid", "lhs")
#: Default sampling space: the inputs of the report's formulation.
INPUTS = ("deps1", "deps2", "alpha", "l1", "l2", "N1", "N2", "T1")
POOL = 2_000_000


def rank_space(X: np.ndarray) -> np.ndarray:
    """Empirical CDF of every column, in (0, 1) (ties share their mean rank)."""
    n = X.shape[0]
    return np.column_stack([(rankdata(X[:, j]) - 0.5) / n for j in range(X.shape[1])])


def grid_cells(U: np.ndarray, n: int) -> np.ndarray:
    """Cell of every row on the regular grid of [0, 1]^d with k = ceil(n^(1/d)) cells per axis."""
    d = U.shape[1]
    k = max(1, math.ceil(n ** (1.0 / d) - 1e-9))
    digits = np.minimum((U * k).astype(np.int64), k - 1)
    return np.ravel_multi_index(tuple(digits.T), (k,) * d)


def select(X: np.ndarray, n: int, method: str, rng: np.random.Generator) -> np.ndarray:
    """Indices of n distinct rows of X (N, d) chosen by ``method``."""
    N, d = X.shape
    if method not in METHODS:
        raise InputError(f"unknown sampling method {method!r} (known: {', '.join(METHODS)})")
    if not 0 < n <= N:
        raise InputError(f"cannot sample {n} rows from {N} available rows")
    if method == "random":
        return rng.choice(N, size=n, replace=False)
    U = rank_space(X)
    if method == "grid":
        # One row per occupied grid cell, cells taken evenly along their (row-major) order.
        cells = grid_cells(U, n)
        order = np.lexsort((rng.random(N), cells))  # random row order within each cell
        first = order[np.r_[True, np.diff(cells[order]) != 0]]
        if len(first) >= n:
            return first[np.round(np.linspace(0, len(first) - 1, n)).astype(np.int64)]
        rest = np.setdiff1d(np.arange(N), first)
        return np.concatenate([first, rng.choice(rest, n - len(first), replace=False)])
    # LHS: each design point takes a row of its stratum in one column (columns in turn); then
    # rows are swapped while no column's stratum occupancy gets worse (conditioned LHS).
    design = qmc.LatinHypercube(d=d, seed=rng).random(n)
    strata = np.minimum((U * n).astype(np.int64), n - 1)
    order = np.argsort(strata, axis=0, kind="stable").T.copy()
    start = np.stack([np.searchsorted(strata[order[j], j], np.arange(n + 1)) for j in range(d)])
    cols = np.arange(n) % d
    k = np.minimum((design[np.arange(n), cols] * n).astype(np.int64), n - 1)
    size = start[cols, k + 1] - start[cols, k]
    pick = np.where(size > 0, start[cols, k] + (rng.random(n) * np.maximum(size, 1)).astype(np.int64), -1)
    first = np.where(pick >= 0, order[cols, np.maximum(pick, 0)], rng.integers(N, size=n))
    first = _distinct(first, N, rng)
    return _clhs_refine(strata, order, start, first, int(rng.integers(2**31)), 30 * n)


def _distinct(rows: np.ndarray, N: int, rng: np.random.Generator) -> np.ndarray:
    """Replace repeated row indices by random unused ones."""
    rows = rows.copy()
    _, first = np.unique(rows, return_index=True)
    dup = np.setdiff1d(np.arange(len(rows)), first)
    if len(dup):
        free = np.setdiff1d(rng.permutation(N)[: len(rows) * 2 + len(dup)], rows)
        rows[dup] = free[: len(dup)]
    return rows


@njit(cache=True)
def _clhs_refine(strata, order, start, chosen, seed, iterations):
    """Swap chosen rows for unchosen ones while sum_j sum_k |count_jk - 1| does not grow.

    ``strata[i, j]`` is the stratum (0..n-1) of row i in column j; ``count_jk`` the chosen rows
    in stratum k of column j; the rows of stratum k of column j are
    ``order[j, start[j, k]:start[j, k + 1]]``. A proposal takes a column j, a row from one of its
    empty strata and a chosen row from one of its crowded strata. Returns the improved choice.
    """
    np.random.seed(seed)
    N, d = strata.shape
    n = chosen.shape[0]
    chosen = chosen.copy()
    counts = np.zeros((d, n), np.int64)
    taken = np.zeros(N, np.bool_)
    for i in range(n):
        taken[chosen[i]] = True
        for j in range(d):
            counts[j, strata[chosen[i], j]] += 1
    for _ in range(iterations):
        j = np.random.randint(d)
        k = np.random.randint(n)
        tries = 0
        while counts[j, k] != 0 and tries < 32:
            k = np.random.randint(n)
            tries += 1
        if counts[j, k] != 0 or start[j, k + 1] == start[j, k]:
            continue
        new = order[j, start[j, k] + np.random.randint(start[j, k + 1] - start[j, k])]
        pos = np.random.randint(n)
        tries = 0
        while counts[j, strata[chosen[pos], j]] < 2 and tries < 32:
            pos = np.random.randint(n)
            tries += 1
        out = chosen[pos]
        if taken[new]:
            continue
        delta = 0
        for jj in range(d):
            a = strata[out, jj]
            b = strata[new, jj]
            if a != b:
                # removing from a: |c-1| -> |c-2|; adding to b: |c-1| -> |c|
                delta += abs(counts[jj, a] - 2) - abs(counts[jj, a] - 1)
                delta += abs(counts[jj, b]) - abs(counts[jj, b] - 1)
        if delta <= 0:
            for jj in range(d):
                counts[jj, strata[out, jj]] -= 1
                counts[jj, strata[new, jj]] += 1
            taken[out] = False
            taken[new] = True
            chosen[pos] = new
    return chosen


def sample_split(ds: Dataset, n_train: int, n_test: int, method: str = "random", seed: int = 0,
                 rules: Sequence[str] = DEFAULT_RULES, columns: Sequence[str] = INPUTS,
                 pool: int = POOL, progress: Callable[[float], None] | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Disjoint sorted global row indices of a train and a test subset.

    Both subsets are drawn together by ``method`` from the rows kept by ``rules`` and then
    split at random, so that both cover the domain alike.
    """
    if method not in METHODS:
        raise InputError(f"unknown sampling method {method!r} (known: {', '.join(METHODS)})")
    for name, v in (("train size", n_train), ("test size", n_test)):
        if not isinstance(v, (int, np.integer)) or v < 0:
            raise InputError(f"{name} must be a non-negative integer, got {v!r}")
    n = n_train + n_test
    if n == 0:
        raise InputError("ask for at least one train or test row")
    rng = np.random.default_rng(seed)
    kept = kept_rows(ds, rules, None if progress is None else (lambda f: progress(0.5 * f)))
    if n > len(kept):
        raise InputError(f"asked for {n} rows but only {len(kept)} rows pass the cleaning rules")
    if method != "random" and len(kept) > max(pool, n):
        kept = np.sort(rng.choice(kept, size=max(pool, n), replace=False))
    X = np.column_stack([v for v in ds.read(list(columns), rows=kept).values()]) \
        if method != "random" else np.empty((len(kept), 1))
    if progress is not None:
        progress(0.6)
    chosen = kept[select(X, n, method, rng)]
    chosen = chosen[rng.permutation(n)]
    if progress is not None:
        progress(0.9)
    return np.sort(chosen[:n_train]), np.sort(chosen[n_train:])


def write_split(ds: Dataset, out: "str | os.PathLike", n_train: int, n_test: int,
                method: str = "random", seed: int = 0, rules: Sequence[str] = DEFAULT_RULES,
                columns: Sequence[str] = INPUTS,
                progress: Callable[[float], None] | None = None) -> dict:
    """Write ``train.parquet``, ``test.parquet`` (all columns plus the source ``row``) and a
    ``manifest.json`` naming the source dataset (its checksum), method, seed and rules."""
    train, test = sample_split(ds, n_train, n_test, method, seed, rules, columns, progress=progress)
    meta = {"format": "hmodel-cell-sample", "hmodel": __version__,
            "source": str(ds.folder), "source_checksum": ds.checksum,
            "schema_version": ds.manifest["schema_version"], "kind": ds.manifest["kind"],
            "options": ds.manifest["options"], "params": ds.manifest["params"],
            "method": method, "seed": seed, "rules": list(rules), "columns": list(columns),
            "files": {}}
    if ds.n_extra:  # a richer DEM cell's extra state travels with its rows
        meta["extra_fields"] = ds.manifest["extra_fields"]
    schema = arrow_schema(n_extra=ds.n_extra, material=ds.material).append(pa.field("row", pa.int64(), nullable=False))

    def writer(name: str, rows: np.ndarray):
        def write(path: Path) -> None:
            cols = {**ds.read(rows=rows), "row": rows}
            table = pa.Table.from_arrays([to_arrow(cols[f.name], f.type) for f in schema], schema=schema)
            pq.write_table(table, path, compression="zstd")
            meta["files"][name] = {"file": path.name, "rows": len(rows), "sha256": sha256(path)}
        return write

    write_outputs(out, {"train.parquet": writer("train", train), "test.parquet": writer("test", test),
                        "manifest.json": lambda p: p.write_text(json.dumps(meta, indent=1) + "\n")})
    return meta
