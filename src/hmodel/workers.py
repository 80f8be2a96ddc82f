"""Where independent tasks run: this process, local worker processes, or a Dask cluster (a
database's shards, a calibration's least-squares starts).

Results are yielded as they complete, with a bounded number of tasks in flight, so that memory
stays bounded whatever the number of shards. Every task is a pure function of its arguments:
the rows do not depend on where or in which order they were computed.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

from .errors import InputError


def run_tasks(fn: Callable, args: Sequence[tuple], keys: Sequence, *, workers: int = 1,
              scheduler: str | None = None, in_flight: int | None = None) -> Iterator[tuple]:
    """Yield ``(key, fn(*args))`` for every task, in completion order; ``workers`` local
    processes at most, and no more than :func:`local_workers` allows."""
    if workers < 1:
        raise InputError(f"workers must be at least 1, got {workers}")
    workers = local_workers(workers)
    if scheduler:
        yield from _dask(fn, args, keys, scheduler, in_flight)
    elif workers == 1 or len(args) <= 1:
        for k, a in zip(keys, args):
            yield k, fn(*a)
    else:
        yield from _processes(fn, args, keys, workers, in_flight or 2 * workers)


def local_workers(requested: int) -> int:
    """``requested`` local processes, capped at one per CPU (``os.cpu_count()``): more only
    share the same cores, each holding its own copy of the model and its tasks in flight, and
    the results do not depend on the number."""
    return max(1, min(requested, os.cpu_count() or 1))


def one_thread_each() -> None:
    """Run this process's BLAS products and Numba kernels on one thread: worker processes
    already share the cores, and threads within each would oversubscribe them (a surrogate's
    batch split among threads, a parallel kernel's thread team, in every worker at once)."""
    import numba
    import scipy.linalg  # noqa: F401  (SciPy's own BLAS: a limit holds for the libraries loaded)
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)
    numba.set_num_threads(1)


def _processes(fn, args, keys, workers, in_flight) -> Iterator[tuple]:
    # spawn: workers start clean (no inherited threads or locks), and import hmodel themselves.
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=one_thread_each) as pool:
        pending = {}
        queue = list(zip(keys, args))[::-1]
        while queue or pending:
            while queue and len(pending) < in_flight:
                k, a = queue.pop()
                pending[pool.submit(fn, *a)] = k
            finished, _ = wait(pending, return_when=FIRST_COMPLETED)
            for fut in finished:
                yield pending.pop(fut), fut.result()


def _dask(fn, args, keys, scheduler, in_flight) -> Iterator[tuple]:
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise InputError("--scheduler needs Dask: pip install 'hmodel[dask]'") from None
    try:
        client = Client(scheduler, timeout="10s", set_as_default=False)
    except (OSError, TimeoutError) as e:
        raise InputError(f"cannot reach the Dask scheduler at {scheduler!r}: {e}") from None
    try:
        n_workers = max(1, len(client.scheduler_info().get("workers", {})))
        limit = in_flight or 2 * n_workers
        queue = list(zip(keys, args))[::-1]
        futures = {}

        def submit():
            k, a = queue.pop()
            fut = client.submit(fn, *a, pure=False)
            futures[fut] = k
            return fut

        ac = as_completed([submit() for _ in range(min(limit, len(queue)))], loop=client.loop)
        for fut in ac:
            k = futures.pop(fut)
            result = fut.result()
            fut.release()
            if queue:
                ac.add(submit())
            yield k, result
    finally:
        client.close()
