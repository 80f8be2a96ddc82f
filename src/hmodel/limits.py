"""The work-size guard: requests too large for this machine are refused before anything is
allocated or computed, in one line naming the size and the limit.

Two limits, each overridable by an environment variable:

- **memory** (``HMODEL_MEMORY_LIMIT``, bytes or ``8GiB``/``500MB``): a request's estimated
  working memory (cells × bytes per cell, Gauss points, recorded rows) must stay within it;
  by default half the memory the system reports available (``MemAvailable`` of
  ``/proc/meminfo``), so that a run never reaches the out-of-memory killer, or half the
  address space the process has left where ``ulimit -v`` (or ``-d``) leaves less: an
  allocation past that limit fails however much memory is free.
- **disk**: a database's estimated size must fit in the free space of its folder's disk.
- **increments** (``HMODEL_MAX_INCREMENTS``, default :data:`MAX_INCREMENTS`): the loading
  increments (or load steps) one run may take; more cannot finish in a working day, nor be
  recorded (every increment is a row of the result table).
- **rows** (``HMODEL_MAX_ROWS``, default :data:`MAX_ROWS`): the rows of one result table, a row
  per material point and increment; more are no table to read (a spreadsheet holds 2^20 rows)
  and take minutes to compute and write. Their memory (:func:`table_bytes`) counts with the
  cells'.

>>> check_count(100, "increments of stage 'shear'", env={})
100
>>> check_count(10**9, "increments of stage 'shear'", env={})
Traceback (most recent call last):
...
hmodel.limits.WorkTooLarge: increments of stage 'shear': 1e+09 exceeds the limit of 1e+07 (HMODEL_MAX_INCREMENTS)
>>> parse_bytes("1.5GiB")
1610612736
"""

from __future__ import annotations

import math
import os
import re
import shutil
from collections.abc import Mapping

from .errors import InputError
from .io import existing_ancestor

#: Default largest number of increments of one run (``HMODEL_MAX_INCREMENTS``).
MAX_INCREMENTS = 10**7
#: Default share of the available memory one request may plan to use.
MEMORY_SHARE = 0.5
MEMORY_ENV = "HMODEL_MEMORY_LIMIT"
INCREMENTS_ENV = "HMODEL_MAX_INCREMENTS"
#: Default largest number of rows of one result table (``HMODEL_MAX_ROWS``).
MAX_ROWS = 10**6
ROWS_ENV = "HMODEL_MAX_ROWS"
#: Bytes one value of a result table takes at the peak of a run: the recorded blocks, their
#: concatenation, its sorted copy and the plot's (measured: 32.5 per value of a 3D table of
#: 26 columns, 845 bytes a row).
TABLE_BYTES_PER_VALUE = 40

_SIZE = re.compile(r"^\s*([0-9.]+(?:[eE][-+]?\d+)?)\s*([KMGT]i?B?|B)?\s*$")
_FACTORS = {"": 1, "B": 1, "K": 1e3, "KB": 1e3, "M": 1e6, "MB": 1e6, "G": 1e9, "GB": 1e9,
            "T": 1e12, "TB": 1e12, "KI": 2**10, "KIB": 2**10, "MI": 2**20, "MIB": 2**20,
            "GI": 2**30, "GIB": 2**30, "TI": 2**40, "TIB": 2**40}


class WorkTooLarge(InputError):
    """A request larger than the machine's memory or than any run can finish."""


def parse_bytes(text: str) -> int:
    """A memory size: a number of bytes, optionally with a unit (``500MB``, ``8GiB``)."""
    m = _SIZE.match(str(text))
    factor = _FACTORS.get((m.group(2) or "").upper()) if m else None
    if factor is None:
        raise InputError(f"{MEMORY_ENV} must be a size such as 8GiB or 500MB, got {text!r}")
    value = float(m.group(1)) * factor
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"{MEMORY_ENV} must be a positive size, got {text!r}")
    return int(value)


