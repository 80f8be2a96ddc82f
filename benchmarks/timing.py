"""Shared by the benchmark scripts: the best wall time of repeated runs after a warm-up."""

from __future__ import annotations

import time


def best_of(fn, repeat: int) -> float:
    """Best of ``repeat`` timed calls of ``fn`` after one untimed call (compilation, caches)."""
    fn()
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)
