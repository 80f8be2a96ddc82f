"""``hmodel`` command line. Its contract: docs/cli.md ("Output and error contract").

Every error of the user's input or of the environment is printed as one line
``hmodel: error: ...``: exit status 1 for a problem with the inputs, the computation or the
machine (an :class:`~hmodel.errors.HModelError`, an ``OSError``, a ``MemoryError``, also one
raised inside a compiled kernel, which reaches Python as the cause of a ``SystemError``), 2 for a
malformed command line (unknown option, a value that is not a number or out of its range, a
missing argument). Anything else is a bug in hmodel: it keeps its traceback. With
``HMODEL_DEBUG=1`` every error shows its full traceback. Outputs are written only once a run
has succeeded.
"""

from __future__ import annotations

import os
import sys
from typing import Annotated, Optional

import typer

from .. import __version__
from ..errors import HModelError
from . import calibrate as calibrate_cmd
from . import compare as compare_cmd
from . import data as data_cmds
from . import dem as dem_cmds
from . import failure as failure_cmd
from . import fem as fem_cmds
from . import models as models_cmd
from . import reproduce as reproduce_cmd
from . import run as run_cmds
from . import stability as stability_cmd
from . import surrogate as surrogate_cmds

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  rich_markup_mode=None,
                  help="The micromechanical H-model of granular materials (Nicot & Darve 2011).")
app.add_typer(run_cmds.app, name="run")
app.add_typer(data_cmds.app, name="data")
app.add_typer(surrogate_cmds.app, name="surrogate")
app.add_typer(dem_cmds.app, name="dem")
app.add_typer(fem_cmds.app, name="fem")
app.command("compare")(compare_cmd.compare)
app.command("calibrate")(calibrate_cmd.calibrate)
app.command("reproduce")(reproduce_cmd.reproduce)
app.command("stability")(stability_cmd.stability)
app.command("failure-surface")(failure_cmd.failure)
app.command("models")(models_cmd.models)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"hmodel {__version__}")
        raise typer.Exit()


@app.callback()
def _root(version: Annotated[Optional[bool], typer.Option("--version", callback=_version,
                                                          is_eager=True, help="Show the version.")] = None) -> None:
    """The micromechanical H-model of granular materials (Nicot & Darve 2011)."""


# Typer's command-line errors derive from click's ClickException, which recent Typer versions
# vendor under a private module: reach the class through a public subclass instead.
_ClickException = next(c for c in typer.BadParameter.__mro__ if c.__name__ == "ClickException")


def _one_line(message: str) -> str:
    return " ".join(str(message).split())


def _environment_message(e: BaseException) -> str:
    """One line for an error of the machine rather than of hmodel (a full disk, a folder that
    vanished, memory exhausted despite the size guard)."""
    if isinstance(e, MemoryError):
        return "out of memory (the work-size guard's estimate was short: lower HMODEL_MEMORY_LIMIT)"
    return f"{e.strerror or e}" + (f": {e.filename!r}" if e.filename else "")


def _out_of_memory(e: BaseException) -> bool:
    """Whether ``e`` is, or was raised by, a ``MemoryError``: an allocation that failed inside
    a compiled (Numba) kernel reaches Python as a ``SystemError`` caused by one."""
    seen = set()
    while e is not None and id(e) not in seen:
        if isinstance(e, MemoryError):
            return True
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return False


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``hmodel`` console script; returns the exit status."""
    debug = os.environ.get("HMODEL_DEBUG", "") not in ("", "0")
    try:
        code = app(args=argv, prog_name="hmodel", standalone_mode=False)
    except SystemExit as e:
        return e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
    except HModelError as e:
        if debug:
            raise
        print(f"hmodel: error: {_one_line(e)}", file=sys.stderr)
        return 1
    except (OSError, MemoryError) as e:
        if debug:
            raise
        print(f"hmodel: error: {_one_line(_environment_message(e))}", file=sys.stderr)
        return 1
    except SystemError as e:
        if debug or not _out_of_memory(e):  # any other SystemError is a bug: its traceback
            raise
        print(f"hmodel: error: {_one_line(_environment_message(MemoryError()))}", file=sys.stderr)
        return 1
    except _ClickException as e:
        if type(e).__name__ == "NoArgsIsHelpError":  # bare group: show its help
            e.show()
            return 2
        ctx = getattr(e, "ctx", None)
        hint = f" (see '{ctx.command_path} --help')" if ctx is not None else ""
        print(f"hmodel: error: {_one_line(e.format_message())}{hint}", file=sys.stderr)
        return e.exit_code
    except (KeyboardInterrupt, typer.Abort):
        print("hmodel: interrupted", file=sys.stderr)
        return 130
    return code if isinstance(code, int) else 0


if __name__ == "__main__":
    sys.exit(main())