def human_bytes(n: float) -> str:
    """``n`` bytes in binary units, three significant digits (``85.8 GiB``)."""
    for unit, factor in (("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= factor:
            return f"{n / factor:.3g} {unit}"
    return f"{n:.0f} B"


def available_memory() -> int:
    """Memory the system reports available to new allocations [bytes]."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


def address_space_left() -> int | None:
    """Bytes the process may still map under its ``ulimit -v`` (``RLIMIT_AS``, against its
    virtual size) or ``ulimit -d`` (``RLIMIT_DATA``, against its data size), the smaller;
    None without either limit."""
    import resource  # here: POSIX only, and only when no HMODEL_MEMORY_LIMIT is given

    left = None
    for limit, field in ((resource.RLIMIT_AS, "VmSize:"), (resource.RLIMIT_DATA, "VmData:")):
        soft = resource.getrlimit(limit)[0]
        if soft == resource.RLIM_INFINITY:
            continue
        used = 0
        try:
            with open("/proc/self/status") as fh:
                used = next((int(line.split()[1]) * 1024 for line in fh if line.startswith(field)), 0)
        except OSError:
            pass
        left = max(soft - used, 0) if left is None else min(left, max(soft - used, 0))
    return left


def memory_limit(env: Mapping[str, str] | None = None) -> tuple[int, str]:
    """The memory budget of one request [bytes] and a phrase saying where it comes from."""
    env = os.environ if env is None else env
    if env.get(MEMORY_ENV):
        return parse_bytes(env[MEMORY_ENV]), MEMORY_ENV
    available, mapped = available_memory(), address_space_left()
    if mapped is not None and mapped < available:
        return (int(MEMORY_SHARE * mapped),
                f"half the address space left under ulimit -v; set {MEMORY_ENV} to change it")
    return int(MEMORY_SHARE * available), f"half the available memory; set {MEMORY_ENV} to change it"


def check_memory(nbytes: float, what: str, env: Mapping[str, str] | None = None) -> None:
    """Refuse (:class:`WorkTooLarge`) a request whose estimated memory ``nbytes`` exceeds the
    budget of :func:`memory_limit`; ``what`` names the request and its sizes."""
    limit, source = memory_limit(env)
    if not nbytes <= limit:  # also refuses NaN and overflowed estimates
        raise WorkTooLarge(f"{what} needs about {human_bytes(nbytes)} of memory, over the limit of "
                           f"{human_bytes(limit)} ({source})")


def check_disk(nbytes: float, folder: "str | os.PathLike", what: str) -> None:
    """Refuse (:class:`WorkTooLarge`) writing about ``nbytes`` under ``folder`` when the disk
    holding it (its nearest existing ancestor) has less free space."""
    path = existing_ancestor(folder)
    free = shutil.disk_usage(path).free
    if not nbytes <= free:
        raise WorkTooLarge(f"{what} needs about {human_bytes(nbytes)} of disk, and {str(path)!r} has "
                           f"{human_bytes(free)} free")


def max_increments(env: Mapping[str, str] | None = None) -> int:
    """The largest number of increments of one run (``HMODEL_MAX_INCREMENTS``)."""
    return _env_count(env, INCREMENTS_ENV, MAX_INCREMENTS)


def _env_count(env: Mapping[str, str] | None, name: str, default: int) -> int:
    """A positive count from the environment variable ``name`` (``default`` when unset)."""
    env = os.environ if env is None else env
    text = env.get(name)
    if not text:
        return default
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (math.isfinite(value) and value >= 1):
        raise InputError(f"{name} must be a positive number, got {text!r}")
    return int(value)


def check_count(n: float, what: str, env: Mapping[str, str] | None = None) -> int:
    """``n`` as an int if it is within :func:`max_increments`, else :class:`WorkTooLarge`.
    ``n`` may be a float too large for an int (a strain over a tiny increment)."""
    limit = max_increments(env)
    if not n <= limit:
        shown = f"{float(n):.3g}" if math.isfinite(float(n)) else "an unbounded number"
        raise WorkTooLarge(f"{what}: {shown} exceeds the limit of {limit:.3g} ({INCREMENTS_ENV})")
    return int(n)


def max_rows(env: Mapping[str, str] | None = None) -> int:
    """The largest number of rows of one result table (``HMODEL_MAX_ROWS``)."""
    return _env_count(env, ROWS_ENV, MAX_ROWS)


def check_rows(n: float, what: str, env: Mapping[str, str] | None = None) -> int:
    """``n`` rows of a result table as an int if within :func:`max_rows`, else
    :class:`WorkTooLarge` naming ``what`` (the request the rows come from)."""
    limit = max_rows(env)
    if not n <= limit:
        shown = f"{float(n):.3g}" if math.isfinite(float(n)) else "an unbounded number of"
        raise WorkTooLarge(f"{what}: a result table of {shown} rows exceeds the limit of {limit:.3g} "
                           f"rows ({ROWS_ENV})")
    return int(n)


def table_bytes(rows: float, columns: int) -> float:
    """Estimated memory [bytes] of a result table of ``rows`` rows and ``columns`` columns
    while it is recorded and written (:data:`TABLE_BYTES_PER_VALUE`)."""
    return float(rows) * float(columns) * TABLE_BYTES_PER_VALUE


def steps_for(change: float, increment: float, what: str) -> int:
    """Increments of at most ``increment`` covering ``change`` (at least 1), checked against
    :func:`max_increments` before any integer is formed."""
    ratio = abs(change) / increment
    return max(1, check_count(math.ceil(ratio - 1e-9) if ratio < 1e300 else ratio, what))
