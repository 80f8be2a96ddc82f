"""The network outputs of recently seen batches of cell states, looked up by the states themselves.

A surrogate whose network sees the state only (the ``compliance`` and ``meso`` formulations)
answers every Newton trial of an increment, and every finite-difference probe of its tangent,
from one evaluation per state. The REV calls the cell solver once per parameter set present, so
a batch of many sets (the walkers of a calibration, the zones of a finite-element mesh) sends
the network as many batches per trial, in turn: a cache of the last one or two batches would
miss on every call, and each trial would cost a full inference. This cache keeps the batches of
the last few increments, up to a memory budget, keyed by a hash of a sample of their rows
(hashing every byte of a finite-element mesh's batch cost more than the cell increments it
saved) and confirmed by comparison of all.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any

import numpy as np

#: Memory budget of one cache (states and outputs); the last ``MIN_ENTRIES`` batches are kept
#: whatever their size (a finite-element mesh's batch alone can exceed it).
MAX_BYTES = 256 * 2**20
MAX_ENTRIES = 256
MIN_ENTRIES = 2
#: Rows of a batch its key hashes at most (evenly spaced; all rows are compared on a hit).
KEY_ROWS = 1024
#: Rows of a batch whose values :func:`distinct_rows` looks at first (evenly spaced): where they
#: all differ, so do most rows, and the batch is not sorted.
SAMPLE_ROWS = 64


def distinct_rows(v: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The rows of ``v`` (n, m) that hold each distinct value once, and for every row the index
    of its value among them (``v[first][inverse]`` equals ``v``); None where all rows differ.

    Rows are grouped by a weighted sum of their fields, sorted, and every row is compared field
    by field with the first of its group: one that differs (its sum rounded to another's) is a
    value of its own. Sorting the sums costs a fraction of a network pass over the rows, but
    where no rows repeat (a sheared REV, a finite-element mesh) it buys nothing: the sort runs
    only where :data:`SAMPLE_ROWS` evenly spaced rows already repeat a value."""
    n, m = v.shape
    if n < 2:
        return None
    key = v @ (1.0 + 0.6180339887498949 * np.arange(m))  # fields weighed apart
    sample = key[::max(1, n // SAMPLE_ROWS)]
    if len(np.unique(sample)) == len(sample):
        return None
    order = np.argsort(key, kind="stable")
    k = key[order]
    new = np.empty(n, bool)
    new[0] = True
    np.not_equal(k[1:], k[:-1], out=new[1:])
    if new.all():
        return None
    inverse = np.empty(n, np.int64)
    inverse[order] = np.cumsum(new) - 1
    first = order[new]
    odd = np.flatnonzero(np.any(v[first][inverse] != v, axis=1))
    if len(odd):
        inverse[odd] = len(first) + np.arange(len(odd))
        first = np.concatenate([first, odd])
    return first, inverse


def _nbytes(value: Any) -> int:
    if isinstance(value, np.ndarray):
        return value.nbytes
    if isinstance(value, (list, tuple)):
        return sum(_nbytes(v) for v in value)
    return 0


class StateCache:
    """Least-recently-used map from a batch of states ``v`` (an array) to what was computed
    from it, within :data:`MAX_BYTES` and :data:`MAX_ENTRIES`."""

    def __init__(self, max_bytes: int = MAX_BYTES, max_entries: int = MAX_ENTRIES):
        self.max_bytes, self.max_entries = max_bytes, max_entries
        self._entries: OrderedDict[tuple, tuple[np.ndarray, Any, int]] = OrderedDict()
        self._bytes = 0

    def __len__(self) -> int:
        return len(self._entries)

    @staticmethod
    def _key(v: np.ndarray, extra: tuple = ()) -> tuple:
        """Shape, type and a hash of at most :data:`KEY_ROWS` rows, and ``extra``: batches
        that share a key but differ are told apart by :meth:`get`'s comparison (a miss), and
        :meth:`put` keeps the newer."""
        sample = v[::max(1, len(v) // KEY_ROWS)] if v.ndim else v
        return v.shape, v.dtype.str, hash(np.ascontiguousarray(sample).tobytes()), extra

    def get(self, v: np.ndarray, extra: tuple = ()) -> Any | None:
        """What was stored for states equal to ``v`` and ``extra`` (what else the value
        depends on: a family network's material), or None."""
        key = self._key(v, extra)
        hit = self._entries.get(key)
        if hit is None or not np.array_equal(hit[0], v):
            return None
        self._entries.move_to_end(key)
        return hit[1]

    def put(self, v: np.ndarray, value: Any, extra: tuple = ()) -> None:
        """Keep ``value`` for (a copy of) the states ``v`` and ``extra``, dropping the oldest
        entries beyond the budget."""
        key = self._key(v, extra)
        old = self._entries.pop(key, None)
        if old is not None:
            self._bytes -= old[2]
        size = v.nbytes + _nbytes(value)
        self._entries[key] = (v.copy(), value, size)
        self._bytes += size
        while len(self._entries) > MIN_ENTRIES and (self._bytes > self.max_bytes
                                                    or len(self._entries) > self.max_entries):
            _, (_, _, n) = self._entries.popitem(last=False)
            self._bytes -= n

    def clear(self) -> None:
        self._entries.clear()
        self._bytes = 0
