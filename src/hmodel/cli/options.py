"""Output options shared by the commands: refused before any work when they cannot be written;
and the ``--workers`` option, capped at the CPUs.

``--out ""`` is a malformed command line (exit 2); an output that exists as the wrong kind
(a file for a folder, a folder for a file) or lies where nothing can be written is refused
with exit 1 (:func:`hmodel.io.check_output_folder`, :func:`hmodel.io.check_output_file`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from ..errors import InputError
from ..io import check_output_file, check_output_folder
from ..workers import local_workers


def _path(value) -> Path:
    if not str(value).strip():
        raise typer.BadParameter("the path is empty")
    return Path(value)


def _folder(ctx: typer.Context, value: Path | None) -> Path | None:
    if value is None or ctx.resilient_parsing:
        return value
    return check_output_folder(value)


def _file(ctx: typer.Context, value: Path | None) -> Path | None:
    if value is None or ctx.resilient_parsing:
        return value
    return check_output_file(value)


def out_folder(help: str, optional: bool = False):
    """The ``--out``/``-o`` option of a command that writes a folder (``optional``: None when
    not given)."""
    return Annotated[Optional[Path] if optional else Path, typer.Option("--out", "-o", help=help, parser=_path, callback=_folder,
                                        metavar="<path>")]


def out_file(help: str):
    """The ``--out``/``-o`` option of a command that writes one file."""
    return Annotated[Path, typer.Option("--out", "-o", help=help, parser=_path, callback=_file,
                                        metavar="<path>")]


def _workers(ctx: typer.Context, value: int | None) -> int | None:
    if value is None or ctx.resilient_parsing:
        return value
    usable = local_workers(value)
    if usable < value:  # more processes would share the same cores (the results are the same)
        typer.echo(f"hmodel: warning: --workers {value} is more than the CPUs ({usable}): using {usable}",
                   err=True)
    return usable


def workers_opt(help: str, optional: bool = False):
    """The ``--workers`` option: local processes, at least 1 (exit 2 below), capped at one per
    CPU with a warning (``optional``: None when not given)."""
    return Annotated[Optional[int] if optional else int, typer.Option("--workers", min=1, help=help,
                                                                      callback=_workers)]


ModelOpt = Annotated[Optional[str], typer.Option(
    "--model", help="Variant of the H-model (hmodel models): published (default), density (alias sand: "
                    "alpha0 from the specimen's void ratio --e0).")]
CalibrationOpt = Annotated[Optional[Path], typer.Option(
    "--calibration", help="Folder (or calibration.json) of a calibration: run its fitted model (parameters, "
                          "variant, 3D directions); -p changes parameters on top of it.")]
E0Opt = Annotated[Optional[str], typer.Option(
    "--e0", help="Void ratio of the specimen, or a comma list (one material point each, broadcast against "
                 "--p0): sets alpha0 through a model that uses e0 (sand), from its alpha0 at --e-ref.")]
ERefOpt = Annotated[Optional[float], typer.Option(
    "--e-ref", help="Void ratio at which the parameters' alpha0 holds (default: the calibration's).")]


def _void_ratios(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise InputError(f"--e0 must be void ratios (0.84 or 0.7,0.8), got {text!r}") from None
    for v in values:
        if not (v > 0 and v < float("inf")):
            raise InputError(f"--e0 must be positive void ratios, got {text!r}")
    return values


def specimen(model: str | None, calibration: Path | None, e0: str | None, e_ref: float | None, dim: int):
    """The run's :class:`~hmodel.calibrate.calibrated.Specimen` of --model, --calibration,
    --e0 and --e-ref (None when none is given)."""
    from ..calibrate.calibrated import Specimen

    return Specimen.make(model, calibration, None if e0 is None else _void_ratios(e0), e_ref, dim)
