"""Reading strain paths and writing run outputs without leaving partial files behind."""

from __future__ import annotations

import csv
import errno
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from .errors import InputError


#: The longest line a CSV file may have, in characters: a file with no line end (``/dev/zero``,
#: a binary file) is refused after reading this much, not read into memory whole.
MAX_CSV_LINE = 2**20


def read_csv_rows(path: "str | os.PathLike", what: str) -> list[list[str]]:
    """The non-blank rows of a text CSV file; a one-line InputError naming ``what`` (e.g.
    "strain path") and the file when it cannot be read. A byte-order mark (a spreadsheet's
    "CSV UTF-8") is not part of the first column's name."""
    if os.path.isdir(path):
        raise InputError(f"{what} {str(path)!r} is a folder, not a CSV file")
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(_bounded_lines(fh, what, path))
            rows = list(reader)
    except OSError as e:
        raise InputError(f"cannot read {what} {str(path)!r}: {e.strerror}") from None
    except UnicodeDecodeError:
        raise InputError(f"{what} {str(path)!r} is not a text CSV file") from None
    except csv.Error as e:  # a field over csv.field_size_limit(), a NUL byte, an open quote
        raise InputError(f"{what} {str(path)!r}, line {reader.line_num}: {e}") from None
    return [r for r in rows if any(c.strip() for c in r)]


def _bounded_lines(fh, what: str, path) -> Iterator[str]:
    for number, line in enumerate(iter(lambda: fh.readline(MAX_CSV_LINE + 1), ""), 1):
        if len(line) > MAX_CSV_LINE and not line.endswith(("\n", "\r")):
            raise InputError(f"{what} {str(path)!r}, line {number}: longer than {MAX_CSV_LINE:,} "
                             "characters (not a text CSV file?)")
        yield line


def read_strain_path(path: "str | os.PathLike") -> np.ndarray:
    """Cumulative strains (n, 3) from a CSV with header ``eps11,eps22[,eps12]``.

    Raises :class:`InputError` naming the file, line and problem for anything malformed.
    """
    path = Path(path)
    rows = read_csv_rows(path, "strain path")
    if not rows:
        raise InputError(f"strain path {str(path)!r} is empty")
    header = [c.strip() for c in rows[0]]
    if header not in (["eps11", "eps22"], ["eps11", "eps22", "eps12"]):
        raise InputError(f"strain path {str(path)!r}: header must be eps11,eps22[,eps12], got {','.join(header)!r}")
    if len(rows) < 2:
        raise InputError(f"strain path {str(path)!r} has a header but no rows")
    out = np.zeros((len(rows) - 1, 3))
    for i, row in enumerate(rows[1:]):
        if len(row) != len(header):
            raise InputError(f"strain path {str(path)!r}, line {i + 2}: expected {len(header)} values, got {len(row)}")
        for j, cell in enumerate(row):
            try:
                v = float(cell)
            except ValueError:
                raise InputError(f"strain path {str(path)!r}, line {i + 2}: {cell.strip()!r} is not a number") from None
            if not np.isfinite(v):
                raise InputError(f"strain path {str(path)!r}, line {i + 2}: non-finite strain {cell.strip()!r}")
            out[i, j] = v
    return out


def existing_ancestor(path: "str | os.PathLike") -> Path:
    """``path`` itself or its nearest ancestor that exists (the current folder at the end)."""
    path = Path(os.path.abspath(path))
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def check_output_folder(out_dir: "str | os.PathLike") -> Path:
    """Refuse, before any work, an output folder that cannot be written: ``out_dir`` is a file,
    or the nearest existing folder of its path is not writable (tried by creating and removing
    a temporary folder there, so that read-only mounts and immutable folders are seen as
    such); nothing is left behind."""
    out_dir = Path(out_dir)
    if str(out_dir).strip() == "":
        raise InputError("the output path is empty: give a folder")
    _refuse_broken_link(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError(f"output path {str(out_dir)!r} exists and is not a folder")
    _check_writable(existing_ancestor(out_dir), out_dir)
    return out_dir


def check_output_file(path: "str | os.PathLike") -> Path:
    """Refuse, before any work, an output file that cannot be written: ``path`` is a folder,
    or the nearest existing folder of its path is not writable; nothing is left behind."""
    path = Path(path)
    if str(path).strip() == "":
        raise InputError("the output path is empty: give a file name")
    _refuse_broken_link(path)
    if path.is_dir():
        raise InputError(f"output file {str(path)!r} is a folder")
    _check_writable(existing_ancestor(path.parent), path)
    return path


def _refuse_broken_link(path: Path) -> None:
    """Refuse a symbolic link in ``path`` that leads nowhere (dangling, or looping): the path
    looks absent, so it would pass as a new output, and the outputs could not be moved there
    after the whole run (``File exists``)."""
    while path != path.parent and not path.exists():
        if path.is_symlink():
            if _stat_errno(path) == errno.ELOOP:
                raise InputError(f"output path {str(path)!r} is a looping symbolic link")
            raise InputError(f"output path {str(path)!r} is a dangling symbolic link "
                             f"(to {os.readlink(path)!r}, which cannot be reached)")
        path = path.parent


def _stat_errno(path: Path) -> int | None:
    try:
        os.stat(path)
    except OSError as e:
        return e.errno
    return None


def _check_writable(folder: Path, target: Path) -> None:
    if not folder.is_dir():
        raise InputError(f"cannot write {str(target)!r}: {str(folder)!r} is not a folder")
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".hmodel-check.", dir=folder))
    except OSError as e:
        raise InputError(f"cannot write {str(target)!r}: {e.strerror} in {str(folder)!r}") from None


def write_rows(rows: list[dict], path: "str | os.PathLike") -> None:
    """A CSV of dict rows; the columns are the union of their keys, in first-seen order."""
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(dict.fromkeys(k for r in rows for k in r)), restval="")
        w.writeheader()
        w.writerows(rows)


def write_outputs(out_dir: "str | os.PathLike", writers: dict[str, Callable[[Path], None]]) -> list[Path]:
    """Write every file into a temporary folder first, then move them all into ``out_dir``.

    A failure in any writer leaves ``out_dir`` as it was (no partial file).
    """
    out_dir = check_output_folder(out_dir)
    parent = out_dir.parent if out_dir.parent != Path("") else Path(".")
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise InputError(f"cannot create output folder {str(out_dir)!r}: {e.strerror}") from None
    tmp = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.", dir=parent))
    try:
        for name, write in writers.items():
            write(tmp / name)
        out_dir.mkdir(exist_ok=True)
        written = []
        for name in writers:
            os.replace(tmp / name, out_dir / name)
            written.append(out_dir / name)
        return written
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
