"""Running YADE (https://yade-dem.org) as a subprocess.

hmodel never imports YADE: it writes a script and a JSON input into a temporary folder, runs
``yade -n -j1 -x SCRIPT INPUT OUTPUT`` there and reads the JSON output back; the folder is
removed whatever happens. The executable is ``$HMODEL_YADE`` if set, else ``yade`` on PATH.
Every failure is a :class:`DEMError` with a one-line message.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from ..errors import SolverError

INSTALL_HINT = "apt-get install -y yade"


class DEMError(SolverError):
    """A DEM run failed: YADE missing, crashed, timed out or did not reach equilibrium."""


class YadeNotFound(DEMError):
    """No YADE executable."""


class EquilibriumError(DEMError):
    """The quasi-static criterion was not met within the iteration cap."""


def find_yade() -> str:
    """Path of the YADE executable (``$HMODEL_YADE`` or ``yade`` on PATH)."""
    override = os.environ.get("HMODEL_YADE")
    if override:
        path = shutil.which(override)
        if path is None:
            raise YadeNotFound(f"YADE is not installed: HMODEL_YADE={override!r} is not an executable "
                               f"({INSTALL_HINT})")
        return path
    path = shutil.which("yade")
    if path is None:
        raise YadeNotFound(f"YADE is not installed: {INSTALL_HINT}")
    return path


def available() -> bool:
    """Whether a YADE executable can be found."""
    try:
        find_yade()
    except YadeNotFound:
        return False
    return True


def _last_line(text: str) -> str:
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    return lines[-1] if lines else "no message"


def run_script(script: str, payload: dict, timeout: float = 600.0,
               files: dict[str, str] | None = None) -> dict:
    """Run ``script`` (Python source for YADE) on ``payload``; return its JSON output.

    ``files`` (name -> text) are written next to the script (its working directory), e.g. the
    shared :mod:`hmodel.dem.yade_common`.

    The script is called as ``script.py input.json output.json`` and must write a JSON object
    with ``status`` (``"ok"`` or ``"no-equilibrium"``) and ``message``.

    Raises
    ------
    YadeNotFound, DEMError, EquilibriumError
    """
    exe = find_yade()
    with tempfile.TemporaryDirectory(prefix="hmodel-dem-") as tmp:
        work = Path(tmp)
        (work / "script.py").write_text(script)
        for name, text in (files or {}).items():
            (work / name).write_text(text)
        (work / "input.json").write_text(json.dumps(payload))
        cmd = [exe, "-n", "-j1", "-x", "script.py", "input.json", "output.json"]
        env = dict(os.environ, OMP_NUM_THREADS="1")
        try:
            proc = subprocess.run(cmd, cwd=work, capture_output=True, text=True, timeout=timeout,
                                  env=env, stdin=subprocess.DEVNULL)
        except subprocess.TimeoutExpired:
            raise DEMError(f"YADE timed out after {timeout:g} s") from None
        except OSError as e:
            raise DEMError(f"YADE could not be started ({exe}): {e.strerror}") from None
        if proc.returncode != 0:
            raise DEMError(f"YADE crashed (exit status {proc.returncode}): "
                           f"{_last_line(proc.stderr or proc.stdout)}")
        try:
            result = json.loads((work / "output.json").read_text())
        except (OSError, ValueError):
            raise DEMError(f"YADE wrote no result: {_last_line(proc.stderr or proc.stdout)}") from None
    if result.get("status") == "no-equilibrium":
        raise EquilibriumError(f"DEM: {result.get('message', 'equilibrium not reached')}")
    if result.get("status") != "ok":
        raise DEMError(f"DEM: {result.get('message') or 'unknown failure'}")
    return result
