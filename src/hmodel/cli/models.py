"""``hmodel models``: the named variants of the H-model that ``--model`` takes."""

from __future__ import annotations

import typer

from ..variants import ALIASES, DEFAULT, VARIANTS


def models() -> None:
    """List the variants of the H-model (--model NAME on run, calibrate and fem)."""
    from rich.console import Console
    from rich.table import Table

    table = Table(title="H-model variants (--model NAME)")
    for c in ("name", "also", "uses e0", "mechanisms", "fits", "what it is"):
        table.add_column(c)
    for name, v in VARIANTS.items():
        also = ", ".join(a for a, target in ALIASES.items() if target == name)
        table.add_row(name + (" (default)" if name == DEFAULT else ""), also, "yes" if v.uses_e0 else "no",
                      ", ".join(f"{k}={val}" for k, val in v.options) or "-", ",".join(v.fitted),
                      v.description)
    Console().print(table)
    typer.echo("The docs recommend sand for sands: calibrate it on tests whose --data give e0, then run "
               "it at any density with --calibration DIR --e0 VALUE.")
