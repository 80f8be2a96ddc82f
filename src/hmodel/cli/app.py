"""``hmodel`` command line. Public contract: see DESIGN.md ("Public contract").

Every error hmodel raises on purpose is printed as one line ``hmodel: error: ...`` with exit
status 1 (2 for a malformed command line); outputs are written only once a run has succeeded.
"""

from __future__ import annotations

import sys
from typing import Annotated, Optional

import typer

from .. import __version__
from ..errors import HModelError
from . import run as run_cmds

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  rich_markup_mode=None,
                  help="The micromechanical H-model of granular materials (Nicot & Darve 2011).")
app.add_typer(run_cmds.app, name="run")


def _version(value: bool) -> None:
    if value:
        typer.echo(f"hmodel {__version__}")
        raise typer.Exit()


@app.callback()
def _root(version: Annotated[Optional[bool], typer.Option("--version", callback=_version,
                                                          is_eager=True, help="Show the version.")] = None) -> None:
    """The micromechanical H-model of granular materials (Nicot & Darve 2011)."""


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``hmodel`` console script."""
    try:
        app(args=argv, prog_name="hmodel")
    except SystemExit as e:
        return e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
    except HModelError as e:
        print(f"hmodel: error: {' '.join(str(e).split())}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("hmodel: interrupted", file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
