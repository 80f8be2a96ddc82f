"""Where the compiled kernels are cached: one directory per version of the package's sources.

Numba's on-disk cache (``@njit(cache=True)``) recognises a kernel by its own file's
modification time and size. A kernel that inlines functions of *another* module (the closed
form inlines :mod:`hmodel.cell.hertz` and :mod:`hmodel.cell.renewal`, the REV trials inline
the cells) is therefore not recompiled when only that other module changes: it keeps running
the old code, silently (docs/development.md, "The Numba cache").

So the cache lives in a directory named by a digest of every source file of the package:
``$HMODEL_CACHE_DIR/numba-<digest>`` (default ``~/.cache/hmodel``, or ``$XDG_CACHE_HOME/hmodel``).
Any change to any source file gives a new directory, and a fresh compilation; the same sources
reuse theirs across processes, worker processes and checkouts. A ``NUMBA_CACHE_DIR`` set by the
user is left as it is (its staleness is then the user's to manage). Old directories may be
deleted at any time.
"""

from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path

#: The package's sources, whose digest names the cache directory.
PACKAGE = Path(__file__).resolve().parent


def source_digest(root: Path = PACKAGE) -> str:
    """A digest of the relative paths and contents of every ``*.py`` file under ``root``."""
    h = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        h.update(path.relative_to(root).as_posix().encode())
        h.update(b"\0")
        h.update(path.read_bytes())
        h.update(b"\0")
    return h.hexdigest()[:16]


def cache_base() -> Path:
    """``$HMODEL_CACHE_DIR``, else ``$XDG_CACHE_HOME/hmodel``, else ``~/.cache/hmodel``."""
    if os.environ.get("HMODEL_CACHE_DIR"):
        return Path(os.environ["HMODEL_CACHE_DIR"])
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "hmodel"


def configure(root: Path = PACKAGE) -> str | None:
    """Point Numba's cache at ``cache_base()/numba-<digest of root>`` unless ``NUMBA_CACHE_DIR``
    is set; returns the directory, or None where the user's is kept or none is writable (Numba
    then keeps its default, beside the sources). Must run before the first kernel is defined:
    Numba picks a kernel's cache directory when it is decorated."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    path = cache_base() / f"numba-{source_digest(root)}"
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    if not os.access(path, os.W_OK):
        return None
    # The environment carries it to worker processes; a Numba imported before us reads its
    # config once, so it is told directly too.
    os.environ["NUMBA_CACHE_DIR"] = str(path)
    if "numba" in sys.modules:
        from numba.core import config

        config.CACHE_DIR = str(path)
    return str(path)
