"""``hmodel reproduce [--quick]``: the project's main job (see :mod:`hmodel.studies.reproduce`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .options import out_folder
from .progress import LazyProgress


def reproduce(
    quick: Annotated[bool, typer.Option("--quick", help="Reduced study (≈ 1 minute): the shipped surrogate "
                                                        "and a small database; without it, the report-scale "
                                                        "database and a surrogate trained on it (≈ 10 min).")] = False,
    out: out_folder("Folder for report.html, figures and tables.") = Path("results"),
    solver: Annotated[str, typer.Option(help="Surrogate compared with the closed form in --quick: "
                                             "surrogate (shipped), surrogate:NAME or surrogate:MODEL_FILE.")] = "surrogate",
) -> None:
    """Reproduce the study in one self-contained HTML report.

    The report holds the engine curves (the report's Fig. 1.7), a database, the surrogate's
    accuracy, the macro comparison and timings."""
    from ..studies.reproduce import reproduce as run

    with LazyProgress("reproducing the study") as progress:
        report = run(out, quick, solver, progress)
    typer.echo(f"wrote {report}")
